//! Where the base model is wrong, and what is missing, without a model of the missing thing:
//! the **unmodelled mass flow** estimated from the measured pressure (input estimation), located
//! in time, pressure, travel and release phase, and described by a sparse regression over a
//! small library of physical candidate terms (the idea of SINDy, Brunton et al. 2016, on one
//! unknown input instead of a whole vector field).
//!
//! # Method
//!
//! The base chamber equation (SPEC §2) is `V dP/dt + κ P dV/dt = κ R T (ṁ_in − ṁ_leak)`. Given the
//! measured pressure `P(t)` of a release (the mean of its group) and the fitted base brake:
//!
//! 1. `P` and `dP/dt` come from a local linear regression over ±[`HALF_WINDOW`] samples (a
//!    Savitzky–Golay filter of order 1; 0.21 s at 100 Hz).
//! 2. The piston is driven by that pressure ([`crate::reference::piston_under_pressure`]), which
//!    gives the travel and the chamber volume `V(t)` the measured pressure implies, and `dV/dt`
//!    through the same filter (so that the two rates carry the same smoothing).
//! 3. The flow the chamber must have received is `ṁ_req = (V dP/dt + κ P dV/dt)/(κ R T)`; the
//!    base model supplies `ṁ_model = ṁ_in(P) − ṁ_leak(P)` at the measured pressure. Their
//!    difference `ṁ_miss = ṁ_req − ṁ_model` is the unmodelled flow: positive when more air arrives
//!    than the model lets in, negative for an extra outflow or a missing inflow.
//! 4. It is averaged over blocks of [`BLOCK_SAMPLES`] (0.25 s). The noise σ of a block follows
//!    from the noise σ of the pressure through the (linear) filter, plus the noise of `ṁ_model`
//!    at the smoothed pressure, plus a model floor of [`MODEL_FLOOR_REL`] of the modelled inflow
//!    (fixed-point twin against this f64 evaluation). A block is significant at |z| ≥ [`Z_SIGNIFICANT`].
//! 5. Significant blocks of one sign form **segments**: a time window with its release phase,
//!    pressure range and travel range.
//! 6. **Sparse regression**: `ṁ_miss` over all blocks, weighted by 1/σ, is regressed by forward
//!    selection (BIC, at most [`MAX_TERMS`] terms) on physical candidate terms: an extra leak to
//!    atmosphere (equivalent orifice), the same leak only above a pressure (a relief valve
//!    cracking, knots every 0.25 bar), an inlet flow scaled by a factor (discharge coefficient or
//!    orifice), an extra dead volume, a different swept-volume rate (a force the model lacks
//!    moves the piston differently: friction, preload), and a constant flow. When the chosen
//!    terms explain at least [`EXPLAINED_ENOUGH`] of the excess χ², the description names them
//!    with their magnitudes; otherwise it describes the segments in words ("inflow stops from
//!    5.9 to 6.9 s", "the flow oscillates around the model").
//!
//! # Limits
//!
//! The pressure alone cannot tell an unmodelled flow from an unmodelled force during the
//! stroke: a force changes the motion, hence `dV/dt`, and shows as an equivalent flow. At rest
//! (before breakaway and at the end stop) the volume is fixed and the reconstruction is a flow.
//! A transducer fault (offset, lag) also shows as an equivalent flow. Edges of sharp events
//! (the valve opening, the end stop) are smeared over ± 0.1 s by the filter. The reconstruction
//! is against the *fitted* base: when a large missing effect pulls the fitted preload or
//! friction to the edge of their tolerance, the modelled breakaway or end stop moves, and a
//! spurious window can appear there (an independent tester saw them around 4 bar and at the
//! end stop; driving the piston with the documented forces instead made clean releases worse).

use pbm::params::{circle_area, GAS_CONSTANT, KAPPA, TEMPERATURE_K};
use pbm::twin::SAMPLE_PERIOD_S;
use pbm::TwinParams;

use crate::reference::{orifice_mass_flow, piston_under_pressure, P0};

/// Half-width of the local regression that smooths and differentiates the pressure, samples.
pub const HALF_WINDOW: usize = 10;
/// Samples per block of the reconstruction (0.25 s).
pub const BLOCK_SAMPLES: usize = 25;
/// |z| from which a block's unmodelled flow is significant.
pub const Z_SIGNIFICANT: f64 = 4.0;
/// A single significant block forms a segment only from this |z| on (two adjacent suffice at
/// [`Z_SIGNIFICANT`]).
pub const Z_SINGLE_BLOCK: f64 = 5.0;
/// Model floor of a block's σ: this share of the modelled inflow (the core's fixed-point twin
/// against this f64 evaluation, and the filter's bias at the corners of the curve).
pub const MODEL_FLOOR_REL: f64 = 0.03;
/// Model floor for the swept-volume flow `κ P dV/dt/(κRT)`: this share of its largest value
/// within ± 1 s (the breakaway and the end stop of a real piston come a little earlier or
/// later than the model's, and dV/dt jumps there).
pub const SWEPT_FLOOR_REL: f64 = 0.1;
/// Supply uncertainty of the fitted base, Pa: near the plateau the modelled inflow depends
/// steeply on the supply, which the base knows only to its tolerance (SPEC §5: ± 0.03 bar).
pub const SUPPLY_SIGMA_PA: f64 = crate::audit::SUPPLY_SPREAD_BAR * 1e5;
/// Most terms the sparse regression keeps.
pub const MAX_TERMS: usize = 3;
/// ΔBIC a term must bring to enter the regression.
pub const TERM_BIC: f64 = 10.0;
/// Share of the excess χ² (above its noise expectation) a term must explain to enter.
pub const MIN_TERM_SHARE: f64 = 0.1;
/// Share of the excess χ² the chosen terms must explain to describe the missing flow.
pub const EXPLAINED_ENOUGH: f64 = 0.7;

/// Phases of a release, from the travel.
pub const PHASES: [&str; 3] = ["filling at rest", "stroke", "end stop / plateau"];

/// One block of the reconstruction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Block {
    /// Centre time, s from the release command.
    pub t_s: f64,
    /// Unmodelled mass flow, g/s (positive: more air arrives than modelled).
    pub flow_g_s: f64,
    /// Its 1-σ noise, g/s.
    pub sigma_g_s: f64,
    /// Measured pressure (smoothed), bar g.
    pub pressure_bar: f64,
    /// Travel the measured pressure implies, mm.
    pub travel_mm: f64,
    /// The base model's inflow at the measured pressure, g/s.
    pub inflow_g_s: f64,
    /// Release phase (index into [`PHASES`]).
    pub phase: usize,
}

impl Block {
    /// Signed significance.
    pub fn z(&self) -> f64 {
        self.flow_g_s / self.sigma_g_s
    }
}

/// A time window of significant unmodelled flow of one sign.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// Start and end, s.
    pub t_s: (f64, f64),
    /// +1: more air arrives than modelled; −1: less (an extra outflow or a missing inflow).
    pub sign: i8,
    /// Mean unmodelled flow, g/s.
    pub mean_g_s: f64,
    /// Mean unmodelled flow over the mean modelled inflow (−1: the inflow stops).
    pub inflow_ratio: f64,
    /// Pressure range, bar g.
    pub pressure_bar: (f64, f64),
    /// Travel range, mm.
    pub travel_mm: (f64, f64),
    /// Phases touched (names of [`PHASES`]).
    pub phases: Vec<&'static str>,
}

/// A term of the sparse regression, with its fitted magnitude.
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    /// Machine name (`extra_leak`, `leak_above`, `inlet_scale`, `dead_volume`, `swept_rate`, `constant`).
    pub name: &'static str,
    /// Magnitude in `unit`.
    pub magnitude: f64,
    /// Unit of the magnitude.
    pub unit: &'static str,
    /// The knot of `leak_above`, bar g (NaN for the others).
    pub knot_bar: f64,
    /// The term in plain words with its magnitude.
    pub text: String,
}

/// The reconstruction of one configuration group.
#[derive(Debug, Clone, PartialEq)]
pub struct Reconstruction {
    /// Blocks in time order.
    pub blocks: Vec<Block>,
    /// Significant windows, in time order.
    pub segments: Vec<Segment>,
    /// Terms of the sparse regression, in the order they entered.
    pub terms: Vec<Term>,
    /// Share of the excess χ² (above its noise expectation) the terms explain, 0..=1.
    pub explained: f64,
    /// Largest |z| of a block.
    pub max_z: f64,
    /// One-sentence description.
    pub description: String,
}

impl Reconstruction {
    /// True when some block's unmodelled flow is significant.
    pub fn significant(&self) -> bool {
        !self.segments.is_empty()
    }
}

/// Local linear regression over ±`half` samples: (value at i, slope per sample).
pub(crate) fn local_linear(y: &[f64], half: usize) -> Vec<(f64, f64)> {
    let n = y.len();
    (0..n)
        .map(|i| {
            let lo = i.saturating_sub(half);
            let hi = (i + half).min(n.saturating_sub(1));
            let m = (hi - lo + 1) as f64;
            let ti = (lo..=hi).map(|k| k as f64).sum::<f64>() / m;
            let yi = y[lo..=hi].iter().sum::<f64>() / m;
            let (mut sxy, mut sxx) = (0.0, 0.0);
            for (k, &v) in y.iter().enumerate().take(hi + 1).skip(lo) {
                let d = k as f64 - ti;
                sxy += d * (v - yi);
                sxx += d * d;
            }
            let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
            (yi + slope * (i as f64 - ti), slope)
        })
        .collect()
}

/// Norm of the weights that map the pressure samples onto the mean of an interior block of
/// filtered slopes (per sample): the noise gain of a block's dP/dt.
fn block_slope_gain() -> f64 {
    let half = HALF_WINDOW as i64;
    let sxx: f64 = (-half..=half).map(|k| (k * k) as f64).sum();
    let span = BLOCK_SAMPLES as i64 + 2 * half;
    let mut w = vec![0.0f64; span as usize];
    for i in 0..BLOCK_SAMPLES as i64 {
        for k in -half..=half {
            w[(i + k + half) as usize] += k as f64 / sxx / BLOCK_SAMPLES as f64;
        }
    }
    w.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Phase of every sample from the travel (mm).
pub fn phase_of(x_mm: &[f64], stroke_mm: f64) -> Vec<usize> {
    let mut moved = false;
    x_mm.iter()
        .map(|&x| {
            if x > 1e-6 {
                moved = true;
            }
            if x >= stroke_mm - 1e-3 {
                2
            } else if moved {
                1
            } else {
                0
            }
        })
        .collect()
}

/// Per-sample quantities of the reconstruction.
struct Samples {
    p_bar: Vec<f64>,
    x_mm: Vec<f64>,
    miss: Vec<f64>,
    inflow: Vec<f64>,
    /// −dP/dt/(κRT), kg/s per m³ of extra dead volume.
    dead_volume: Vec<f64>,
    /// −P dV/dt/(RT), kg/s per unit relative error of the swept-volume rate.
    swept: Vec<f64>,
    /// −(flow through a 1 mm² orifice to atmosphere), kg/s.
    leak_unit: Vec<f64>,
    volume: Vec<f64>,
    /// dṁ_model/dP, kg/s per Pa.
    model_slope: Vec<f64>,
    /// dṁ_in/dP_supply, kg/s per Pa.
    supply_slope: Vec<f64>,
}

fn samples(params: &TwinParams, measured_bar_g: &[f64]) -> Samples {
    let dt = SAMPLE_PERIOD_S;
    let fit = local_linear(measured_bar_g, HALF_WINDOW);
    let p_bar: Vec<f64> = fit.iter().map(|f| f.0).collect();
    let (x, _v) = piston_under_pressure(params, &p_bar, dt);
    let area = params.piston_area_m2;
    let volume: Vec<f64> = x.iter().map(|&x| params.dead_volume_m3 + area * x).collect();
    let dvol = local_linear(&volume, HALF_WINDOW);
    let krt = KAPPA * GAS_CONSTANT * TEMPERATURE_K;
    let a_in = circle_area(params.orifice);
    let a_leak = circle_area(params.leak);
    let supply = params.supply.to_abs_pa();
    let cf = params.discharge_coeff;
    let model = |p: f64| orifice_mass_flow(cf, a_in, supply, p) - orifice_mass_flow(cf, a_leak, p, P0);
    let n = measured_bar_g.len();
    let mut s = Samples {
        p_bar: p_bar.clone(),
        x_mm: x.iter().map(|v| v * 1e3).collect(),
        miss: Vec::with_capacity(n),
        inflow: Vec::with_capacity(n),
        dead_volume: Vec::with_capacity(n),
        swept: Vec::with_capacity(n),
        leak_unit: Vec::with_capacity(n),
        volume: volume.clone(),
        model_slope: Vec::with_capacity(n),
        supply_slope: Vec::with_capacity(n),
    };
    for i in 0..n {
        let p = ((p_bar[i] + 1.0) * 1e5).max(1.0);
        let dp = fit[i].1 * 1e5 / dt;
        let dv = dvol[i].1 / dt;
        let required = (volume[i] * dp + KAPPA * p * dv) / krt;
        let m = model(p);
        s.miss.push(required - m);
        s.inflow.push(orifice_mass_flow(cf, a_in, supply, p));
        s.dead_volume.push(-dp / krt);
        s.swept.push(-KAPPA * p * dv / krt);
        s.leak_unit.push(-orifice_mass_flow(cf, 1e-6, p, P0));
        let h = 500.0;
        s.model_slope.push((model(p + h) - model(p - h)) / (2.0 * h));
        let hs = SUPPLY_SIGMA_PA;
        s.supply_slope.push(
            (orifice_mass_flow(cf, a_in, supply + hs, p) - orifice_mass_flow(cf, a_in, supply - hs, p)) / (2.0 * hs),
        );
    }
    s
}

/// Reconstructs the unmodelled flow of one release (mean measured pressure `measured_bar_g`,
/// 100 Hz from the release command, noise σ `sigma_bar` per sample) against the base brake
/// `params` (no mechanisms).
pub fn reconstruct(params: &TwinParams, measured_bar_g: &[f64], sigma_bar: f64) -> Reconstruction {
    let mut base = *params;
    base.ext = pbm::mechanism::Extensions::NONE;
    let s = samples(&base, measured_bar_g);
    let n = measured_bar_g.len();
    let nb = n / BLOCK_SAMPLES;
    let krt = KAPPA * GAS_CONSTANT * TEMPERATURE_K;
    let slope_gain = block_slope_gain();
    let sigma_pa = sigma_bar.max(1e-6) * 1e5;
    let phases = phase_of(&s.x_mm, params.stroke.mm());
    let mean = |v: &[f64], r: std::ops::Range<usize>| v[r.clone()].iter().sum::<f64>() / r.len() as f64;
    // Regressors per block (kg/s): dead volume, swept rate, unit leak, inflow, constant.
    let mut reg: Vec<[f64; 5]> = Vec::with_capacity(nb);
    let mut blocks = Vec::with_capacity(nb);
    for b in 0..nb {
        let r = b * BLOCK_SAMPLES..(b + 1) * BLOCK_SAMPLES;
        let vol = mean(&s.volume, r.clone());
        let inflow = mean(&s.inflow, r.clone());
        let slope = mean(&s.model_slope, r.clone()).abs();
        // Filtered dP/dt noise (bar/s → Pa/s) through V/(κRT), the model's flow at a pressure
        // smoothed over the block and the filter, and the model floor.
        let sigma_rate = vol / krt * sigma_pa * slope_gain / SAMPLE_PERIOD_S;
        let sigma_model = slope * sigma_pa / ((BLOCK_SAMPLES + 2 * HALF_WINDOW) as f64).sqrt();
        let sigma_supply = mean(&s.supply_slope, r.clone()).abs() * SUPPLY_SIGMA_PA;
        // The largest swept-volume flow within ± 1 s: a real piston breaks away and reaches
        // its end stop a little earlier or later than the model's.
        let near = r.start.saturating_sub(4 * BLOCK_SAMPLES)..(r.end + 4 * BLOCK_SAMPLES).min(n);
        let swept = s.swept[near].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let sigma = (sigma_rate.powi(2)
            + sigma_model.powi(2)
            + sigma_supply.powi(2)
            + (MODEL_FLOOR_REL * inflow).powi(2)
            + (SWEPT_FLOOR_REL * swept).powi(2))
        .sqrt();
        let mut count = [0usize; 3];
        for &ph in &phases[r.clone()] {
            count[ph] += 1;
        }
        let phase = (0..3).max_by_key(|&k| count[k]).unwrap_or(0);
        blocks.push(Block {
            t_s: (r.start as f64 + BLOCK_SAMPLES as f64 / 2.0) * SAMPLE_PERIOD_S,
            flow_g_s: mean(&s.miss, r.clone()) * 1e3,
            sigma_g_s: sigma * 1e3,
            pressure_bar: mean(&s.p_bar, r.clone()),
            travel_mm: mean(&s.x_mm, r.clone()),
            inflow_g_s: inflow * 1e3,
            phase,
        });
        reg.push([
            mean(&s.dead_volume, r.clone()),
            mean(&s.swept, r.clone()),
            mean(&s.leak_unit, r.clone()),
            inflow,
            1e-3,
        ]);
    }
    let max_z = blocks.iter().map(|b| b.z().abs()).fold(0.0, f64::max);
    let segments = segments(&blocks);
    let (terms, explained) = if segments.is_empty() { (Vec::new(), 0.0) } else { sparse_terms(&blocks, &reg, params) };
    let description = describe(&segments, &terms, explained, max_z);
    Reconstruction { blocks, segments, terms, explained, max_z, description }
}

/// The maximal runs of consecutive `items` that `keep` accepts and that `joins` links pairwise
/// (index ranges, in order): the windows of the brake's and the reservoir's reconstructions.
pub(crate) fn runs<T>(
    items: &[T],
    keep: impl Fn(&T) -> bool,
    joins: impl Fn(&T, &T) -> bool,
) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < items.len() {
        if !keep(&items[i]) {
            i += 1;
            continue;
        }
        let mut j = i + 1;
        while j < items.len() && keep(&items[j]) && joins(&items[j - 1], &items[j]) {
            j += 1;
        }
        out.push(i..j);
        i = j;
    }
    out
}

/// Runs of significant blocks of one sign.
fn segments(blocks: &[Block]) -> Vec<Segment> {
    let mut out = Vec::new();
    let sig = |b: &Block| b.z().abs() >= Z_SIGNIFICANT;
    for r in runs(blocks, sig, |a, b| a.z().signum() == b.z().signum()) {
        let run = &blocks[r];
        let sign = run[0].z().signum();
        if run.len() >= 2 || run[0].z().abs() >= Z_SINGLE_BLOCK {
            let half = BLOCK_SAMPLES as f64 * SAMPLE_PERIOD_S / 2.0;
            let span = |f: fn(&Block) -> f64| {
                run.iter().map(f).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
            };
            let flow: f64 = run.iter().map(|b| b.flow_g_s).sum::<f64>() / run.len() as f64;
            let inflow: f64 = run.iter().map(|b| b.inflow_g_s).sum::<f64>() / run.len() as f64;
            let mut phases: Vec<&'static str> = Vec::new();
            for b in run {
                if !phases.contains(&PHASES[b.phase]) {
                    phases.push(PHASES[b.phase]);
                }
            }
            out.push(Segment {
                t_s: (run[0].t_s - half, run[run.len() - 1].t_s + half),
                sign: if sign > 0.0 { 1 } else { -1 },
                mean_g_s: flow,
                inflow_ratio: if inflow.abs() > 1e-9 { flow / inflow } else { f64::NAN },
                pressure_bar: span(|b| b.pressure_bar),
                travel_mm: span(|b| b.travel_mm),
                phases,
            });
        }
    }
    out
}

/// Weighted least squares of `y` on the columns `cols` (rows weighted already): coefficients and χ².
fn least_squares(cols: &[Vec<f64>], y: &[f64]) -> Option<(Vec<f64>, f64)> {
    let k = cols.len();
    let mut m = vec![0.0; k * k];
    let mut rhs = vec![0.0; k];
    for a in 0..k {
        for b in 0..k {
            m[a * k + b] = cols[a].iter().zip(&cols[b]).map(|(u, v)| u * v).sum();
        }
        rhs[a] = cols[a].iter().zip(y).map(|(u, v)| u * v).sum();
    }
    let coef = crate::audit::solve(&m, &rhs, k)?;
    let chi2 = y
        .iter()
        .enumerate()
        .map(|(i, &yi)| {
            let fit: f64 = (0..k).map(|a| coef[a] * cols[a][i]).sum();
            (yi - fit).powi(2)
        })
        .sum();
    Some((coef, chi2))
}

/// A candidate column of the library: name, knot (NaN unless a hinge), extra parameters.
struct Candidate {
    name: &'static str,
    knot: f64,
    column: Vec<f64>,
    params: usize,
}

/// Forward selection over the term library; returns the terms and the share of the excess χ²
/// they explain.
fn sparse_terms(blocks: &[Block], reg: &[[f64; 5]], params: &TwinParams) -> (Vec<Term>, f64) {
    let w: Vec<f64> = blocks.iter().map(|b| 1.0 / (b.sigma_g_s * 1e-3)).collect();
    let y: Vec<f64> = blocks.iter().zip(&w).map(|(b, w)| b.flow_g_s * 1e-3 * w).collect();
    let col = |j: usize| -> Vec<f64> { reg.iter().zip(&w).map(|(r, w)| r[j] * w).collect() };
    let mut library = vec![
        Candidate { name: "dead_volume", knot: f64::NAN, column: col(0), params: 1 },
        Candidate { name: "swept_rate", knot: f64::NAN, column: col(1), params: 1 },
        Candidate { name: "extra_leak", knot: f64::NAN, column: col(2), params: 1 },
        Candidate { name: "inlet_scale", knot: f64::NAN, column: col(3), params: 1 },
        Candidate { name: "constant", knot: f64::NAN, column: col(4), params: 1 },
    ];
    let p_max = blocks.iter().map(|b| b.pressure_bar).fold(0.0, f64::max);
    let mut knot = 0.5;
    while knot < p_max - 0.3 {
        let column = reg
            .iter()
            .zip(blocks)
            .zip(&w)
            .map(|((r, b), w)| if b.pressure_bar >= knot { r[2] * w } else { 0.0 })
            .collect();
        library.push(Candidate { name: "leak_above", knot, column, params: 2 });
        knot += 0.25;
    }
    let n = blocks.len() as f64;
    let chi0: f64 = y.iter().map(|v| v * v).sum();
    let mut chosen: Vec<usize> = Vec::new();
    let mut chi = chi0;
    let mut coef = Vec::new();
    while chosen.len() < MAX_TERMS {
        let mut best: Option<(usize, Vec<f64>, f64)> = None;
        for (j, c) in library.iter().enumerate() {
            // One term of each kind (a second knot of the same hinge is not a new idea).
            if chosen.iter().any(|&k| library[k].name == c.name) {
                continue;
            }
            let cols: Vec<Vec<f64>> = chosen.iter().chain([&j]).map(|&k| library[k].column.clone()).collect();
            let set: Vec<usize> = chosen.iter().copied().chain([j]).collect();
            if let Some((cf, x2)) = least_squares(&cols, &y) {
                // A term is an explanation only at a physically possible magnitude; otherwise
                // the columns just cancel the base model (the library can rebuild any flow
                // from −100 % of everything).
                let possible = set.iter().zip(&cf).all(|(&k, &c)| plausible(library[k].name, c, params));
                if possible && best.as_ref().is_none_or(|b| x2 < b.2) {
                    best = Some((j, cf, x2));
                }
            }
        }
        let Some((j, cf, x2)) = best else { break };
        // BIC, and a share of the excess: a term that only polishes the fit of another one
        // is not a second thing missing.
        if chi - x2 <= TERM_BIC + library[j].params as f64 * n.ln() || chi - x2 < MIN_TERM_SHARE * (chi0 - n) {
            break;
        }
        chosen.push(j);
        coef = cf;
        chi = x2;
    }
    let excess = (chi0 - n).max(1e-9);
    let explained = ((chi0 - chi) / excess).clamp(0.0, 1.0);
    let terms = chosen.iter().zip(&coef).map(|(&j, &c)| term(&library[j], c, params)).collect();
    (terms, explained)
}

/// Whether coefficient `c` of term `name` is a physically possible brake: a dead volume
/// between −60 % and +150 % of the model's, an inflow or a swept-volume rate within ± 60 %, a
/// leak to atmosphere (never an inflow from it) of at most a 3 mm orifice.
fn plausible(name: &str, c: f64, params: &TwinParams) -> bool {
    match name {
        "dead_volume" => (-0.6..=1.5).contains(&(c / params.dead_volume_m3)),
        "swept_rate" | "inlet_scale" => (-0.6..=0.6).contains(&c),
        "extra_leak" | "leak_above" => (0.0..=circle_area(pbm::Meters(3e-3)) / 1e-6).contains(&c),
        _ => c.is_finite(),
    }
}

/// A fitted library column in plain words.
fn term(c: &Candidate, coef: f64, params: &TwinParams) -> Term {
    let (magnitude, unit, text) = match c.name {
        "dead_volume" => {
            let pct = 100.0 * coef / params.dead_volume_m3;
            (pct, "%", format!("a dead volume {:+.0} % from the model's ({:+.2} L)", pct, coef * 1e3))
        }
        "swept_rate" => {
            let pct = 100.0 * coef;
            (
                pct,
                "%",
                format!(
                    "the piston sweeps volume {pct:+.0} % faster than the model's motion (a force the model \
                     lacks: friction, preload, or a different piston)"
                ),
            )
        }
        "extra_leak" | "leak_above" => {
            // The column is the flow through 1 mm²: the coefficient is the area in mm².
            let d_mm = (4.0 * coef.max(0.0) / std::f64::consts::PI).sqrt();
            let what = "an extra leak to atmosphere";
            let text = if c.name == "leak_above" {
                format!("{what} above {:.2} bar g (equivalent orifice {:.2} mm)", c.knot, d_mm.abs())
            } else {
                format!("{what} at every pressure (equivalent orifice {:.2} mm)", d_mm.abs())
            };
            (d_mm, "mm", text)
        }
        "inlet_scale" => {
            let pct = 100.0 * coef;
            (pct, "%", format!("an inflow {pct:+.0} % from the model's (discharge coefficient or orifice)"))
        }
        _ => {
            let g = coef;
            (g, "g/s", format!("a constant {} of {:.2} g/s", if g >= 0.0 { "inflow" } else { "outflow" }, g.abs()))
        }
    };
    Term { name: c.name, magnitude, unit, knot_bar: c.knot, text }
}

fn fmt_range(r: (f64, f64), decimals: usize, unit: &str) -> String {
    if (r.1 - r.0).abs() < 0.5 * 10f64.powi(-(decimals as i32)) {
        format!("{:.*} {unit}", decimals, r.0)
    } else {
        format!("{:.*}–{:.*} {unit}", decimals, r.0, decimals, r.1)
    }
}

/// One segment in words.
pub fn segment_text(s: &Segment) -> String {
    let what = if s.sign > 0 {
        "more air arrives than modelled".to_owned()
    } else if s.inflow_ratio < -1.3 {
        "the inflow stops and air flows back out".to_owned()
    } else if s.inflow_ratio <= -0.7 {
        "the inflow stops".to_owned()
    } else if s.inflow_ratio < 0.0 && s.inflow_ratio.is_finite() {
        format!("{:.0} % less air arrives than modelled (an outflow or a smaller inflow)", -100.0 * s.inflow_ratio)
    } else {
        "air leaves the chamber".to_owned()
    };
    format!(
        "{what} from {:.1} to {:.1} s ({}, {}, travel {}; {:+.2} g/s)",
        s.t_s.0,
        s.t_s.1,
        s.phases.join(" and "),
        fmt_range(s.pressure_bar, 1, "bar g"),
        fmt_range(s.travel_mm, 0, "mm"),
        s.mean_g_s
    )
}

fn describe(segments: &[Segment], terms: &[Term], explained: f64, max_z: f64) -> String {
    if segments.is_empty() {
        return format!("no unmodelled flow above the noise (largest block {max_z:.1} σ)");
    }
    if !terms.is_empty() && explained >= EXPLAINED_ENOUGH {
        let names: Vec<&str> = terms.iter().map(|t| t.text.as_str()).collect();
        return format!("the missing flow looks like {} ({:.0} % of it)", names.join(" plus "), 100.0 * explained);
    }
    // Alternating signs: an oscillation.
    let changes = segments.windows(2).filter(|w| w[0].sign != w[1].sign).count();
    if changes >= 3 {
        let t0 = segments[0].t_s.0;
        let t1 = segments[segments.len() - 1].t_s.1;
        let starts: Vec<f64> = segments.iter().filter(|s| s.sign == segments[0].sign).map(|s| s.t_s.0).collect();
        let period = if starts.len() >= 2 {
            (starts[starts.len() - 1] - starts[0]) / (starts.len() - 1) as f64
        } else {
            f64::NAN
        };
        let amp = segments.iter().map(|s| s.mean_g_s.abs()).fold(0.0, f64::max);
        return format!(
            "the flow oscillates around the model from {t0:.1} to {t1:.1} s (period about {period:.1} s, up to {amp:.2} g/s): \
             the supply or the inlet is not steady"
        );
    }
    let mut by_size: Vec<&Segment> = segments.iter().collect();
    by_size.sort_by(|a, b| {
        let wa = a.mean_g_s.abs() * (a.t_s.1 - a.t_s.0);
        let wb = b.mean_g_s.abs() * (b.t_s.1 - b.t_s.0);
        wb.total_cmp(&wa)
    });
    by_size.truncate(2);
    by_size.sort_by(|a, b| a.t_s.0.total_cmp(&b.t_s.0));
    by_size.iter().map(|s| segment_text(s)).collect::<Vec<_>>().join("; ")
}
