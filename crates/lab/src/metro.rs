//! `host-sim audit-metro`: the model-discrepancy audit on real pneumatic data (SPEC §8,
//! MetroPT-3 head: the air production unit of a Porto metro train, ~10 s samples).
//!
//! # The small model: the core's [`pbm::reservoir::Reservoir`]
//!
//! Built from the brake twin's fixed-point pieces (`no_std`, so a controller can run it too):
//! one reservoir (volume V, pressure TP3) with the twin's chamber and energy equation, a
//! compressor as a mass-flow source while it is *loaded* (the one new piece), and consumption +
//! leakage as an orifice to atmosphere through the twin's flow table (choked at 8–10 bar, mass
//! flow ∝ p/√T). Base: adiabatic, every flow at T0 = 293.15 K (dp/dt = fill·loaded − λ p). The
//! fit varies the compressor delivery (g/s) and the outlet diameter (mm) at an assumed volume
//! [`METRO_VOLUME_M3`] (a pressure record shows only flows per volume) and Cf
//! [`METRO_DISCHARGE_COEFF`]. Mechanisms, with the brake library's names:
//!
//! - `heat_transfer` τ: the gas temperature is a state relaxing to the wall (T0); the compressor
//!   delivers air at the measured `Oil_temperature` (the outlet temperature proxy);
//! - `transport_delay` (s): air reaches the reservoir this long after the compressor loads (the
//!   outlet and dryer must first climb to reservoir pressure before the check valve opens);
//!   unloading acts at once;
//! - `valve_lag` (s): the compressor flow ramps up as 1 − e^(−t/τ) after loading;
//! - `sensor_lag` (s), `sensor_offset` (bar), `sensor_gain` (ratio): the transducer;
//! - `laminar_leak`: an extra leak ∝ gauge pressure, g/s at 7 bar g (at the assumed volume);
//! - `wall_heat` (reservoir only, [`WallNode`]): the wall as a second thermal node, its
//!   gas-to-wall heat-capacity ratio and its cooling time; fitted on every candidate with
//!   `heat_transfer` (whose τ couples gas and wall) and named by the same two tests.
//!
//! [`simulate_reference`] is the same model written out in `f64`; a test checks the
//! fixed-point one against it.
//!
//! Loaded = `COMP` < 0.5 (MetroPT-3: COMP is the air-intake valve signal, active when the
//! compressor does *not* take in air). COMP is sampled every ~10 s, so each switch is known only
//! to its interval and is estimated inside it ([`estimate_switches`]). Each phase is simulated
//! from the measured pressure at its start (see [`simulate`]); base and candidates share this.
//!
//! Candidates: the mechanisms above (the brake library's `regulator_droop`,
//! `progressive_spring` and `gas_temperature` have no counterpart here: no regulator, no
//! piston, and a supply temperature is a fill-rate scale).
//!
//! Every fitted candidate is validated on compressor cycles it was not fitted to ([`HeldOut`]),
//! beside what the record itself allows ([`RecordFloor`]); one-off consumption events in a
//! single cycle are found without a model, reported and left out ([`OneOffEvent`]); rows before
//! the first complete cycle are not followed ([`model_start`]).
//!
//! Result on `metropt3_head.csv` (bench/audit_metro.md): the adiabatic base misses the fast
//! pressure drop in the first two minutes after each unloading and the slowing rise during
//! loading; the audit names `heat_transfer+transport_delay+wall_heat` and the held-out NMSE
//! falls from 0.91 % to 0.11 %, within 1.2× of the record's floor (0.09 %). `--synthetic-sweep N`
//! hides a drawn mechanism in records from the `f64` reference and scores the same audit on them
//! ([`synthetic_sweep`]).
//!
//! The fit, the candidate ranking and the decision use the
//! same machinery and rules as the brake audit ([`crate::audit::levenberg_marquardt`], ΔBIC with
//! n_eff and the [`crate::audit::BIC_THRESHOLD`] / [`crate::audit::MIN_RSS_RATIO`] rules).

use crate::audit::{
    inverse_diag, levenberg_marquardt, noise_sigma, ranking_line, verdict_json, RankedFit, RankingJson, VerdictJson,
    BIC_THRESHOLD, MIN_RSS_RATIO, NOISE_FLOOR_RATIO,
};
use crate::random::{normal_pair, unit};
use anyhow::{Context, Result};
use pbm::fixed::Q;
use pbm::mechanism::Extensions;
use pbm::mechanism::Mechanism;
use pbm::params::{KAPPA, TEMPERATURE_K};
use pbm::reservoir::{fill_rate_bar_per_s, vent_rate_per_s, Reservoir, ReservoirParams, WallNode, RESERVOIR_SUBSTEP_S};
use pbm::twin::laminar_gain;
use pbm::{BarG, KelvinQ8, Meters, PressureQ24};
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

pub use pbm_io::metro::{read_metro, MetroRow};

/// Default location of the data: the repository's extract, relative to the repository root.
pub const DEFAULT_PATH: &str = pbm_io::metro::EXTRACT;

/// The candidates of the metro audit: the brake library's mechanisms that the reservoir has
/// (`regulator_droop`, `progressive_spring` and `gas_temperature` have no counterpart: no
/// regulator, no piston, the delivery temperature is measured). Names and units are the brake
/// audit's; `laminar_leak` is at [`METRO_VOLUME_M3`].
pub const METRO_EFFECTS: [Mechanism; 7] = [
    Mechanism::HeatTransfer,
    Mechanism::TransportDelay,
    Mechanism::ValveLag,
    Mechanism::SensorLag,
    Mechanism::SensorOffset,
    Mechanism::SensorGain,
    Mechanism::LaminarLeak,
];

/// The reservoir scope of a metro candidate ([`pbm::mechanism::Descriptor::reservoir`]).
fn scope(e: Mechanism) -> pbm::mechanism::Scope {
    // Every entry of METRO_EFFECTS has a reservoir scope (a test checks it); any other
    // mechanism is off in this model and never searched.
    e.descriptor().reservoir.unwrap_or(pbm::mechanism::Scope {
        valid: (e.off(), e.off()),
        search: (e.off(), e.off()),
        scale: pbm::mechanism::SearchScale::Linear,
        starts: &[],
        plausible: &[],
        plausible_why: "",
        identifiable: false,
    })
}

/// Magnitude of a candidate from the fit's unit box `u` (0..1).
fn metro_value(e: Mechanism, u: f64) -> f64 {
    scope(e).value_at(u)
}

/// False for the mechanisms a TP3 record cannot separate from the base
/// ([`pbm::mechanism::Scope::identifiable`]): hidden in a record they leave the base at the
/// noise floor (`none` is then the right answer) or give a poor magnitude.
pub fn metro_identifiable(e: Mechanism) -> bool {
    scope(e).identifiable
}

/// d value / d u (for the uncertainty).
fn metro_slope(e: Mechanism, u: f64) -> f64 {
    let h = 1e-4;
    let (a, b) = ((u - h).max(0.0), (u + h).min(1.0));
    (metro_value(e, b) - metro_value(e, a)) / (b - a)
}

/// Starting points of a candidate's magnitude in the unit box.
fn metro_starts(e: Mechanism) -> Vec<f64> {
    let s = scope(e);
    s.starts.iter().map(|&v| s.coordinate_of(v)).collect()
}

/// Reservoir volume the fit assumes, m³ (main reservoir and piping of the air production unit).
/// A pressure record only shows flows per volume: another volume scales the reported compressor
/// delivery, laminar leak and outlet area by the same factor and changes nothing else.
pub const METRO_VOLUME_M3: f64 = 0.5;
/// Discharge coefficient of the outlet orifice (SPEC §3's): only Cf·A is observable.
pub const METRO_DISCHARGE_COEFF: f64 = 0.8;

/// The core reservoir's parameters for a point `u` of the fit's unit box (`u[0]`: compressor
/// delivery 0.5–30.5 g/s, `u[1]`: outlet orifice 0.15–5 mm, log scale) with `effects` on.
pub fn metro_params(u: &[f64], effects: &[(Mechanism, f64)]) -> ReservoirParams {
    let at = |i: usize| u.get(i).copied().unwrap_or(0.5).clamp(0.0, 1.0);
    let mut ext = Extensions::NONE;
    for &(e, v) in effects {
        ext[e] = v;
    }
    ReservoirParams {
        volume_m3: METRO_VOLUME_M3,
        compressor_g_per_s: 0.5 + 30.0 * at(0),
        outlet: Meters::from_mm(0.15 * (5.0f64 / 0.15).powf(at(1))),
        discharge_coeff: METRO_DISCHARGE_COEFF,
        ext,
        wall: pbm::reservoir::WallNode::OFF,
    }
}

/// A reservoir model the row driver can run: the core fixed-point one or the `f64` reference.
trait MetroModel {
    /// Restarts from a transducer reading (bar g); `settle` as [`Reservoir::restart`].
    fn restart(&mut self, reading_bar_g: f64, settle: bool);
    /// One [`RESERVOIR_SUBSTEP_S`] with the compressor loaded (as commanded), delivering at
    /// `delivery_c` °C.
    fn step(&mut self, loaded: bool, delivery_c: f64);
    /// What the transducer reads now, bar g.
    fn reading(&self) -> f64;
    /// Whether the model has a state that outlives a compressor cycle (the wall node), which
    /// [`spin_up`] must bring to its cycling temperature first.
    fn has_slow_state(&self) -> bool;
    /// The wall node's temperature over ambient (1 without one).
    fn wall_theta(&self) -> f64;
    /// Puts the wall node at `theta` over ambient.
    fn set_wall_theta(&mut self, theta: f64);
}

/// A record starts while the compressor has been cycling for hours, so a wall node is warm,
/// at a temperature nobody measured. Rather than fit it, [`spin_up`] puts the wall at the
/// temperature that repeating the record's first complete cycle brings it to: three cycles
/// give the wall temperatures w₁, w₂, w₃ at their ends, which approach that temperature
/// geometrically (the wall is a first-order store, nearly linear over a cycle), so Aitken's
/// extrapolation w₃ − (w₃ − w₂)² / (w₃ − 2w₂ + w₁) gives it even when τ_w spans many cycles;
/// a fourth cycle then settles the gas to it. Returns the row the run then starts at
/// ([`model_start`]), or `None` when it did not run: a model without a slow state is left as it
/// is.
fn spin_up<M: MetroModel>(rows: &[MetroRow], model: &mut M) -> Option<usize> {
    if !model.has_slow_state() {
        return None;
    }
    let &(l, _, n) = complete_cycles(rows).first()?;
    let cycle = &rows[l - 1..n];
    let mut w = [0.0; 3];
    for wk in &mut w {
        drive(cycle, model, &Switches::MIDPOINT, &[]);
        *wk = model.wall_theta();
    }
    let (d1, d2) = (w[1] - w[0], w[2] - w[1]);
    let ratio = d2 / d1;
    if d1 != 0.0 && ratio.is_finite() && (0.0..0.999).contains(&ratio) {
        model.set_wall_theta(w[2] + d2 * ratio / (1.0 - ratio));
        drive(cycle, model, &Switches::MIDPOINT, &[]);
    }
    Some(l - 1)
}

impl MetroModel for Reservoir {
    fn restart(&mut self, reading_bar_g: f64, settle: bool) {
        Reservoir::restart(self, PressureQ24::from_bar_g(BarG(reading_bar_g)), settle);
    }
    fn step(&mut self, loaded: bool, delivery_c: f64) {
        self.update(loaded, KelvinQ8::from_celsius(delivery_c));
    }
    fn reading(&self) -> f64 {
        Reservoir::reading(self).to_bar_g().0
    }
    fn has_slow_state(&self) -> bool {
        self.has_wall_node()
    }
    fn wall_theta(&self) -> f64 {
        Reservoir::wall_theta(self).to_f64()
    }
    fn set_wall_theta(&mut self, theta: f64) {
        Reservoir::set_wall_theta(self, Q::from_f64(theta));
    }
}

/// Rounds of switch estimation and refit per candidate ([`audit_metro`]).
const SWITCH_ROUNDS: usize = 2;

/// Runs a model along the rows, as the transducer would read it at each row time.
///
/// COMP is sampled every ~10 s, so it is taken to switch at the midpoint between two rows. Each
/// phase is simulated from the measured pressure at its start, like a brake release from its
/// known start: a loading phase from the last row before it, with the gas at the wall
/// temperature and the compressor at rest; a decay phase from its first row, keeping the gas
/// temperature the loading left (what `heat_transfer` is about). Each restart shifts pressure and
/// transducer state together, so a transducer lag survives it. The loaded time of a cycle is
/// known only to about ± 10 s (± 0.2 bar of fill), an offset that would otherwise sit on the
/// whole 30 min decay and swamp every mechanism.
///
/// `anchors`: rows after which the model restarts on the measured pressure, keeping its state (the
/// last row of a [`OneOffEvent`]: an input the record does not hold).
fn drive<M: MetroModel>(rows: &[MetroRow], model: &mut M, switches: &Switches, anchors: &[usize]) -> Vec<f64> {
    let mut out = Vec::with_capacity(rows.len());
    let Some(first) = rows.first() else { return out };
    model.restart(first.tp3_bar, true);
    out.push(model.reading());
    let mut was_loaded = first.loaded;
    let mut switch = 0;
    for (i, w) in rows.windows(2).enumerate() {
        let (r, next) = (w[0], w[1]);
        if next.loaded && !r.loaded {
            model.restart(r.tp3_bar, true);
        } else if (was_loaded && !r.loaded) || anchors.contains(&i) {
            model.restart(r.tp3_bar, false);
        }
        was_loaded = r.loaded;
        let n = substeps(r, next);
        let at = if r.loaded == next.loaded {
            n
        } else {
            switch += 1;
            switches.at(switch - 1, n)
        };
        for k in 0..n {
            model.step(if k < at { r.loaded } else { next.loaded }, r.oil_c);
        }
        out.push(model.reading());
    }
    out
}

/// Substeps of the interval from row `r` to row `next`.
fn substeps(r: MetroRow, next: MetroRow) -> usize {
    ((next.t_s - r.t_s) / RESERVOIR_SUBSTEP_S).round().max(1.0) as usize
}

/// When the compressor switched inside each sampling interval in which COMP changes: the
/// substep of the switch, in the order of those intervals. COMP is sampled every ~10 s, so a
/// switch is known only to its interval; without an estimate it is taken at the midpoint
/// ([`Switches::MIDPOINT`]). The audit estimates each one as a nuisance parameter
/// ([`estimate_switches`]), like the start of a brake release, which is known exactly.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Switches(Vec<usize>);

impl Switches {
    /// Every switch at the midpoint of its interval.
    pub const MIDPOINT: Switches = Switches(Vec::new());

    /// The substep of switch `j` in an interval of `n` substeps.
    fn at(&self, j: usize, n: usize) -> usize {
        self.0.get(j).map_or(n / 2, |&k| k.min(n))
    }

    /// The switches after the first `k` (a run that starts later in the record).
    fn skip(&self, k: usize) -> Switches {
        Switches(self.0.get(k..).map(<[usize]>::to_vec).unwrap_or_default())
    }

    /// Seconds after the start of its interval at which each switch is taken (midpoints when
    /// not estimated), for `rows`.
    pub fn seconds(&self, rows: &[MetroRow]) -> Vec<f64> {
        rows.windows(2)
            .filter(|w| w[0].loaded != w[1].loaded)
            .enumerate()
            .map(|(j, w)| self.at(j, substeps(w[0], w[1])) as f64 * RESERVOIR_SUBSTEP_S)
            .collect()
    }
}

/// Estimates when the compressor switched inside each interval in which COMP changes, for
/// the model `params` ([`Switches`]): coordinate descent over the substeps of each interval,
/// minimising the squared residual of the cycle it belongs to (the model restarts before each
/// loading phase, so a cycle's switches only move that cycle's rows). Without this, the fill
/// rate times the ± 5 s of the sampling (≈ 0.1 bar) sits on every loading phase and pulls every
/// other parameter of the fit.
///
/// `events`: rows left out of the cost, with the model restarted after each ([`OneOffEvent`]).
pub fn estimate_switches(rows: &[MetroRow], params: &ReservoirParams, events: &[OneOffEvent]) -> Option<Switches> {
    let intervals: Vec<(usize, usize)> = rows
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0].loaded != w[1].loaded)
        .map(|(i, w)| (i, substeps(w[0], w[1])))
        .collect();
    let mut at: Vec<usize> = intervals.iter().map(|&(_, n)| n / 2).collect();
    // Cycles: from the row before each loading phase to the next one (the driver's settling
    // restarts), with the switches inside them.
    let starts: Vec<usize> =
        rows.windows(2).enumerate().filter(|(_, w)| w[1].loaded && !w[0].loaded).map(|(i, _)| i).collect();
    let mut bounds: Vec<usize> = std::iter::once(0).chain(starts.iter().copied()).collect();
    bounds.push(rows.len());
    bounds.dedup();
    // A model with a wall node carries its wall from cycle to cycle: each segment starts from
    // the state the segments before it (with their estimated switches) left, from the spun-up
    // first complete cycle on. Without one, every segment starts from a fresh model, as it
    // always did (the restart settles all else). Rows before the first complete cycle are no
    // model's to follow ([`model_start`]).
    let lead = model_start(rows);
    let mut carried = Reservoir::new(params).ok()?;
    let warm = spin_up(rows, &mut carried).is_some();
    for seg in bounds.windows(2) {
        let (a, b) = (seg[0], seg[1]);
        if a < lead {
            continue;
        }
        let inside: Vec<usize> =
            (0..intervals.len()).filter(|&j| (a..b.saturating_sub(1)).contains(&intervals[j].0)).collect();
        let rows_seg = &rows[a..b];
        let anchors: Vec<usize> = events
            .iter()
            .filter(|e| !e.recovered)
            .map(|e| e.rows.1)
            .filter(|r| (a..b).contains(r))
            .map(|r| r - a)
            .collect();
        let start = if warm { carried } else { Reservoir::new(params).ok()? };
        let local_of = |at: &[usize]| Switches(inside.iter().map(|&j| at[j]).collect());
        if inside.is_empty() {
            if warm {
                drive(rows_seg, &mut carried, &local_of(&at), &anchors);
            }
            continue;
        }
        let cost = |at: &[usize]| -> Option<f64> {
            let m = drive(rows_seg, &mut start.clone(), &local_of(at), &anchors);
            Some(
                m.iter()
                    .zip(rows_seg)
                    .enumerate()
                    .filter(|(i, _)| a + i >= lead && !in_event(events, a + i))
                    .map(|(_, (m, r))| (m - r.tp3_bar).powi(2))
                    .sum(),
            )
        };
        let mut best = cost(&at)?;
        for _pass in 0..3 {
            let mut moved = false;
            for &j in &inside {
                for k in 0..=intervals[j].1 {
                    let old = at[j];
                    at[j] = k;
                    match cost(&at) {
                        Some(c) if c < best => {
                            best = c;
                            moved = true;
                        }
                        _ => at[j] = old,
                    }
                }
            }
            if !moved {
                break;
            }
        }
        if warm {
            drive(rows_seg, &mut carried, &local_of(&at), &anchors);
        }
    }
    Some(Switches(at))
}

/// The first row a model follows: the row before the first complete cycle's loading. Before it
/// the record begins in the middle of a cycle, with the gas (and a wall node) at temperatures
/// nobody measured, so the audit neither fits nor judges those rows (for every candidate alike,
/// so their residuals stay comparable). 0 without a complete cycle.
pub fn model_start(rows: &[MetroRow]) -> usize {
    complete_cycles(rows).first().map_or(0, |&(l, _, _)| l - 1)
}

/// Runs a model along the rows: [`drive`] from the first row, or, for a model with a slow state,
/// [`spin_up`] then [`drive`] from [`model_start`] (the rows before it read as measured).
fn run_model<M: MetroModel>(rows: &[MetroRow], model: &mut M, switches: &Switches, anchors: &[usize]) -> Vec<f64> {
    let Some(lead) = spin_up(rows, model) else {
        return drive(rows, model, switches, anchors);
    };
    let skipped = rows.get(..lead + 1).map_or(0, |r| r.windows(2).filter(|w| w[0].loaded != w[1].loaded).count());
    let shifted: Vec<usize> = anchors.iter().filter(|&&a| a >= lead).map(|a| a - lead).collect();
    let mut out: Vec<f64> = rows[..lead].iter().map(|r| r.tp3_bar).collect();
    out.extend(drive(&rows[lead..], model, &switches.skip(skipped), &shifted));
    out
}

/// TP3 at the row times (bar g, as the transducer reads it) from the core's fixed-point
/// [`Reservoir`]: the model the audit fits. `None` when the parameters are out of its range.
///
/// The model is shifted onto the measured pressure at the start of each phase (keeping the
/// transducer's lag): at the last row before a loading phase, with the gas at the wall
/// temperature and the compressor at rest, and at the first row of a decay phase, keeping the
/// gas temperature and the compressor line: the compressor switch is known only to ± 5 s.
pub fn simulate(rows: &[MetroRow], params: &ReservoirParams) -> Option<Vec<f64>> {
    simulate_switched(rows, params, &Switches::MIDPOINT)
}

/// [`simulate`] with the compressor switching at `switches` ([`estimate_switches`]).
pub fn simulate_switched(rows: &[MetroRow], params: &ReservoirParams, switches: &Switches) -> Option<Vec<f64>> {
    simulate_around(rows, params, switches, &[])
}

/// [`simulate_switched`] restarting on the measured pressure after each one-off event that left a
/// lasting change ([`OneOffEvent::recovered`] false)
/// ([`OneOffEvent`]); the event's own rows are not a model's to follow.
pub fn simulate_around(
    rows: &[MetroRow],
    params: &ReservoirParams,
    switches: &Switches,
    events: &[OneOffEvent],
) -> Option<Vec<f64>> {
    let mut model = Reservoir::new(params).ok()?;
    let anchors: Vec<usize> = events.iter().filter(|e| !e.recovered).map(|e| e.rows.1).collect();
    Some(run_model(rows, &mut model, switches, &anchors))
}

/// Why a fitted wall node (`with_wall`, on the mechanisms of `without`) is not credible, if it is
/// not: a wall found by an independent tester's plants that have none (7 of 37 records) had its
/// cooling time or capacity at an edge of the search range or undetermined (the fit using the
/// node as a spare degree of freedom, not as a wall), or did not predict held-out cycles better.
/// A wall must be determined ([`WALL_MAX_REL_SIGMA`]), sit inside its ranges, and cut the
/// held-out NMSE by [`WALL_HELD_OUT_GAIN`].
fn wall_not_credible(with_wall: &MetroFit, without: &MetroFit) -> Option<String> {
    let (w, [se, st]) = with_wall.wall?;
    if se >= WALL_MAX_REL_SIGMA * w.capacity_ratio || st >= WALL_MAX_REL_SIGMA * w.cooling_s {
        return Some(format!(
            "the data do not determine it (heat-capacity ratio {:.3} ± {se:.3}, cooling {:.0} ± {st:.0} s)",
            w.capacity_ratio, w.cooling_s
        ));
    }
    let near_edge = |v: f64, (lo, hi): (f64, f64)| {
        let u = log_coordinate(v, (lo, hi));
        !(0.02..=0.98).contains(&u)
    };
    if near_edge(w.capacity_ratio, WALL_CAPACITY_SEARCH) {
        return Some(format!(
            "its heat-capacity ratio {:.3} sits at the edge of {}–{}",
            w.capacity_ratio, WALL_CAPACITY_SEARCH.0, WALL_CAPACITY_SEARCH.1
        ));
    }
    if near_edge(w.cooling_s, WALL_COOLING_SEARCH_S) {
        return Some(format!(
            "its cooling time {:.0} s sits at the edge of {}–{} s",
            w.cooling_s, WALL_COOLING_SEARCH_S.0, WALL_COOLING_SEARCH_S.1
        ));
    }
    if let (Some(a), Some(b)) = (with_wall.held_out, without.held_out) {
        if a.nmse_pct > WALL_HELD_OUT_GAIN * b.nmse_pct {
            return Some(format!(
                "it does not predict held-out cycles better ({:.3} % against {:.3} % without it)",
                a.nmse_pct, b.nmse_pct
            ));
        }
    }
    None
}

/// A wall node must bring the held-out NMSE to this share of the model without it or below.
pub const WALL_HELD_OUT_GAIN: f64 = 0.85;
/// A wall node whose 1 σ (the larger of the covariance's and the jackknife's) reaches this share
/// of either magnitude is not determined by the data.
pub const WALL_MAX_REL_SIGMA: f64 = 0.75;

/// NMSE (%) of `curve` over the rows where `observed` is a number (outside the events).
fn nmse_outside(observed: &[f64], curve: &[f64]) -> f64 {
    let (m, c): (Vec<f64>, Vec<f64>) = observed.iter().zip(curve).filter(|(o, _)| o.is_finite()).unzip();
    pbm::metrics::nmse_pct(&m, &c).unwrap_or(f64::NAN)
}

/// Whether row `i` lies in one of `events`.
fn in_event(events: &[OneOffEvent], i: usize) -> bool {
    events.iter().any(|e| (e.rows.0..=e.rows.1).contains(&i))
}

/// `f64` reference of the same reservoir (the SPEC §2 chamber and energy equations written out
/// directly), used only to check the fixed-point model ([`simulate`]).
#[derive(Debug, Clone)]
struct ReferenceReservoir {
    params: ReservoirParams,
    /// Compressor fill rate (bar/s), outlet decay rate λ (1/s) and laminar leak rate (1/s per
    /// bar g), at the wall temperature: fixed by the parameters, so derived once.
    fill: f64,
    leak: f64,
    laminar: f64,
    /// Reservoir pressure, bar abs.
    p: f64,
    /// Gas temperature, K.
    temp: f64,
    /// Wall temperature, K ([`pbm::reservoir::WallNode`]; the ambient without one).
    wall: f64,
    /// Transducer state, bar g.
    sensed: f64,
    /// Delivery the reservoir sees, and a commanded change still travelling (elapsed s, state).
    loaded_eff: bool,
    pending: Option<(f64, bool)>,
    /// Time since the effective switch, s.
    since_switch: f64,
}

impl ReferenceReservoir {
    fn new(params: &ReservoirParams) -> Self {
        Self {
            params: *params,
            fill: fill_rate_bar_per_s(params),
            leak: vent_rate_per_s(params),
            laminar: laminar_gain(params.ext[Mechanism::LaminarLeak], TEMPERATURE_K, params.volume_m3, 1.0),
            p: 1.0,
            temp: TEMPERATURE_K,
            wall: TEMPERATURE_K,
            sensed: 0.0,
            loaded_eff: false,
            pending: None,
            since_switch: 1e9,
        }
    }
}

impl MetroModel for ReferenceReservoir {
    fn restart(&mut self, reading_bar_g: f64, settle: bool) {
        let e = &self.params.ext;
        let shift = (reading_bar_g - e[Mechanism::SensorOffset]) / e[Mechanism::SensorGain] - self.sensed;
        self.sensed += shift;
        self.p = (self.p + shift).max(0.0);
        if settle {
            self.temp = self.wall;
            self.pending = None;
            self.loaded_eff = false;
        }
    }

    fn step(&mut self, command: bool, delivery_c: f64) {
        let e = self.params.ext;
        let h = RESERVOIR_SUBSTEP_S;
        let (fill, leak) = (self.fill, self.leak);
        let t0 = TEMPERATURE_K;
        let delay = if command { e[Mechanism::TransportDelay] } else { 0.0 };
        if command != self.pending.map_or(self.loaded_eff, |(_, s)| s) {
            self.pending = Some((0.0, command));
        }
        // Share of this substep after a switch (continuous in the delay).
        let previous = self.loaded_eff;
        let mut new_share = 1.0;
        if let Some((t, s)) = self.pending {
            if t + h >= delay {
                new_share = ((t + h - delay) / h).clamp(0.0, 1.0);
                self.loaded_eff = s;
                self.since_switch = 0.0;
                self.pending = None;
            } else {
                self.pending = Some((t + h, s));
            }
        }
        // Mean opening over the substep, 1 − e^(−t/τ) from the switch.
        let lag = e[Mechanism::ValveLag];
        let ramp =
            if lag > 0.0 { 1.0 - lag / h * (1.0 - (-h / lag).exp()) * (-self.since_switch / lag).exp() } else { 1.0 };
        self.since_switch += h;
        let on = |l: bool| f64::from(u8::from(l));
        let q_in = fill * (new_share * on(self.loaded_eff) * ramp + (1.0 - new_share) * on(previous));
        let p = self.p;
        let q_lam = self.laminar * (p - 1.0);
        let dp = if e[Mechanism::HeatTransfer] > 0.0 {
            let theta = self.temp / t0;
            let q_out = leak * p / theta.sqrt() + q_lam; // mass flows on the T0 basis
            let e_out = leak * p * theta.sqrt() + q_lam * theta;
            let tc = delivery_c + 273.15;
            let tau = e[Mechanism::HeatTransfer];
            let dp = (q_in * tc / t0 - e_out + p * (self.wall - self.temp) / (self.temp * tau)) * h;
            let dm_rel = (q_in - q_out) * h * theta / (KAPPA * p);
            let w = self.params.wall;
            if w.is_on() {
                // Heat the gas gives the wall (m c_v (T − T_w)/τ) over the wall's capacity, and the
                // wall's own cooling to ambient.
                let mass_rel = p / theta / pbm::reservoir::WALL_REF_BAR;
                self.wall +=
                    (w.capacity_ratio * mass_rel * (self.temp - self.wall) / tau - (self.wall - t0) / w.cooling_s) * h;
            }
            self.temp = (self.temp * (1.0 + dp / p - dm_rel)).clamp(75.0, 1200.0);
            dp
        } else {
            (q_in - leak * p - q_lam) * h
        };
        self.p = (p + dp).max(0.0);
        let (start, end) = (p - 1.0, self.p - 1.0);
        self.sensed = if e[Mechanism::SensorLag] > 0.0 {
            // Exact first-order response to the pressure ramp over the substep.
            let tau = e[Mechanism::SensorLag];
            let keep = (-h / tau).exp();
            end - (end - start) * tau / h * (1.0 - keep) + (self.sensed - start) * keep
        } else {
            end
        };
    }

    fn reading(&self) -> f64 {
        let e = &self.params.ext;
        e[Mechanism::SensorOffset] + e[Mechanism::SensorGain] * self.sensed
    }
    fn has_slow_state(&self) -> bool {
        self.params.wall.is_on()
    }
    fn wall_theta(&self) -> f64 {
        self.wall / TEMPERATURE_K
    }
    fn set_wall_theta(&mut self, theta: f64) {
        if self.params.wall.is_on() {
            self.wall = theta * TEMPERATURE_K;
        }
    }
}

/// TP3 at the row times from the `f64` reference (to check [`simulate`]).
pub fn simulate_reference(rows: &[MetroRow], params: &ReservoirParams) -> Vec<f64> {
    run_model(rows, &mut ReferenceReservoir::new(params), &Switches::MIDPOINT, &[])
}

/// A synthetic MetroPT-3-like record from the `f64` reference (with any mechanisms on in
/// `params`), for tests that hide an effect from the audit: `n_rows` rows ~10 s apart (every
/// tenth step 9 s, as in the real extract), a pressure-switch governor that loads below 8 bar
/// and unloads above 10 bar (decided at the midpoint between two rows, where the audit assumes
/// the switch), an oil temperature that rises towards 80 °C while loaded and cools towards 55 °C
/// otherwise, and Gaussian transducer noise `sigma_bar` from `seed`. The model runs without
/// restarts, unlike the audit's.
pub fn synthetic_rows(params: &ReservoirParams, n_rows: usize, sigma_bar: f64, seed: u64) -> Vec<MetroRow> {
    synthetic_rows_with(params, n_rows, sigma_bar, seed, 0.0)
}

/// [`synthetic_rows`] with the consumption (the outlet's decay rate) drawn anew at each
/// loading, uniform within ± `consumption_spread` (relative) of the parameters' (from its own
/// stream of `seed`, so the noise is the same as without): cycles that differ as a train's do.
fn synthetic_rows_with(
    params: &ReservoirParams,
    n_rows: usize,
    sigma_bar: f64,
    seed: u64,
    consumption_spread: f64,
) -> Vec<MetroRow> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut consumption = ChaCha8Rng::seed_from_u64(seed ^ 0x636f_6e73);
    let mut model = ReferenceReservoir::new(params);
    let documented_leak = model.leak;
    model.restart(8.5, true);
    let (mut t, mut loaded, mut oil_c) = (0.0, true, 60.0);
    // A wall node takes hours to reach its cycling temperature, as in a real record that starts
    // while the compressor has been cycling for long: the rows of the first 30,000 s (10 τ_w of
    // the tests' wall) are dropped.
    let warm_up = if params.wall.is_on() { 3000 } else { 0 };
    let mut rows = Vec::with_capacity(n_rows + warm_up);
    for i in 0..n_rows + warm_up {
        let (noise, _) = normal_pair(&mut rng);
        rows.push(MetroRow { t_s: t, tp3_bar: model.reading() + sigma_bar * noise, loaded, oil_c });
        let dt = if i % 10 == 9 { 9.0 } else { 10.0 };
        let n = (dt / RESERVOIR_SUBSTEP_S) as usize;
        for k in 0..n {
            if k == n / 2 {
                let p = model.reading();
                let was = loaded;
                loaded = if loaded { p < 10.0 } else { p < 8.0 };
                if loaded && !was && consumption_spread > 0.0 {
                    model.leak = documented_leak * (1.0 + consumption_spread * (2.0 * unit(&mut consumption) - 1.0));
                }
            }
            model.step(loaded, oil_c);
            let (target, tau) = if loaded { (80.0, 300.0) } else { (55.0, 900.0) };
            oil_c += (target - oil_c) * RESERVOIR_SUBSTEP_S / tau;
        }
        t += dt;
    }
    let t0 = rows.get(warm_up).map_or(0.0, |r| r.t_s);
    rows.drain(..warm_up.min(rows.len()));
    for r in &mut rows {
        r.t_s -= t0;
    }
    rows
}

/// Options of the audit-metro run.
#[derive(Debug, Clone, PartialEq)]
pub struct MetroOptions {
    /// Write the verdict as JSON (the brake audit's keys).
    pub json: Option<PathBuf>,
    /// Plots: a `.svg` file (measured vs adiabatic vs extended), or a directory that receives
    /// `metro_curves.svg` and `metro_residual.svg`.
    pub plot: Option<PathBuf>,
    /// Instead of the file: a sweep of this many synthetic records, each with one mechanism
    /// hidden at a magnitude drawn from `seed` (see [`synthetic_sweep`]); prints the hit rate.
    pub synthetic_sweep: Option<usize>,
    /// Seed of the synthetic sweep.
    pub seed: u64,
}

impl Default for MetroOptions {
    fn default() -> Self {
        Self { json: None, plot: None, synthetic_sweep: None, seed: 1 }
    }
}

/// Base point of the synthetic records in the fit's unit box: 8.9 g/s, 0.4 mm (close to the
/// fit on the real extract).
pub const SYNTHETIC_BASE_U: [f64; 2] = [0.28, 0.4];
/// Transducer noise of the synthetic records, bar (the σ estimated on the real extract).
pub const SYNTHETIC_SIGMA_BAR: f64 = 0.0012;
/// Rows per synthetic record (as the real extract: ≈ 2.8 h).
pub const SYNTHETIC_ROWS: usize = 1000;

/// One case of [`synthetic_sweep`].
#[derive(Debug, Clone, PartialEq)]
pub struct SweepCase {
    /// Seed of the case (the record's noise and the draw).
    pub seed: u64,
    /// The hidden mechanism and magnitude.
    pub truth: (Mechanism, f64),
    /// What the audit named.
    pub cause: String,
    /// The named magnitude (first mechanism), if any.
    pub magnitude: Option<f64>,
    /// Base and extended NMSE, %.
    pub nmse_pct: (f64, f64),
}

impl SweepCase {
    /// Right name and magnitude within 20 % (of the deviation from 1 for a gain).
    pub fn named_right(&self) -> bool {
        let (e, v) = self.truth;
        let size = |x: f64| x - e.off();
        self.cause == e.name() && self.magnitude.is_some_and(|m| (size(m) - size(v)).abs() <= 0.2 * size(v).abs())
    }
    /// The audit named a mechanism that is not the hidden one (alone or in a pair).
    pub fn wrong_name(&self) -> bool {
        // `none` and `unexplained` name nothing.
        !matches!(self.cause.as_str(), "none" | "unexplained")
            && self.cause.split('+').any(|c| c != self.truth.0.name())
    }
    /// [`Self::named_right`] and the extended NMSE at least 5× below the base's.
    pub fn hit(&self) -> bool {
        self.named_right() && self.nmse_pct.0 >= 5.0 * self.nmse_pct.1
    }
}

/// Draws a mechanism and magnitude for each of `cases` seeds (`seed`, `seed + 1`, …), hides it
/// in a [`synthetic_rows`] record from the `f64` reference and runs [`audit_metro`] on it.
pub fn synthetic_sweep(cases: usize, seed: u64) -> Result<Vec<SweepCase>> {
    (0..cases as u64)
        .into_par_iter()
        .map(|i| {
            let case_seed = seed.wrapping_add(i);
            let mut rng = ChaCha8Rng::seed_from_u64(case_seed ^ 0x6d65_7472_6f00);
            let pick = (unit(&mut rng) * METRO_EFFECTS.len() as f64) as usize;
            let effect = METRO_EFFECTS[pick.min(METRO_EFFECTS.len() - 1)];
            // Place before side, as the draws have always been made (one seed, one case).
            let u_value = unit(&mut rng);
            let u_side = unit(&mut rng);
            let value = scope(effect).draw(u_side, u_value);
            let params = metro_params(&SYNTHETIC_BASE_U, &[(effect, value)]);
            let rows = synthetic_rows(&params, SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, case_seed);
            let out = audit_metro_with(&rows, false)?;
            Ok(SweepCase {
                seed: case_seed,
                truth: (effect, value),
                magnitude: out.chosen.effects.first().map(|e| e.1),
                cause: out.cause,
                nmse_pct: (out.base.nmse_pct, out.chosen.nmse_pct),
            })
        })
        .collect()
}

/// Text table of a sweep: one line per case, then the rates per mechanism and overall.
pub fn sweep_summary(cases: &[SweepCase]) -> String {
    let mut s = String::new();
    for c in cases {
        let _ = writeln!(
            s,
            "seed {:>4}  {:<16} {:>8.3}  →  {:<32} {:>9}  NMSE {:.4} % → {:.4} %  {}",
            c.seed,
            c.truth.0.name(),
            c.truth.1,
            c.cause,
            c.magnitude.map_or("-".to_owned(), |m| format!("{m:.3}")),
            c.nmse_pct.0,
            c.nmse_pct.1,
            if c.hit() {
                "hit"
            } else if c.named_right() {
                "named (gain < 5×)"
            } else {
                "MISS"
            }
        );
    }
    for e in METRO_EFFECTS {
        let of: Vec<&SweepCase> = cases.iter().filter(|c| c.truth.0 == e).collect();
        let named = of.iter().filter(|c| c.named_right()).count();
        let hits = of.iter().filter(|c| c.hit()).count();
        let _ = writeln!(
            s,
            "{:<16} cases {:>3}  named right {:>3}  hits (also ≥ 5×) {:>3}",
            e.name(),
            of.len(),
            named,
            hits
        );
    }
    for (label, identifiable) in [("identifiable", true), ("collinear with the base", false)] {
        let of: Vec<&SweepCase> = cases.iter().filter(|c| metro_identifiable(c.truth.0) == identifiable).collect();
        let n = of.len().max(1) as f64;
        let named = of.iter().filter(|c| c.named_right()).count();
        let hits = of.iter().filter(|c| c.hit()).count();
        let wrong = of.iter().filter(|c| c.wrong_name()).count();
        let _ = writeln!(
            s,
            "{label}: {} cases, named right (name, magnitude within 20 %) {named} ({:.1} %), hits (also ≥ 5× \
             NMSE gain) {hits} ({:.1} %), another mechanism named {wrong}",
            of.len(),
            100.0 * named as f64 / n,
            100.0 * hits as f64 / n
        );
    }
    s
}

/// A fitted metro candidate.
#[derive(Debug, Clone, PartialEq)]
pub struct MetroFit {
    /// Name.
    pub name: String,
    /// Mechanisms, magnitudes and 1-σ uncertainties (Gauss–Newton covariance at the optimum,
    /// inflated by n/n_eff as in the brake audit).
    pub effects: Vec<(Mechanism, f64, f64)>,
    /// The wall node ([`WallNode`], [`WALL_HEAT`]) with the 1-σ of ε and τ_w, when the candidate
    /// has one.
    pub wall: Option<(WallNode, [f64; 2])>,
    /// RSS (σ units).
    pub rss: f64,
    /// ΔBIC vs base.
    pub delta_bic: f64,
    /// NMSE, %.
    pub nmse_pct: f64,
    /// The fitted core reservoir model.
    pub params: ReservoirParams,
    /// Model curve.
    pub curve: Vec<f64>,
    /// The compressor switches the curve was run with ([`estimate_switches`]).
    pub switches: Switches,
    /// Leave-one-cycle-out validation ([`HeldOut`]); `None` when not run or with too few
    /// complete cycles.
    pub held_out: Option<HeldOut>,
}

/// Outcome of the metro audit.
#[derive(Debug, Clone, PartialEq)]
pub struct MetroOutcome {
    /// `none`, a mechanism or `a+b`.
    pub cause: String,
    /// Base fit.
    pub base: MetroFit,
    /// Chosen model.
    pub chosen: MetroFit,
    /// Candidates, best ΔBIC first.
    pub ranking: Vec<MetroFit>,
    /// Estimated noise σ, bar.
    pub sigma: f64,
    /// Residual RMS and bias of the base model during loading, the first 2 min after unloading,
    /// and later, bar.
    pub base_phase_rms: [(String, f64, f64); 3],
    /// The same for the chosen model.
    pub chosen_phase_rms: [(String, f64, f64); 3],
    /// RMS residual of the base and the chosen model in noise σ (the brake audit's measure;
    /// [`crate::audit::NOISE_FLOOR_RATIO`] is the floor).
    pub residual_to_noise: (f64, f64),
    /// Why a candidate that passed the tests was not named, if one was not.
    pub note: Option<String>,
    /// What the chosen model misses, aligned on the compressor cycle ([`aligned_rate`]).
    pub missing: Vec<AlignedRate>,
    /// RMS error, bar, that the switch instant alone leaves in a loading phase: COMP is sampled
    /// every Δt, so the switch is known only within Δt, and the fill rate × Δt/√12 sits on the
    /// whole phase unless the switch is estimated ([`estimate_switches`], which the fits do).
    pub switch_timing_floor_bar: f64,
    /// The chosen model against the cycle-to-cycle variation of the record ([`CycleFloor`]);
    /// `None` with fewer than three complete cycles.
    pub cycle_floor: Option<CycleFloor>,
    /// When the chosen model has the compressor switch, s after the start of each sampling
    /// interval in which COMP changes ([`Switches::seconds`]).
    pub switch_s: Vec<f64>,
    /// One-off consumption events, left out of every fit and figure ([`one_off_events`]).
    pub events: Vec<OneOffEvent>,
    /// What any model driven by COMP can reach on held-out cycles of this record
    /// ([`RecordFloor`]); `None` with fewer than three complete cycles.
    pub record_floor: Option<RecordFloor>,
    /// A lasting change of the air consumption between cycles ([`consumption_change`]).
    pub consumption_change: Option<ConsumptionChange>,
}

/// The unmodelled pressure rate of the chosen model, aligned on the compressor's switching and
/// averaged over the cycles: what the model misses, and when, in a cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct AlignedRate {
    /// `loaded` (time since the compressor loaded) or `unloaded` (time since it unloaded).
    pub phase: &'static str,
    /// Start of the time bin, s since the switch.
    pub from_s: f64,
    /// Width of the bin, s.
    pub width_s: f64,
    /// Mean unmodelled rate (measured − model), bar/min.
    pub mean_bar_per_min: f64,
    /// Its standard error over the intervals of the bin, bar/min.
    pub se_bar_per_min: f64,
    /// Intervals in the bin.
    pub count: usize,
    /// Lowest and highest measured pressure of its intervals, bar.
    pub pressure_bar: (f64, f64),
    /// A [`ALIGNED_BIN_S`] window of the late part of a phase (after 600 s), scanned beside the
    /// [`ALIGNED_LATE_BIN_S`] bins so that a short error there is not averaged away (an
    /// independent tester's 40 g drawn for 60 s at 600 s after every unloading was missing from
    /// "what is missing"). There are many of them, so one counts at [`ALIGNED_SCAN_SE`].
    pub scan: bool,
}

impl AlignedRate {
    /// Significant at 3 standard errors ([`ALIGNED_SCAN_SE`] for a scan window).
    pub fn significant(&self) -> bool {
        let se = if self.scan { ALIGNED_SCAN_SE } else { 3.0 };
        self.count >= 3 && self.mean_bar_per_min.abs() >= se * self.se_bar_per_min
    }
}

/// Standard errors at which a late scan window ([`AlignedRate::scan`]) is significant: a 30 min
/// decay holds about 25 of them per phase, so 3 SE would be passed by one somewhere by chance.
pub const ALIGNED_SCAN_SE: f64 = 4.5;

/// The significant bins of `rates` as windows in words, e.g. "an extra outflow from 60 to 180 s
/// after the compressor unloads (up to 0.022 bar/min)".
pub fn describe_aligned(rates: &[AlignedRate]) -> String {
    let joins = |a: &AlignedRate, b: &AlignedRate| {
        b.phase == a.phase
            && b.mean_bar_per_min.signum() == a.mean_bar_per_min.signum()
            && (b.from_s - a.from_s - a.width_s).abs() < 1e-9
    };
    // A scan window inside a significant bin of the same sign says nothing new.
    let covered = |a: &AlignedRate| {
        a.scan
            && rates.iter().any(|b| {
                !b.scan
                    && b.significant()
                    && b.phase == a.phase
                    && b.mean_bar_per_min.signum() == a.mean_bar_per_min.signum()
                    && b.from_s <= a.from_s
                    && a.from_s + a.width_s <= b.from_s + b.width_s
            })
    };
    let mut parts = Vec::new();
    for r in crate::missing_flow::runs(rates, |a| a.significant() && !covered(a), joins) {
        let run = &rates[r];
        let (first, last) = (&run[0], &run[run.len() - 1]);
        let peak = run.iter().map(|r| r.mean_bar_per_min.abs()).fold(0.0, f64::max);
        let p_min = run.iter().map(|r| r.pressure_bar.0).fold(f64::INFINITY, f64::min);
        let p_max = run.iter().map(|r| r.pressure_bar.1).fold(f64::NEG_INFINITY, f64::max);
        parts.push(format!(
            "{} from {:.0} to {:.0} s after the compressor {} ({p_min:.1}–{p_max:.1} bar, up to {peak:.3} bar/min)",
            match (first.mean_bar_per_min < 0.0, first.phase == "loaded") {
                (true, _) => "an extra outflow",
                (false, true) => "an extra inflow",
                (false, false) => "less outflow than modelled",
            },
            first.from_s,
            last.from_s + last.width_s,
            if first.phase == "loaded" { "loads" } else { "unloads" }
        ));
    }
    if parts.is_empty() {
        "no systematic unmodelled rate in the compressor cycle".to_owned()
    } else {
        parts.join("; ")
    }
}

/// Width of the bins of [`aligned_rate`] in the first 10 min of a phase, s.
pub const ALIGNED_BIN_S: f64 = 60.0;
/// Width of the later bins of [`aligned_rate`], s.
pub const ALIGNED_LATE_BIN_S: f64 = 300.0;

/// The cycles of a record as replicates: how far a model driven by COMP alone can get.
///
/// The record repeats one operation (load to 10 bar, decay to 8 bar) a few times; what differs
/// between the repetitions (the train's air consumption, the dryer's purges) is an input the
/// record does not hold, and no time-invariant model can follow it. So, as in a lack-of-fit
/// test with replicates, the residual is split into *pure error* (its spread between cycles at
/// the same time since the switch) and *lack of fit* (its mean over the cycles). At each time
/// the mean is tested against its spread (Student t with cycles − 1 degrees of freedom, 99 %
/// two-sided); the times are strongly correlated (one consumption per cycle moves the whole
/// decay), so they are not counted as independent: with α = 1 % per time, the expected share
/// of times beyond the bound is ≤ α whatever the correlation, and by Markov's inequality a share
/// `s` has probability ≤ α/`s` under an adequate model. The model's error is called systematic
/// when that bound is ≤ 5 % (a share ≥ 20 %). The brake audit does the same with repeated
/// releases.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleFloor {
    /// Complete cycles compared (a loading phase and the decay up to the next one).
    pub cycles: usize,
    /// Times compared per cycle (every 10 s of both phases, aligned on the switches).
    pub points: usize,
    /// RMS spread of the residual between cycles at the same time since the switch, bar.
    pub spread_bar: f64,
    /// RMS of the residual averaged over the cycles, bar: the error common to all cycles.
    pub systematic_bar: f64,
    /// Share of the times at which the mean is beyond the 99 % bound of its spread.
    pub share_beyond: f64,
}

impl CycleFloor {
    /// Upper bound of the probability of [`Self::share_beyond`] under a model that is right up to
    /// the cycle-to-cycle variation (Markov: α / share).
    pub fn p_at_most(&self) -> f64 {
        (CYCLE_ALPHA / self.share_beyond.max(1e-12)).min(1.0)
    }

    /// Whether the model's error common to all cycles is beyond the cycle-to-cycle variation
    /// ([`Self::p_at_most`] ≤ 5 %).
    pub fn systematic(&self) -> bool {
        self.p_at_most() <= 0.05
    }
}

/// The first interval k (rows k, k + 1) of rows a..b that reaches time `t`, if any.
fn interval_at(rows: &[MetroRow], a: usize, b: usize, t: f64) -> Option<usize> {
    (a..b - 1).find(|&k| rows[k + 1].t_s >= t)
}

/// `value` at time `t`, linear over the interval from row `k` to row `k + 1` (clamped to it).
fn interpolate(rows: &[MetroRow], k: usize, t: f64, value: impl Fn(usize) -> f64) -> f64 {
    let (t0, t1) = (rows[k].t_s, rows[k + 1].t_s);
    let w = ((t - t0) / (t1 - t0).max(1e-9)).clamp(0.0, 1.0);
    value(k) * (1.0 - w) + value(k + 1) * w
}

/// Step of the common time grid of [`cycle_floor`], s.
const CYCLE_GRID_S: f64 = 10.0;
/// Two-sided level of the per-time test of [`CycleFloor`].
const CYCLE_ALPHA: f64 = 0.01;

/// Student t's two-sided 99 % bound (0.995 quantile) for `dof` degrees of freedom: tabulated to
/// 10, then the Cornish–Fisher expansion (within 0.4 % from 10 on).
fn t_bound_99(dof: usize) -> f64 {
    const TABLE: [f64; 10] = [63.657, 9.925, 5.841, 4.604, 4.032, 3.707, 3.499, 3.355, 3.250, 3.169];
    match dof {
        0 => f64::INFINITY,
        1..=10 => TABLE[dof - 1],
        _ => {
            let (z, v) = (2.575_829_f64, dof as f64);
            z + (z.powi(3) + z) / (4.0 * v) + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * v * v)
        }
    }
}

/// [`CycleFloor`] of the residual `measured − curve`, or `None` with fewer than three complete
/// cycles.
pub fn cycle_floor(rows: &[MetroRow], measured: &[f64], curve: &[f64]) -> Option<CycleFloor> {
    if curve.len() != rows.len() || measured.len() != rows.len() {
        return None;
    }
    let cycles = complete_cycles(rows);
    if cycles.len() < 3 {
        return None;
    }
    let residual = |i: usize| measured[i] - curve[i];
    // The residual of rows a..b at time `ts` after row a (linear between rows).
    let at = |a: usize, b: usize, ts: f64| -> f64 {
        let t = rows[a].t_s + ts;
        let k = interval_at(rows, a, b, t).unwrap_or(b - 2);
        interpolate(rows, k, t, residual)
    };
    let span = |a: usize, b: usize| rows[b - 1].t_s - rows[a].t_s;
    let loaded_s = cycles.iter().map(|&(l, u, _)| span(l, u)).fold(f64::INFINITY, f64::min);
    let decay_s = cycles.iter().map(|&(_, u, n)| span(u, n)).fold(f64::INFINITY, f64::min);
    let mut points: Vec<Vec<f64>> = Vec::new();
    for (phase_s, loading) in [(loaded_s, true), (decay_s, false)] {
        let mut ts = 0.0;
        while ts <= phase_s {
            points.push(cycles.iter().map(|&(l, u, n)| if loading { at(l, u, ts) } else { at(u, n, ts) }).collect());
            ts += CYCLE_GRID_S;
        }
    }
    let k = cycles.len() as f64;
    let bound = t_bound_99(cycles.len() - 1);
    let (mut var, mut mean2, mut beyond) = (0.0, 0.0, 0usize);
    // Times at which a cycle is inside a one-off event (NaN) are left out.
    points.retain(|v| v.iter().all(|x| x.is_finite()));
    for v in &points {
        let m = v.iter().sum::<f64>() / k;
        let s2 = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0);
        var += s2;
        mean2 += m * m;
        beyond += usize::from(m.abs() > bound * (s2 / k).sqrt());
    }
    let n = points.len().max(1) as f64;
    Some(CycleFloor {
        cycles: cycles.len(),
        points: points.len(),
        spread_bar: (var / n).sqrt(),
        systematic_bar: (mean2 / n).sqrt(),
        share_beyond: beyond as f64 / n,
    })
}

/// The unmodelled rate `((p_{i+1} − p_i) − (m_{i+1} − m_i)) / Δt` of every interval that lies
/// inside one phase (not the interval of a switch, whose instant COMP gives only to ± 5 s),
/// binned by time since the phase began: [`ALIGNED_BIN_S`] bins for the first 10 min, then
/// [`ALIGNED_LATE_BIN_S`] bins to the end of the phase (a slow error over a 30 min decay is as
/// much a finding as a fast one after the switch).
pub fn aligned_rate(rows: &[MetroRow], measured: &[f64], curve: &[f64]) -> Vec<AlignedRate> {
    let early = (600.0 / ALIGNED_BIN_S) as usize;
    let bin_of = |since_s: f64| -> (usize, f64, f64) {
        let k = (since_s / ALIGNED_BIN_S) as usize;
        if k < early {
            (k, k as f64 * ALIGNED_BIN_S, ALIGNED_BIN_S)
        } else {
            let late = ((since_s - 600.0) / ALIGNED_LATE_BIN_S) as usize;
            (early + late, 600.0 + late as f64 * ALIGNED_LATE_BIN_S, ALIGNED_LATE_BIN_S)
        }
    };
    // Per bin: the rates and the pressure range they were measured at.
    // (phase, bin) → the bin's rates and the pressure range they were measured at.
    type Bins = std::collections::BTreeMap<(u8, usize), (Vec<f64>, f64, f64)>;
    let mut bins = Bins::new();
    // The late part again in ALIGNED_BIN_S windows ([`AlignedRate::scan`]).
    let mut scan = Bins::new();
    let mut since = f64::NAN;
    for i in 1..rows.len().saturating_sub(1) {
        let (prev, r, next) = (rows[i - 1], rows[i], rows[i + 1]);
        if r.loaded != prev.loaded {
            since = r.t_s;
        }
        // Only intervals of one phase, after the first full interval of that phase (the model
        // restarts at a phase's first rows).
        if next.loaded != r.loaded || !since.is_finite() || r.t_s <= since {
            continue;
        }
        let dt = next.t_s - r.t_s;
        let (Some(&m0), Some(&m1)) = (curve.get(i), curve.get(i + 1)) else { continue };
        if dt <= 0.0 {
            continue;
        }
        let rate = ((measured[i + 1] - measured[i]) - (m1 - m0)) / dt * 60.0;
        if rate.is_finite() {
            let add = |acc: &mut Bins, key: (u8, usize)| {
                let e = acc.entry(key).or_insert((Vec::new(), f64::INFINITY, f64::NEG_INFINITY));
                e.0.push(rate);
                e.1 = e.1.min(measured[i]);
                e.2 = e.2.max(measured[i]);
            };
            add(&mut bins, (u8::from(r.loaded), bin_of(r.t_s - since).0));
            if r.t_s - since >= 600.0 {
                add(&mut scan, (u8::from(r.loaded), ((r.t_s - since - 600.0) / ALIGNED_BIN_S) as usize));
            }
        }
    }
    let rate_of = |phase: u8, from_s: f64, width_s: f64, scan: bool, (v, p_min, p_max): (Vec<f64>, f64, f64)| {
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        AlignedRate {
            phase: if phase == 1 { "loaded" } else { "unloaded" },
            from_s,
            width_s,
            mean_bar_per_min: mean,
            se_bar_per_min: (var / n).sqrt(),
            count: v.len(),
            pressure_bar: (p_min, p_max),
            scan,
        }
    };
    let mut out: Vec<AlignedRate> = bins
        .into_iter()
        .map(|((loaded, bin), acc)| {
            let (_, from_s, width_s) = if bin < early {
                bin_of(bin as f64 * ALIGNED_BIN_S)
            } else {
                bin_of(600.0 + (bin - early) as f64 * ALIGNED_LATE_BIN_S)
            };
            rate_of(loaded, from_s, width_s, false, acc)
        })
        .collect();
    out.extend(
        scan.into_iter()
            .map(|((loaded, k), acc)| rate_of(loaded, 600.0 + k as f64 * ALIGNED_BIN_S, ALIGNED_BIN_S, true, acc)),
    );
    out
}

/// Residual RMS and bias (measured − model), bar, while the compressor is loaded, in the first
/// 2 min after it unloads, and later.
fn phase_rms(rows: &[MetroRow], measured: &[f64], curve: &[f64]) -> [(String, f64, f64); 3] {
    let mut acc = [(0.0, 0.0, 0usize); 3];
    let mut last_unload = f64::NEG_INFINITY;
    for (i, r) in rows.iter().enumerate() {
        if i > 0 && rows[i - 1].loaded && !r.loaded {
            last_unload = r.t_s;
        }
        let k = if r.loaded {
            0
        } else if r.t_s - last_unload < 120.0 {
            1
        } else {
            2
        };
        let e = measured[i] - curve.get(i).copied().unwrap_or(f64::NAN);
        if !e.is_finite() {
            // An event's row (or a missing model row): not the model's to follow.
            continue;
        }
        acc[k].0 += e * e;
        acc[k].1 += e;
        acc[k].2 += 1;
    }
    let names = ["compressor loaded", "first 2 min after unloading", "decay (later)"];
    let phase = |k: usize| {
        let (s, b, c) = acc[k];
        let c = c.max(1) as f64;
        (names[k].to_owned(), (s / c).sqrt(), b / c)
    };
    [phase(0), phase(1), phase(2)]
}

/// Runs the metro audit on rows.
/// Fits the metro candidates to one record: the residual in noise σ of a candidate at a point of
/// its unit box, and the Levenberg–Marquardt fit with the compressor switches estimated
/// ([`estimate_switches`]), on every row or only on the rows a mask keeps (held-out
/// validation, [`HeldOut`]).
struct MetroFitter<'a> {
    rows: &'a [MetroRow],
    measured: Vec<f64>,
    sigma: f64,
    /// One-off events: their rows are left out, and the model restarts after a lasting one.
    events: Vec<OneOffEvent>,
    /// The first row a model follows ([`model_start`]).
    lead: usize,
}

/// A fitted candidate: the optimum and the switches it was run with.
type FitResult = (crate::audit::LmResult, Switches);

/// A candidate model: library mechanisms on the base, and whether the wall is a second thermal
/// node ([`WallNode`]). Its unit box: compressor, outlet, one coordinate per mechanism, then ε
/// and τ_w of the wall ([`wall_at`]).
#[derive(Debug, Clone, PartialEq)]
struct Candidate {
    effects: Vec<Mechanism>,
    wall: bool,
}

impl Candidate {
    fn of(effects: &[Mechanism]) -> Self {
        Self { effects: effects.to_vec(), wall: false }
    }

    /// The mechanisms at their magnitudes in `u` (after the two base coordinates).
    fn on(&self, u: &[f64]) -> Vec<(Mechanism, f64)> {
        self.effects
            .iter()
            .enumerate()
            .map(|(i, &e)| (e, metro_value(e, u.get(2 + i).copied().unwrap_or(0.0))))
            .collect()
    }

    /// Index of the wall's first coordinate.
    fn wall_index(&self) -> usize {
        2 + self.effects.len()
    }

    /// The core reservoir's parameters at `u`.
    fn params(&self, u: &[f64]) -> ReservoirParams {
        let mut p = metro_params(u, &self.on(u));
        if self.wall {
            p.wall = wall_at(u.get(self.wall_index()..).unwrap_or(&[]));
        }
        p
    }

    /// Name in reports: the mechanisms joined by `+`, then `wall_heat`.
    fn name(&self) -> String {
        if self.effects.is_empty() && !self.wall {
            return "base".to_owned();
        }
        let mut names: Vec<&str> = self.effects.iter().map(|e| e.name()).collect();
        if self.wall {
            names.push(WALL_HEAT);
        }
        names.join("+")
    }
}

/// Name of the wall node in the metro audit's reports ([`WallNode`]).
pub const WALL_HEAT: &str = "wall_heat";
/// Range of the wall's heat-capacity ratio ε in the fit (log scale).
pub const WALL_CAPACITY_SEARCH: (f64, f64) = (0.01, 3.0);
/// Range of the wall's cooling time τ_w in the fit, s (log scale).
pub const WALL_COOLING_SEARCH_S: (f64, f64) = (60.0, 20_000.0);

/// The wall node at the unit-box coordinates `u` = (ε, τ_w), each on a log scale over its search
/// range.
fn wall_at(u: &[f64]) -> WallNode {
    let log = |i: usize, (lo, hi): (f64, f64)| lo * (hi / lo).powf(u.get(i).copied().unwrap_or(0.5).clamp(0.0, 1.0));
    WallNode { capacity_ratio: log(0, WALL_CAPACITY_SEARCH), cooling_s: log(1, WALL_COOLING_SEARCH_S) }
}

/// The unit-box coordinate of a value on a log scale over `(lo, hi)`.
fn log_coordinate(v: f64, (lo, hi): (f64, f64)) -> f64 {
    ((v / lo).ln() / (hi / lo).ln()).clamp(0.0, 1.0)
}

impl MetroFitter<'_> {
    /// The candidate's curve at `u` ([`simulate_around`] the events).
    fn simulate(&self, u: &[f64], c: &Candidate, sw: &Switches) -> Option<Vec<f64>> {
        simulate_around(self.rows, &c.params(u), sw, &self.events)
    }

    /// Residual (σ units) of the rows `keep` admits (all with `None`) outside the events.
    fn resid(&self, u: &[f64], c: &Candidate, sw: &Switches, keep: Option<&[bool]>) -> Option<Vec<f64>> {
        let m = self.simulate(u, c, sw)?;
        let r: Vec<f64> = m
            .iter()
            .zip(&self.measured)
            .enumerate()
            .filter(|(i, _)| *i >= self.lead && keep.is_none_or(|k| k[*i]) && !in_event(&self.events, *i))
            .map(|(_, (a, b))| (a - b) / self.sigma)
            .collect();
        r.iter().all(|v| v.is_finite()).then_some(r)
    }

    fn fit_at(
        &self,
        c: &Candidate,
        starts: &[Vec<f64>],
        sw: &Switches,
        keep: Option<&[bool]>,
    ) -> Option<crate::audit::LmResult> {
        starts
            .par_iter()
            .filter_map(|x0| levenberg_marquardt(&|u: &[f64]| self.resid(u, c, sw, keep), x0, 60))
            .min_by(|a, b| a.rss.total_cmp(&b.rss))
    }

    /// Every candidate is fitted with the compressor switches at the midpoints of their sampling
    /// intervals, then with the switches estimated for its optimum, refitted, twice
    /// ([`estimate_switches`]): each model gets the same nuisance freedom, so the comparison
    /// stays fair and the switch timing no longer pulls the parameters. A cycle's switches move
    /// only that cycle's rows (the model restarts before each loading phase), so the switches
    /// of a held-out cycle do not touch the fit.
    fn fit(&self, c: &Candidate, starts: Vec<Vec<f64>>, keep: Option<&[bool]>) -> Option<FitResult> {
        let mut lm = self.fit_at(c, &starts, &Switches::MIDPOINT, keep)?;
        let mut sw = Switches::MIDPOINT;
        for _ in 0..SWITCH_ROUNDS {
            let next = estimate_switches(self.rows, &c.params(&lm.x), &self.events)?;
            match self.fit_at(c, std::slice::from_ref(&lm.x), &next, keep) {
                Some(refit) if refit.rss < lm.rss => {
                    lm = refit;
                    sw = next;
                }
                _ => break,
            }
        }
        Some((lm, sw))
    }

    /// Leave-one-cycle-out validation of a candidate fitted at `x` on every row: for each
    /// complete cycle, the candidate is refitted on the other rows (from `x`) and predicts the
    /// cycle; `None` with fewer than [`HELD_OUT_MIN_CYCLES`] complete cycles.
    ///
    /// Returns the validation and each fold's optimum (for the jackknife uncertainty).
    fn held_out(&self, c: &Candidate, x: &[f64], in_sample: &[f64]) -> Option<(HeldOut, Vec<Vec<f64>>)> {
        let cycles = complete_cycles(self.rows);
        if cycles.len() < HELD_OUT_MIN_CYCLES {
            return None;
        }
        // Cycles are dealt to at most HELD_OUT_MAX_FOLDS folds in turn (1, 2, …, k, 1, 2, …), so a
        // long record costs k refits, not one per cycle, and each fold spans the whole record.
        let k = cycles.len().min(HELD_OUT_MAX_FOLDS);
        let n = self.rows.len();
        // Per fold: its held-out (first, end) rows, the predicted curve and the fold's optimum.
        type Fold = (Vec<(usize, usize)>, Vec<f64>, Vec<f64>);
        let folds: Vec<Option<Fold>> = (0..k)
            .into_par_iter()
            .map(|f| {
                // The row before the loading is the cycle's initial condition (the model restarts
                // on it), so the held-out rows are the loading start up to the next one.
                let out: Vec<(usize, usize)> =
                    cycles.iter().skip(f).step_by(k).map(|&(l, _, next)| (l, next)).collect();
                let keep: Vec<bool> = (0..n).map(|i| !out.iter().any(|&(l, next)| (l..next).contains(&i))).collect();
                let (lm, sw) = self.fit(c, vec![x.to_vec()], Some(&keep))?;
                let curve = self.simulate(&lm.x, c, &sw)?;
                Some((out, curve, lm.x))
            })
            .collect();
        let (mut measured, mut predicted, mut fitted, mut optima) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for fold in folds {
            let (out, curve, x) = fold?;
            for (l, next) in out {
                for i in (l..next).filter(|&i| !in_event(&self.events, i)) {
                    measured.push(self.measured[i]);
                    predicted.push(*curve.get(i)?);
                    fitted.push(*in_sample.get(i)?);
                }
            }
            optima.push(x);
        }
        let held = HeldOut {
            cycles: cycles.len(),
            folds: k,
            rows: measured.len(),
            nmse_pct: pbm::metrics::nmse_pct(&measured, &predicted)?,
            in_sample_nmse_pct: pbm::metrics::nmse_pct(&measured, &fitted)?,
        };
        Some((held, optima))
    }
}

/// Width of the windows in which [`one_off_events`] compares the decay rates of the cycles, s.
pub const EVENT_WINDOW_S: f64 = 60.0;
/// The first minutes after unloading are not searched for one-off events: there the decay rate
/// changes fast and the ± 5 s of the COMP sampling moves it more than an event would.
pub const EVENT_SKIP_S: f64 = 180.0;
/// A window's rate is an event when it is this many robust σ of the cycle-to-cycle differences
/// away from the other cycles' rate in the same window (and by at least [`EVENT_MIN_BAR_PER_MIN`]).
pub const EVENT_SIGMAS: f64 = 8.0;
/// Windows after an event in which its pressure may come back to the other cycles' course
/// ([`OneOffEvent::recovered`]).
pub const EVENT_RECOVERY_WINDOWS: usize = 10;
/// Smallest rate difference called an event, bar/min: ten times the rate noise that a 1.2 mbar
/// transducer noise leaves in a 60 s window (√2 · 1.2 mbar per min), so quantisation alone
/// never makes one.
pub const EVENT_MIN_BAR_PER_MIN: f64 = 0.017;

/// A one-off change of the air consumption in one cycle (issue 17: tell a systematic mechanism
/// from a one-off event, and report the event as such instead of bending a mechanism to fit
/// it). Found without any model ([`one_off_events`]): in a window of the decay, one cycle's
/// pressure falls at a rate the other cycles, at the same time after unloading, do not share.
/// The audit leaves its rows out of every fit and figure; when the pressure did not come back, it
/// also restarts the model on the measured pressure after it (an input the record does not hold,
/// like the consumption itself).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OneOffEvent {
    /// The complete cycle it happened in (1 = the record's first).
    pub cycle: usize,
    /// First and last row it covers.
    pub rows: (usize, usize),
    /// Seconds since the record's first row, start and end.
    pub t_s: (f64, f64),
    /// Seconds after the compressor unloaded at which it began.
    pub since_unload_s: f64,
    /// Pressure range over it, bar.
    pub pressure_bar: (f64, f64),
    /// Largest pressure the cycle had lost beyond what the other cycles lost since the event
    /// began, bar (negative: it lost less; an inflow).
    pub dip_bar: f64,
    /// What it had lost beyond them at the event's end, bar: ≈ 0 when the pressure came back
    /// ([`Self::recovered`]).
    pub net_bar: f64,
    /// The pressure returned to the other cycles' course within [`EVENT_RECOVERY_WINDOWS`]
    /// windows: a transient, not a lasting loss. Otherwise the model restarts after the event.
    pub recovered: bool,
    /// Largest window difference in robust σ of the cycle-to-cycle differences.
    pub sigmas: f64,
}

impl OneOffEvent {
    /// Air that a pressure change of `bar` is, g, at the assumed volume [`METRO_VOLUME_M3`] and
    /// the wall temperature (m = Δp V / (R T)).
    pub fn air_g(bar: f64) -> f64 {
        bar * 1e5 * METRO_VOLUME_M3 / (pbm::params::GAS_CONSTANT * TEMPERATURE_K) * 1e3
    }

    /// One sentence: when, where and how much air.
    pub fn describe(&self) -> String {
        let what = if self.dip_bar >= 0.0 { "more outflow" } else { "less outflow" };
        let mut s = format!(
            "a one-off event in cycle {} from {:.0} to {:.0} s of the record ({:.0} s after unloading, {:.2}–{:.2} \
             bar): {:.3} bar {what} than the other cycles at that time (≈ {:.0} g of air at {} m³)",
            self.cycle,
            self.t_s.0,
            self.t_s.1,
            self.since_unload_s,
            self.pressure_bar.0,
            self.pressure_bar.1,
            self.dip_bar.abs(),
            Self::air_g(self.dip_bar.abs()),
            METRO_VOLUME_M3,
        );
        if self.recovered {
            s.push_str(", then the pressure came back to the other cycles' course");
        } else {
            s.push_str(&format!(", a lasting change of {:+.3} bar", -self.net_bar));
        }
        s
    }
}

/// Finds [`OneOffEvent`]s in the decays of the complete cycles, without a model: each decay is
/// cut into [`EVENT_WINDOW_S`] windows from [`EVENT_SKIP_S`] after the unloading, and a cycle's
/// rate in a window is compared with the median of the other cycles' rates in the same window
/// (at least two others). The differences' robust σ (1.4826 · MAD over every cycle and window)
/// is the cycle-to-cycle variation; a difference beyond [`EVENT_SIGMAS`] of it (and
/// [`EVENT_MIN_BAR_PER_MIN`]) in one cycle only is an event. Neighbouring windows of one cycle
/// (a gap of one allowed) make one event. A mechanism acts in every cycle, so it never shows here.
/// After a lasting change of consumption ([`consumption_change`], looked for first without
/// events) the cycles are compared only with those on their side of it.
pub fn one_off_events(rows: &[MetroRow]) -> Vec<OneOffEvent> {
    let change = consumption_change(rows, &[]);
    one_off_events_split(rows, change.map_or(usize::MAX, |c| c.first_cycle_after - 1))
}

/// [`one_off_events`] with the cycles before complete cycle `split` (0-based) compared only with
/// each other, and those from it on only with each other: after a lasting change of consumption
/// ([`consumption_change`]) the other side's cycles are not the reference (every cycle of the
/// smaller side would otherwise differ from the median of the rest).
fn one_off_events_split(rows: &[MetroRow], split: usize) -> Vec<OneOffEvent> {
    let cycles = complete_cycles(rows);
    if cycles.len() < 3 {
        return Vec::new();
    }
    let same_side = |a: usize, b: usize| (a < split) == (b < split);
    // Pressure of the decay u..n at `ts` after its first row (linear between rows), if inside.
    let at = |u: usize, n: usize, ts: f64| -> Option<f64> {
        let t = rows[u].t_s + ts;
        Some(interpolate(rows, interval_at(rows, u, n, t)?, t, |i| rows[i].tp3_bar))
    };
    let longest = cycles.iter().map(|&(_, u, n)| rows[n - 1].t_s - rows[u].t_s).fold(0.0, f64::max);
    let windows = ((longest - EVENT_SKIP_S) / EVENT_WINDOW_S).max(0.0) as usize;
    // rate[c][w], bar/min.
    let rate: Vec<Vec<Option<f64>>> = cycles
        .iter()
        .map(|&(_, u, n)| {
            (0..windows)
                .map(|w| {
                    let a = EVENT_SKIP_S + w as f64 * EVENT_WINDOW_S;
                    Some((at(u, n, a + EVENT_WINDOW_S)? - at(u, n, a)?) / EVENT_WINDOW_S * 60.0)
                })
                .collect()
        })
        .collect();
    let median = |mut v: Vec<f64>| -> f64 {
        v.sort_by(f64::total_cmp);
        let m = v.len() / 2;
        if v.len() % 2 == 0 {
            (v[m - 1] + v[m]) / 2.0
        } else {
            v[m]
        }
    };
    let mut diff: Vec<Vec<Option<f64>>> = vec![vec![None; windows]; cycles.len()];
    for w in 0..windows {
        for c in 0..cycles.len() {
            let others: Vec<f64> =
                (0..cycles.len()).filter(|&o| o != c && same_side(o, c)).filter_map(|o| rate[o][w]).collect();
            if let (Some(r), true) = (rate[c][w], others.len() >= 2) {
                diff[c][w] = Some(r - median(others));
            }
        }
    }
    let all: Vec<f64> = diff.iter().flatten().flatten().map(|d| d.abs()).collect();
    if all.len() < 8 {
        return Vec::new();
    }
    let sigma = (1.4826 * median(all)).max(1e-6);
    let big = |c: usize, w: usize| {
        diff[c][w].is_some_and(|d| d.abs() > EVENT_SIGMAS * sigma && d.abs() > EVENT_MIN_BAR_PER_MIN)
    };
    let mut events = Vec::new();
    for (c, &(_, u, n)) in cycles.iter().enumerate() {
        // A window where another cycle is off too is not one cycle's event.
        let flagged: Vec<bool> = (0..windows)
            .map(|w| big(c, w) && !(0..cycles.len()).any(|o| o != c && same_side(o, c) && big(o, w)))
            .collect();
        let mut w = 0;
        while w < windows {
            if !flagged[w] {
                w += 1;
                continue;
            }
            let mut end = w;
            while end + 1 < windows && (flagged[end + 1] || (end + 2 < windows && flagged[end + 2])) {
                end += 1;
            }
            // An event rarely fills whole windows: the windows on either side that lean the same
            // way by more than the noise (3 σ) belong to it too.
            let sign = diff[c][w].unwrap_or(0.0).signum();
            let leans = |k: usize| diff[c][k].is_some_and(|d| d * sign > 3.0 * sigma);
            let mut start = w;
            while start > 0 && leans(start - 1) {
                start -= 1;
            }
            while end + 1 < windows && leans(end + 1) {
                end += 1;
            }
            // Then follow what the cycle has lost beyond the others since the event began: if it
            // comes back (within a noise-sized band, or to a fifth of its peak) in the next
            // windows, the event is a transient and ends there; otherwise it ends with its last
            // flagged window and the model restarts after it.
            let lost =
                |to: usize| -> f64 { -(start..=to).filter_map(|k| diff[c][k]).sum::<f64>() * EVENT_WINDOW_S / 60.0 };
            let peak = (start..=end).map(lost).fold(0.0f64, |a, v| if v.abs() > a.abs() { v } else { a });
            let band = (3.0 * sigma * EVENT_WINDOW_S / 60.0).max(0.2 * peak.abs());
            let back = (end + 1..windows.min(end + 1 + EVENT_RECOVERY_WINDOWS)).find(|&k| lost(k).abs() <= band);
            let recovered = back.is_some();
            let end = back.unwrap_or(end);
            let (from, to) =
                (EVENT_SKIP_S + start as f64 * EVENT_WINDOW_S, EVENT_SKIP_S + (end + 1) as f64 * EVENT_WINDOW_S);
            let inside: Vec<usize> = (u..n).filter(|&i| (from..=to).contains(&(rows[i].t_s - rows[u].t_s))).collect();
            if let (Some(&first), Some(&last)) = (inside.first(), inside.last()) {
                let p = inside.iter().map(|&i| rows[i].tp3_bar);
                events.push(OneOffEvent {
                    cycle: c + 1,
                    rows: (first, last),
                    t_s: (rows[first].t_s, rows[last].t_s),
                    since_unload_s: rows[first].t_s - rows[u].t_s,
                    pressure_bar: (p.clone().fold(f64::INFINITY, f64::min), p.fold(f64::NEG_INFINITY, f64::max)),
                    dip_bar: peak,
                    net_bar: lost(end),
                    recovered,
                    sigmas: (start..=end).filter_map(|k| diff[c][k]).map(|d| d.abs() / sigma).fold(0.0, f64::max),
                });
            }
            w = end + 1;
        }
    }
    events
}

/// Fewest complete cycles in which [`consumption_change`] looks for a lasting change (two on each
/// side of it and one to place it).
pub const CHANGE_MIN_CYCLES: usize = 5;
/// Sequences of independent cycles that [`consumption_change`] compares the record with.
pub const CHANGE_SIMULATIONS: usize = 1999;
/// A change is reported when at most this share of those sequences splits as strongly.
pub const CHANGE_ALPHA: f64 = 0.01;
/// Smallest change of the decay rate reported, bar/min (≈ 3 g of air a minute at 0.5 m³; ten
/// times the cycle-to-cycle spread of the decay rates in the MetroPT-3 extract).
pub const CHANGE_MIN_BAR_PER_MIN: f64 = 0.005;

/// How the decay rate moves over the record ([`ConsumptionChange`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChangeShape {
    /// One level up to a cycle, another from the next one on (a leak that opened, a consumer
    /// switched on).
    Step,
    /// A steady drift over the cycles (a straight line fits them better than any step).
    Drift,
}

/// A lasting change of the air consumption over the record (issue 17: a mid-record step was only
/// `unexplained`, without saying when). Found without a model ([`consumption_change`]): each
/// complete cycle's decay rate over a window common to all of them (from [`EVENT_SKIP_S`] after
/// unloading to the end of the shortest decay), and the split of that sequence into an earlier
/// and a later group that differ most (the largest two-sample t over the splits). It is reported
/// only when three things hold: fewer than [`CHANGE_ALPHA`] of [`CHANGE_SIMULATIONS`] sequences of
/// independent, identically distributed cycles split as strongly (the maximum over the splits is
/// what is tested, so trying every split is paid for), every cycle of one group is beyond every
/// cycle of the other (one odd cycle cannot make it), and the rates differ by at least
/// [`CHANGE_MIN_BAR_PER_MIN`]. Cycle-to-cycle variation in consumption (which the record does not
/// hold either) is then not mistaken for a change. A model with constant parameters cannot follow
/// such a change; the audit names when it happened instead of bending a mechanism to it.
#[derive(Debug, Clone, PartialEq)]
pub struct ConsumptionChange {
    /// Step or drift.
    pub shape: ChangeShape,
    /// Decay rate of every complete cycle over the common window, bar/min (negative: falling),
    /// in order; a cycle whose window lies inside one-off events has none and is left out.
    pub cycle_rates: Vec<f64>,
    /// The common window, s after unloading.
    pub window_s: (f64, f64),
    /// The first complete cycle (1 = the record's first) after the change.
    pub first_cycle_after: usize,
    /// The change lies between these two instants, s since the record's first row. A change inside
    /// a window moves that cycle's rate only part of the way: when the last cycle before the change
    /// (or the first after it) is more than 3 σ of the other cycles' spread from its group toward
    /// the other group, the change is placed inside its window; otherwise between the two
    /// windows.
    pub between_s: (f64, f64),
    /// Mean decay rate before and after the change (for a drift: of the first and the last of
    /// the split's groups), bar/min.
    pub rate_bar_per_min: (f64, f64),
    /// Share of the simulated independent sequences that split as strongly (the record counted).
    pub p_value: f64,
}

impl ConsumptionChange {
    /// One sentence: when, which way and how strong.
    pub fn describe(&self) -> String {
        let (a, b) = self.rate_bar_per_min;
        let which = if b < a { "faster" } else { "slower" };
        let hours = |s: f64| s / 3600.0;
        match self.shape {
            ChangeShape::Step => format!(
                "a lasting change of the air consumption: from cycle {} on, the pressure falls {which} ({a:.4} → \
                 {b:.4} bar/min, {:.0}–{:.0} s after unloading); it began between {:.2} h and {:.2} h into the record \
                 (p ≤ {:.3} against independent cycles)",
                self.first_cycle_after,
                self.window_s.0,
                self.window_s.1,
                hours(self.between_s.0),
                hours(self.between_s.1),
                self.p_value
            ),
            ChangeShape::Drift => format!(
                "a drift of the air consumption over the record: the pressure falls {which} from cycle to cycle \
                 ({a:.4} → {b:.4} bar/min, {:.0}–{:.0} s after unloading; p ≤ {:.3} against independent cycles)",
                self.window_s.0, self.window_s.1, self.p_value
            ),
        }
    }
}

/// Least-squares slope of TP3 over `t` in rows a..b, bar/min, with every run of rows outside the
/// one-off `events` given an intercept of its own (an event's rows are left out, and a pressure
/// that did not come back after it does not tilt the slope). `None` without 3 rows.
fn decay_slope(rows: &[MetroRow], events: &[OneOffEvent], a: usize, b: usize) -> Option<f64> {
    let (mut sxy, mut sxx, mut used) = (0.0, 0.0, 0usize);
    let mut i = a;
    while i < b {
        if in_event(events, i) {
            i += 1;
            continue;
        }
        let j = (i..b).find(|&k| in_event(events, k)).unwrap_or(b);
        let n = (j - i) as f64;
        let (tm, pm) =
            (rows[i..j].iter().map(|r| r.t_s).sum::<f64>() / n, rows[i..j].iter().map(|r| r.tp3_bar).sum::<f64>() / n);
        for r in &rows[i..j] {
            sxy += (r.t_s - tm) * (r.tp3_bar - pm);
            sxx += (r.t_s - tm).powi(2);
        }
        used += j - i;
        i = j;
    }
    (used >= 3 && sxx > 0.0).then(|| sxy / sxx * 60.0)
}

/// The strongest split of `x` into an earlier and a later group of at least two: (t statistic of
/// the difference of their means with pooled variance, index of the first of the later group).
fn best_split(x: &[f64]) -> (f64, usize) {
    let n = x.len();
    let mut best = (0.0, 0);
    for k in 2..=n.saturating_sub(2) {
        let (l, r) = x.split_at(k);
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (ml, mr) = (mean(l), mean(r));
        let ss = l.iter().map(|v| (v - ml).powi(2)).sum::<f64>() + r.iter().map(|v| (v - mr).powi(2)).sum::<f64>();
        let s2 = (ss / (n - 2) as f64).max(1e-18);
        let t = (mr - ml).abs() / (s2 * (1.0 / k as f64 + 1.0 / (n - k) as f64)).sqrt();
        if t > best.0 {
            best = (t, k);
        }
    }
    best
}

/// The record's lasting change of air consumption ([`ConsumptionChange`]), or `None` when the
/// cycles' decay rates show none (or there are fewer than [`CHANGE_MIN_CYCLES`] complete cycles
/// to tell one from the cycle-to-cycle variation).
pub fn consumption_change(rows: &[MetroRow], events: &[OneOffEvent]) -> Option<ConsumptionChange> {
    use rand_core::{Rng, SeedableRng};
    let cycles = complete_cycles(rows);
    if cycles.len() < CHANGE_MIN_CYCLES {
        return None;
    }
    let decay_s = cycles.iter().map(|&(_, u, n)| rows[n - 1].t_s - rows[u].t_s).fold(f64::INFINITY, f64::min);
    let window_s = (EVENT_SKIP_S, decay_s);
    if decay_s < EVENT_SKIP_S + 3.0 * EVENT_WINDOW_S {
        return None;
    }
    let in_window = |u: usize, n: usize| {
        let t0 = rows[u].t_s;
        let a = (u..n).find(|&i| rows[i].t_s - t0 >= window_s.0)?;
        let b = (a..n).find(|&i| rows[i].t_s - t0 > window_s.1).unwrap_or(n);
        Some((a, b))
    };
    // Every cycle whose window is not all inside one-off events, with its window's rows.
    // (complete cycle, its window's rows, its rate)
    let kept: Vec<(usize, (usize, usize), f64)> = cycles
        .iter()
        .enumerate()
        .filter_map(|(c, &(_, u, n))| {
            let (a, b) = in_window(u, n)?;
            Some((c, (a, b), decay_slope(rows, events, a, b)?))
        })
        .collect();
    let rates: Vec<f64> = kept.iter().map(|k| k.2).collect();
    if rates.len() < CHANGE_MIN_CYCLES {
        return None;
    }
    let (t, k) = best_split(&rates);
    if k == 0 {
        return None;
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (before, after) = rates.split_at(k);
    let range = |v: &[f64]| {
        (v.iter().copied().fold(f64::INFINITY, f64::min), v.iter().copied().fold(f64::NEG_INFINITY, f64::max))
    };
    let ((before_lo, before_hi), (after_lo, after_hi)) = (range(before), range(after));
    let separated = before_hi < after_lo || after_hi < before_lo;
    if !separated || (mean(after) - mean(before)).abs() < CHANGE_MIN_BAR_PER_MIN {
        return None;
    }
    // The maximum t over the splits of independent normal cycles (t does not depend on their
    // mean or scale), by simulation: a fixed seed, so the audit is reproducible.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x0c0a_5e17);
    let mut unit = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let mut simulated = vec![0.0; rates.len()];
    let mut as_strong = 1usize;
    for _ in 0..CHANGE_SIMULATIONS {
        for v in simulated.iter_mut() {
            let (a, b) = (unit().max(f64::MIN_POSITIVE), unit());
            *v = (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos();
        }
        as_strong += usize::from(best_split(&simulated).0 >= t);
    }
    let p_value = as_strong as f64 / (CHANGE_SIMULATIONS + 1) as f64;
    if p_value > CHANGE_ALPHA {
        return None;
    }
    // A straight line over the cycles against the step: the smaller residual names the shape.
    let n = rates.len() as f64;
    let xm = (n - 1.0) / 2.0;
    let ym = mean(&rates);
    let sxx: f64 = (0..rates.len()).map(|i| (i as f64 - xm).powi(2)).sum();
    let slope = rates.iter().enumerate().map(|(i, y)| (i as f64 - xm) * (y - ym)).sum::<f64>() / sxx;
    let line_ss: f64 = rates.iter().enumerate().map(|(i, y)| (y - ym - slope * (i as f64 - xm)).powi(2)).sum();
    let (mb, ma) = (mean(before), mean(after));
    let step_ss: f64 =
        before.iter().map(|v| (v - mb).powi(2)).sum::<f64>() + after.iter().map(|v| (v - ma).powi(2)).sum::<f64>();
    // Where in time: the boundary cycles against the spread of the other cycles about their
    // group's mean.
    let others: Vec<f64> = before[..k - 1]
        .iter()
        .map(|v| v - mean(&before[..k - 1]))
        .chain(after[1..].iter().map(|v| v - mean(&after[1..])))
        .collect();
    let spread = (others.iter().map(|d| d * d).sum::<f64>() / (others.len() - 2).max(1) as f64).sqrt();
    let toward = |r: f64, from: f64, to: f64| (r - from) * (to - from).signum() > 3.0 * spread;
    let window = |c: usize| {
        let (a, b) = kept[c].1;
        (rows[a].t_s, rows[b - 1].t_s)
    };
    let between_s = if toward(rates[k - 1], mean(&before[..k - 1]), ma) {
        window(k - 1)
    } else if toward(rates[k], mean(&after[1..]), mb) {
        window(k)
    } else {
        (window(k - 1).1, window(k).0)
    };
    Some(ConsumptionChange {
        shape: if line_ss < step_ss { ChangeShape::Drift } else { ChangeShape::Step },
        first_cycle_after: kept[k].0 + 1,
        between_s,
        rate_bar_per_min: (mb, ma),
        window_s,
        cycle_rates: rates,
        p_value,
    })
}

/// Point-to-point scatter of TP3 while the compressor is loaded, bar, from the record alone: the
/// rate changes from one sampling interval to the next inside each loading phase (without the
/// intervals where the compressor switches or the delivery starts), less their mean per phase (the smooth
/// slowing of the fill), over √6 (the second difference of white noise has 6 times its
/// variance). In MetroPT-3 it is ≈ 20× the transducer noise: the pressure rises 0.2 bar between
/// rows, and a second of sampling jitter or a pulsing delivery moves a row by 0.02 bar. No
/// model driven by a 10 s COMP record can follow it. `None` without three such intervals.
pub fn loaded_jitter_bar(rows: &[MetroRow]) -> Option<f64> {
    let mut dev = Vec::new();
    let mut i = 1;
    while i < rows.len() {
        if !rows[i].loaded || rows[i - 1].loaded {
            i += 1;
            continue;
        }
        let end = (i..rows.len()).find(|&k| !rows[k].loaded).unwrap_or(rows.len());
        // Rate changes between consecutive intervals of rows i..end, inner ones only.
        let rate = |k: usize| (rows[k + 1].tp3_bar - rows[k].tp3_bar) / (rows[k + 1].t_s - rows[k].t_s).max(1e-9);
        // Intervals i..end−1 lie inside the phase; the first of them also holds the transport
        // delay's end (the delivery starts in it), so the changes start from the second.
        let d: Vec<f64> =
            (i + 2..end.saturating_sub(1)).map(|k| (rate(k) - rate(k - 1)) * (rows[k + 1].t_s - rows[k].t_s)).collect();
        if d.len() >= 2 {
            let m = d.iter().sum::<f64>() / d.len() as f64;
            dev.extend(d.iter().map(|x| x - m));
        }
        i = end;
    }
    (dev.len() >= 3).then(|| (dev.iter().map(|x| x * x).sum::<f64>() / dev.len() as f64 / 6.0).sqrt())
}

/// What this record lets any model driven by COMP reach on held-out cycles: the NMSE (SPEC §6
/// Eq. 16, over the held-out rows) that the loaded phases' own scatter ([`loaded_jitter_bar`])
/// and the decays' cycle-to-cycle spread ([`CycleFloor::spread_bar`]) alone leave. A model
/// within about 1.5× of it has nothing systematic left that the record can show.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordFloor {
    /// [`loaded_jitter_bar`].
    pub loaded_jitter_bar: f64,
    /// The decays' spread between cycles at equal time since the switch, bar.
    pub decay_spread_bar: f64,
    /// The NMSE those two leave on the complete cycles' rows, %.
    pub nmse_pct: f64,
}

/// [`RecordFloor`] of `rows` with the cycle-to-cycle spread `spread_bar`; `None` without
/// complete cycles or a loaded-phase scatter.
fn record_floor(rows: &[MetroRow], events: &[OneOffEvent], spread_bar: f64) -> Option<RecordFloor> {
    let jitter = loaded_jitter_bar(rows)?;
    let (mut sum, mut n) = (0.0, 0usize);
    for (l, _, next) in complete_cycles(rows) {
        for i in (l..next).filter(|&i| !in_event(events, i)) {
            let p = rows[i].tp3_bar;
            if p > pbm::metrics::NMSE_MIN_BAR_G {
                let sd = if rows[i].loaded { jitter } else { spread_bar };
                sum += (sd / p).powi(2);
                n += 1;
            }
        }
    }
    (n > 0).then(|| RecordFloor {
        loaded_jitter_bar: jitter,
        decay_spread_bar: spread_bar,
        nmse_pct: 100.0 * (sum / n as f64).sqrt(),
    })
}

/// Fewest complete compressor cycles for a held-out validation ([`HeldOut`]): each fold fits on
/// the others, so at least two must remain. The audit refuses a record with fewer.
pub const HELD_OUT_MIN_CYCLES: usize = 3;
/// Most folds of the held-out validation: more cycles are dealt to this many folds.
pub const HELD_OUT_MAX_FOLDS: usize = 5;

/// Held-out validation of a fitted candidate (issue 17: a model is judged on the compressor
/// cycles it was not fitted to). Every complete cycle (a loading phase and the decay to the next
/// one) is held out once, in at most [`HELD_OUT_MAX_FOLDS`] folds (one cycle per fold up to that
/// many cycles): the candidate is refitted on the rest of the record and predicts the fold's
/// cycles from the pressure at each one's start, the same initial condition the fit uses. The
/// folds' optima also give each magnitude a jackknife uncertainty (the spread the cycles
/// themselves cause), which the reported 1 σ never falls below.
/// Only the two compressor switch instants of the held-out cycle come from its own rows (COMP
/// gives them only to its 10 s sampling, [`estimate_switches`]); every model parameter comes
/// from the other cycles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldOut {
    /// Complete cycles, each held out once.
    pub cycles: usize,
    /// Folds they were dealt to (one refit each; [`HELD_OUT_MAX_FOLDS`] at most).
    pub folds: usize,
    /// Rows predicted (the complete cycles' rows).
    pub rows: usize,
    /// NMSE of the held-out predictions over those rows, %.
    pub nmse_pct: f64,
    /// NMSE of the fit to every row over the same rows, %: held-out well above it is overfit.
    pub in_sample_nmse_pct: f64,
}

/// (loading start, unloading start, next loading start) row indices of every complete cycle.
fn complete_cycles(rows: &[MetroRow]) -> Vec<(usize, usize, usize)> {
    let loads: Vec<usize> = (1..rows.len()).filter(|&i| rows[i].loaded && !rows[i - 1].loaded).collect();
    loads
        .windows(2)
        .filter_map(|w| (w[0]..w[1]).find(|&i| !rows[i].loaded).map(|u| (w[0], u, w[1])))
        .filter(|&(l, u, n)| u > l + 1 && n > u + 1)
        .collect()
}

/// Gauge pressures a compressed-air reservoir record may hold, bar g (a reading outside is not a
/// reservoir pressure in bar: another unit, a sign error, a broken channel).
pub const TP3_RANGE_BAR_G: (f64, f64) = (-0.5, 20.0);
/// Smallest median pressure rise over the loading phases, bar: a compressor that loads without
/// raising the pressure is not what the model describes (a frozen or disconnected channel).
pub const MIN_LOADED_RISE_BAR: f64 = 0.05;

/// Refuses a record the audit cannot judge, with the reason: a pressure outside
/// [`TP3_RANGE_BAR_G`], fewer than [`HELD_OUT_MIN_CYCLES`] complete compressor cycles (no cycle
/// to hold out, and a cause named on one cycle is a guess), or loading phases that do not raise
/// the pressure.
pub fn check_record(rows: &[MetroRow]) -> Result<()> {
    let (lo, hi) = TP3_RANGE_BAR_G;
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| !(lo..=hi).contains(&r.tp3_bar)) {
        anyhow::bail!(
            "TP3 reads {} bar at row {} ({} s): outside {lo}…{hi} bar g, not a compressed-air reservoir pressure \
             in bar",
            r.tp3_bar,
            i + 1,
            r.t_s
        );
    }
    let cycles = complete_cycles(rows);
    if cycles.len() < HELD_OUT_MIN_CYCLES {
        anyhow::bail!(
            "the record holds {} complete compressor cycles (a loading phase and the decay to the next loading); \
             the audit needs at least {HELD_OUT_MIN_CYCLES}, to validate every model on cycles it was not fitted to",
            cycles.len()
        );
    }
    let mut rises: Vec<f64> = cycles.iter().map(|&(l, u, _)| rows[u].tp3_bar - rows[l - 1].tp3_bar).collect();
    rises.sort_by(f64::total_cmp);
    let median = rises[rises.len() / 2];
    if median < MIN_LOADED_RISE_BAR {
        anyhow::bail!(
            "the pressure does not rise while the compressor is loaded (median rise {median:.3} bar over {} cycles): \
             a frozen or disconnected TP3, or COMP not the compressor's load signal",
            cycles.len()
        );
    }
    Ok(())
}

/// The metro audit ([`MetroOutcome`]) with every fitted candidate validated on held-out
/// compressor cycles ([`HeldOut`]).
pub fn audit_metro(rows: &[MetroRow]) -> Result<MetroOutcome> {
    audit_metro_with(rows, true)
}

/// [`audit_metro`], with the held-out validation only when `validate` (the synthetic sweep
/// scores the verdict and skips it: it refits every candidate once per cycle).
pub fn audit_metro_with(rows: &[MetroRow], validate: bool) -> Result<MetroOutcome> {
    check_record(rows)?;
    let measured: Vec<f64> = rows.iter().map(|r| r.tp3_bar).collect();
    let sigma = noise_sigma(&measured).max(1e-3);
    let events = one_off_events(rows);
    let lead = model_start(rows);
    let fitter = MetroFitter { rows, measured: measured.clone(), sigma, events: events.clone(), lead };
    // The measurements a model is judged on: NaN before the first complete cycle and on the
    // events' rows (the summaries skip them).
    let observed: Vec<f64> = measured
        .iter()
        .enumerate()
        .map(|(i, &m)| if i < lead || in_event(&events, i) { f64::NAN } else { m })
        .collect();
    let fit = |c: &Candidate, starts: Vec<Vec<f64>>| fitter.fit(c, starts, None);
    let base_starts: Vec<Vec<f64>> = [0.2, 0.5, 0.8].iter().flat_map(|&a| [0.3, 0.6].map(|b| vec![a, b])).collect();
    let (base_lm, base_sw) = fit(&Candidate::of(&[]), base_starts).context("base model cannot be fitted")?;
    let mut fits: Vec<(Candidate, crate::audit::LmResult, Switches)> = METRO_EFFECTS
        .par_iter()
        .filter_map(|&e| {
            let starts = metro_starts(e).into_iter().map(|s| vec![base_lm.x[0], base_lm.x[1], s]).collect();
            let c = Candidate::of(&[e]);
            fit(&c, starts).map(|(lm, sw)| (c, lm, sw))
        })
        .collect();
    fits.sort_by(|a, b| a.1.rss.total_cmp(&b.1.rss));
    let top: Vec<(Mechanism, f64)> = fits.iter().take(3).map(|(c, lm, _)| (c.effects[0], lm.x[2])).collect();
    let mut pair_fits = Vec::new();
    for i in 0..top.len() {
        for j in i + 1..top.len() {
            let c = Candidate::of(&[top[i].0, top[j].0]);
            let starts = vec![vec![base_lm.x[0], base_lm.x[1], top[i].1, top[j].1]];
            if let Some((lm, sw)) = fit(&c, starts) {
                pair_fits.push((c, lm, sw));
            }
        }
    }
    fits.extend(pair_fits);
    // The wall as a second thermal node, on every fitted candidate with heat transfer (its τ
    // couples gas and wall), from that candidate's optimum.
    let wall_fits: Vec<(Candidate, crate::audit::LmResult, Switches)> = fits
        .par_iter()
        .filter(|(c, _, _)| c.effects.contains(&Mechanism::HeatTransfer))
        .filter_map(|(c, lm, _)| {
            let wc = Candidate { effects: c.effects.clone(), wall: true };
            // Gas and wall share the heat: with a wall that stores it, the gas's own τ comes out
            // longer than the one-node fit's, so starts also stretch it (two optima otherwise
            // trap the fit: a small fast wall near the one-node τ, a large slow one beyond it).
            let ht = c.effects.iter().position(|&e| e == Mechanism::HeatTransfer).map(|i| 2 + i);
            let starts = [(0.1, 300.0, 1.0), (0.5, 3000.0, 1.0), (0.5, 3000.0, 2.5), (1.0, 10_000.0, 2.5)]
                .iter()
                .map(|&(eps, tau_w, stretch)| {
                    let mut x = lm.x.clone();
                    if let Some(i) = ht {
                        let tau = metro_value(Mechanism::HeatTransfer, x[i]) * stretch;
                        x[i] = scope(Mechanism::HeatTransfer).coordinate_of(tau);
                    }
                    x.extend([log_coordinate(eps, WALL_CAPACITY_SEARCH), log_coordinate(tau_w, WALL_COOLING_SEARCH_S)]);
                    x
                })
                .collect();
            fit(&wc, starts).map(|(lm, sw)| (wc, lm, sw))
        })
        .collect();
    fits.extend(wall_fits);
    let n = measured.len();
    let best = fits.iter().map(|f| &f.1).chain([&base_lm]).min_by(|a, b| a.rss.total_cmp(&b.rss)).cloned();
    let best = best.context("no fit")?;
    // The test counts effective samples from the noise's own correlation (second differences of
    // the record), the uncertainty is inflated by the best model's leftover correlation, as in
    // the brake audit.
    let rho_noise = crate::audit::noise_lag1(&measured);
    let n_eff = (n as f64 * (1.0 - rho_noise) / (1.0 + rho_noise)).max(5.0);
    let rho = crate::audit::acf(&best.residual, 1).first().copied().unwrap_or(0.0).clamp(0.0, 0.995);
    let inflation = ((1.0 + rho) / (1.0 - rho)).max(n as f64 / n_eff);
    let dbic = |r0: f64, r1: f64, dk: usize| n_eff * (r0 / r1.max(1e-300)).ln() - dk as f64 * n_eff.ln();
    let mk = |c: &Candidate, lm: &crate::audit::LmResult, sw: &Switches| {
        let on = c.on(&lm.x);
        let params = c.params(&lm.x);
        let curve = simulate_around(rows, &params, sw, &events).unwrap_or_default();
        let validated = if validate { fitter.held_out(c, &lm.x, &curve) } else { None };
        // Jackknife 1-σ over the held-out folds: sqrt((k − 1)/k · Σ (θ_f − θ̄)²), for each magnitude
        // read out of the folds' optima by `value`.
        let jackknife = |value: &dyn Fn(&[f64]) -> f64| -> f64 {
            let Some((_, optima)) = &validated else { return 0.0 };
            let v: Vec<f64> = optima.iter().map(|x| value(x)).collect();
            let k = v.len() as f64;
            if k < 2.0 {
                return 0.0;
            }
            let mean = v.iter().sum::<f64>() / k;
            ((k - 1.0) / k * v.iter().map(|x| (x - mean).powi(2)).sum::<f64>()).sqrt()
        };
        // 1-σ from s² (JᵀJ)⁻¹ with s² = RSS/(n − k) inflated for the residual correlation, and
        // never below the jackknife's: the cycles differ more than the noise, and the
        // covariance alone claimed ten times too small an error for the wall node.
        let dims = lm.x.len();
        let s2 = lm.rss / n.saturating_sub(dims).max(1) as f64 * inflation;
        let diag = inverse_diag(&lm.jtj, dims);
        let eff: Vec<(Mechanism, f64, f64)> = on
            .iter()
            .enumerate()
            .map(|(i, &(e, v))| {
                let gn = (diag[2 + i] * s2).max(0.0).sqrt() * metro_slope(e, lm.x[2 + i]).abs();
                let jk = jackknife(&|x| metro_value(e, x.get(2 + i).copied().unwrap_or(0.0)));
                (e, v, gn.max(jk))
            })
            .collect();
        // The wall's coordinates are logarithmic: d value / d u = value · ln(hi/lo).
        let wall = c.wall.then(|| {
            let k = c.wall_index();
            let sd = |i: usize, v: f64, (lo, hi): (f64, f64)| {
                (diag.get(i).copied().unwrap_or(f64::INFINITY) * s2).max(0.0).sqrt() * v * (hi / lo).ln()
            };
            let w = params.wall;
            let jk_eps = jackknife(&|x| wall_at(x.get(k..).unwrap_or(&[])).capacity_ratio);
            let jk_tau = jackknife(&|x| wall_at(x.get(k..).unwrap_or(&[])).cooling_s);
            (
                w,
                [
                    sd(k, w.capacity_ratio, WALL_CAPACITY_SEARCH).max(jk_eps),
                    sd(k + 1, w.cooling_s, WALL_COOLING_SEARCH_S).max(jk_tau),
                ],
            )
        });
        MetroFit {
            name: c.name(),
            nmse_pct: nmse_outside(&observed, &curve),
            effects: eff,
            wall,
            rss: lm.rss,
            delta_bic: dbic(base_lm.rss, lm.rss, lm.x.len() - 2),
            held_out: validated.map(|(h, _)| h),
            params,
            curve,
            switches: sw.clone(),
        }
    };
    let base = mk(&Candidate::of(&[]), &base_lm, &base_sw);
    let mut ranking: Vec<MetroFit> = fits.par_iter().map(|(e, lm, sw)| mk(e, lm, sw)).collect();
    ranking.sort_by(|a, b| b.delta_bic.total_cmp(&a.delta_bic));
    let mut chosen = base.clone();
    let mut wall_note = None;
    if let Some(s) = ranking.iter().find(|c| c.effects.len() == 1 && c.wall.is_none()) {
        if s.delta_bic > BIC_THRESHOLD && base.rss / s.rss >= MIN_RSS_RATIO {
            chosen = s.clone();
            let pair = ranking
                .iter()
                .filter(|c| c.effects.len() == 2 && c.wall.is_none() && c.effects.iter().any(|e| e.0 == s.effects[0].0))
                .max_by(|a, b| a.delta_bic.total_cmp(&b.delta_bic));
            if let Some(p) = pair {
                if dbic(s.rss, p.rss, 1) > BIC_THRESHOLD && s.rss / p.rss >= MIN_RSS_RATIO {
                    chosen = p.clone();
                }
            }
            // The wall node on the chosen mechanisms, by the same two tests for its two
            // parameters.
            let same = |c: &MetroFit| {
                c.wall.is_some()
                    && c.effects.len() == chosen.effects.len()
                    && c.effects.iter().zip(&chosen.effects).all(|(a, b)| a.0 == b.0)
            };
            if let Some(w) = ranking.iter().find(|c| same(c)) {
                if dbic(chosen.rss, w.rss, 2) > BIC_THRESHOLD && chosen.rss / w.rss >= MIN_RSS_RATIO {
                    match wall_not_credible(w, &chosen) {
                        None => chosen = w.clone(),
                        Some(why) => wall_note = Some(format!("{} fits better but is not named: {why}", w.name)),
                    }
                }
            }
        }
    }
    // The same honesty as the brake audit: a cause must at least halve the residual when it
    // does not reach the noise floor, and no cause is `none` only at the floor.
    let to_noise = |rss: f64| (rss / n.max(1) as f64).sqrt();
    let mut note = wall_note;
    let (rb, rc) = (to_noise(base.rss), to_noise(chosen.rss));
    if !chosen.effects.is_empty() && crate::audit::explains_too_little(rb, rc) {
        let little = format!("{} leaves {rc:.1}× of the base's {rb:.1}× the noise: too little explained", chosen.name);
        note = Some(match note {
            Some(wall) => format!("{wall}; {little}"),
            None => little,
        });
        chosen = base.clone();
    }
    let residual_to_noise = (rb, to_noise(chosen.rss));
    let cause =
        crate::audit::cause_name((!chosen.effects.is_empty()).then_some(chosen.name.as_str()), rb <= NOISE_FLOOR_RATIO);
    // The chosen model against the cycle-to-cycle variation; its spread also sets the record's floor.
    let floor = cycle_floor(rows, &observed, &chosen.curve);
    Ok(MetroOutcome {
        cause,
        residual_to_noise,
        note,
        base_phase_rms: phase_rms(rows, &observed, &base.curve),
        chosen_phase_rms: phase_rms(rows, &observed, &chosen.curve),
        missing: aligned_rate(rows, &observed, &chosen.curve),
        cycle_floor: floor,
        record_floor: floor.and_then(|f| record_floor(rows, &events, f.spread_bar)),
        consumption_change: consumption_change(rows, &events),
        events,
        switch_s: chosen.switches.seconds(rows),
        switch_timing_floor_bar: {
            let mut dt: Vec<f64> = rows.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
            dt.sort_by(f64::total_cmp);
            fill_rate_bar_per_s(&chosen.params) * dt.get(dt.len() / 2).copied().unwrap_or(0.0) / 12f64.sqrt()
        },
        base,
        chosen,
        ranking,
        sigma,
    })
}

impl MetroOutcome {
    /// Text summary.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "MetroPT-3 audit: noise σ {:.4} bar (estimated)", self.sigma);
        let b = &self.base.params;
        let _ = writeln!(
            s,
            "base (adiabatic core reservoir, V = {} m³ assumed): compressor {:.2} g/s ({:.4} bar/s), outlet \
             {:.3} mm (decay {:.2e} 1/s), NMSE {:.3} %",
            b.volume_m3,
            b.compressor_g_per_s,
            fill_rate_bar_per_s(b),
            b.outlet.mm(),
            vent_rate_per_s(b),
            self.base.nmse_pct
        );
        for (name, rms, bias) in &self.base_phase_rms {
            let _ = writeln!(s, "  {name:<28} RMS {rms:.4} bar, bias (measured − model) {bias:+.4} bar");
        }
        for e in &self.events {
            let _ = writeln!(
                s,
                "{} ({:.0} σ of the cycle-to-cycle differences; its {} rows are left out of every fit and figure)",
                e.describe(),
                e.sigmas,
                e.rows.1 + 1 - e.rows.0
            );
        }
        for c in &self.ranking {
            s.push_str(&ranking_line(&c.name, c.delta_bic, self.base.rss / c.rss, c.nmse_pct, &c.json_effects()));
        }
        let _ = writeln!(
            s,
            "cause: {}{}  NMSE {:.3} % → {:.3} % (ratio {:.1})",
            self.cause,
            self.chosen
                .json_effects()
                .iter()
                .map(|(name, unit, v, u)| format!("  {name} = {v:.3} ± {u:.3} {unit}"))
                .collect::<String>(),
            self.base.nmse_pct,
            self.chosen.nmse_pct,
            self.base.nmse_pct / self.chosen.nmse_pct
        );
        for (name, rms, bias) in &self.chosen_phase_rms {
            let _ = writeln!(s, "  chosen: {name:<20} RMS {rms:.4} bar, bias (measured − model) {bias:+.4} bar");
        }
        if let Some(h) = self.base.held_out {
            let _ = writeln!(
                s,
                "held out (each of the {} complete cycles predicted by a fit to the rest of the record, in {} folds, {} \
                 rows; NMSE held out vs fitted to all):",
                h.cycles, h.folds, h.rows
            );
            if let Some(f) = self.record_floor {
                let _ = writeln!(
                    s,
                    "  floor of this record          {:.3} %   (what no model driven by COMP can beat: {:.4} bar of \
                     scatter while loaded, {:.4} bar between cycles in the decays)",
                    f.nmse_pct, f.loaded_jitter_bar, f.decay_spread_bar
                );
            }
            for f in std::iter::once(&self.base).chain(&self.ranking) {
                if let Some(h) = f.held_out {
                    let _ = writeln!(
                        s,
                        "  {:<36} {:.3} % vs {:.3} %{}",
                        f.name,
                        h.nmse_pct,
                        h.in_sample_nmse_pct,
                        if f.name == self.chosen.name { "  (chosen)" } else { "" }
                    );
                }
            }
        }
        let _ = writeln!(
            s,
            "  (COMP gives each switch only to its sampling interval, {:.4} bar RMS in a loaded phase if taken at the \
             midpoint; the fits estimate each switch inside its interval, at {} s)",
            self.switch_timing_floor_bar,
            self.switch_s.iter().map(|t| format!("{t:.1}")).collect::<Vec<_>>().join(", ")
        );
        if let Some(f) = &self.cycle_floor {
            let _ = writeln!(
                s,
                "the {} complete cycles as replicates ({} times each): residual spread between cycles {:.4} bar \
                 ({:.1}× the transducer noise), mean over the cycles {:.4} bar RMS, beyond the 99 % bound of its spread \
                 at {:.0} % of the times (p ≤ {:.3}): {}",
                f.cycles,
                f.points,
                f.spread_bar,
                f.spread_bar / self.sigma,
                f.systematic_bar,
                100.0 * f.share_beyond,
                f.p_at_most(),
                if f.systematic() { "systematic" } else { "within the cycle-to-cycle variation" }
            );
        }
        if let Some(c) = &self.consumption_change {
            let _ = writeln!(
                s,
                "decay rate of each complete cycle {:.0}–{:.0} s after unloading (bar/min): {}",
                c.window_s.0,
                c.window_s.1,
                c.cycle_rates.iter().map(|r| format!("{r:+.4}")).collect::<Vec<_>>().join(", ")
            );
            let _ = writeln!(s, "  {}", c.describe());
        }
        let _ = writeln!(s, "what the chosen model misses, by time since the compressor switched (bar/min, ± 1 SE):");
        for a in self.missing.iter().filter(|a| !a.scan || a.significant()) {
            let _ = writeln!(
                s,
                "  {:<8} {:>4.0}–{:<4.0} s  {:+.4} ± {:.4}  ({} intervals){}",
                a.phase,
                a.from_s,
                a.from_s + a.width_s,
                a.mean_bar_per_min,
                a.se_bar_per_min,
                a.count,
                if a.significant() { "  significant" } else { "" }
            );
        }
        let _ = writeln!(s, "verdict: {}", self.verdict_text());
        s
    }

    /// The verdict in one sentence with its evidence (the brake audit's wording).
    pub fn verdict_text(&self) -> String {
        let (b, c) = self.residual_to_noise;
        let mut text = match self.cause.as_str() {
            "none" => format!("none: the base model is consistent with the noise ({b:.1}× the noise σ)"),
            "unexplained" => format!(
                "unexplained: the base model's residual is {b:.1}× the noise (floor {NOISE_FLOOR_RATIO}) and no \
                 mechanism explains it"
            ),
            name if c <= NOISE_FLOOR_RATIO => format!("{name}: explains the discrepancy ({b:.1}× → {c:.1}× the noise)"),
            name => format!(
                "{name} explains part of the discrepancy ({b:.1}× → {c:.1}× the noise, floor {NOISE_FLOOR_RATIO}): \
                 something else is missing too"
            ),
        };
        if let Some(n) = &self.note {
            text.push_str(&format!("; {n}"));
        }
        for e in &self.events {
            text.push_str(&format!("; the record also holds {}, not a mechanism (one cycle only)", e.describe()));
        }
        if let Some(c) = &self.consumption_change {
            text.push_str(&format!(
                "; the record also holds {}, which no model with constant parameters follows{}",
                c.describe(),
                if self.chosen.effects.is_empty() { "" } else { " (the named magnitudes are fitted across it)" }
            ));
        }
        if c > NOISE_FLOOR_RATIO {
            if let Some(f) = &self.cycle_floor {
                text.push_str(&format!(
                    "; the {} cycles differ from each other by {:.3} bar RMS ({:.0}× the transducer noise: air \
                     consumption the record does not hold, which no model driven by COMP alone can follow), {}",
                    f.cycles,
                    f.spread_bar,
                    f.spread_bar / self.sigma,
                    if f.systematic() {
                        format!(
                            "and beyond that variation the model still errs the same way in every cycle (at {:.0} % \
                             of the times, p ≤ {:.3})",
                            100.0 * f.share_beyond,
                            f.p_at_most()
                        )
                    } else {
                        "and the model's error is within that variation (the rest varies from cycle to cycle)"
                            .to_owned()
                    }
                ));
            }
            if let (Some(h), Some(f)) = (self.chosen.held_out, self.record_floor) {
                text.push_str(&format!(
                    "; on cycles it was not fitted to it reaches NMSE {:.3} % ({:.1}× this record's floor of {:.3} %: \
                     the loaded phases scatter by {:.3} bar from row to row and the decays by {:.3} bar from cycle to \
                     cycle, which no model driven by COMP can follow)",
                    h.nmse_pct,
                    h.nmse_pct / f.nmse_pct,
                    f.nmse_pct,
                    f.loaded_jitter_bar,
                    f.decay_spread_bar
                ));
            }
            text.push_str(&format!("; what is missing: {}", describe_aligned(&self.missing)));
        }
        text
    }

    /// JSON verdict: the brake audit's format ([`crate::audit::AuditOutcome::to_json`]) without
    /// the per-trace NMSEs (one record).
    pub fn to_json(&self) -> serde_json::Value {
        let mut doc = verdict_json(&VerdictJson {
            cause: &self.cause,
            causes: self.chosen.json_effects(),
            nmse_pct: (self.base.nmse_pct, self.chosen.nmse_pct),
            nmse_per_trace_pct: None,
            noise_sigma_bar: self.sigma,
            ranking: RankingJson::rows(&self.ranking, self.base.rss),
        });
        doc["residual_to_noise"] = serde_json::json!({
            "base": self.residual_to_noise.0,
            "chosen": self.residual_to_noise.1,
            "noise_floor": NOISE_FLOOR_RATIO,
        });
        doc["explains_all"] = serde_json::Value::Bool(self.residual_to_noise.1 <= NOISE_FLOOR_RATIO);
        doc["verdict"] = serde_json::json!(self.verdict_text());
        doc["switch_timing_floor_bar"] = serde_json::json!(self.switch_timing_floor_bar);
        doc["one_off_events"] = serde_json::json!(self
            .events
            .iter()
            .map(|e| serde_json::json!({
                "cycle": e.cycle, "rows": [e.rows.0, e.rows.1], "t_s": [e.t_s.0, e.t_s.1],
                "since_unload_s": e.since_unload_s, "pressure_bar": [e.pressure_bar.0, e.pressure_bar.1],
                "dip_bar": e.dip_bar, "net_bar": e.net_bar, "recovered": e.recovered,
                "air_g": OneOffEvent::air_g(e.dip_bar.abs()),
                "sigmas": e.sigmas, "text": e.describe(),
            }))
            .collect::<Vec<_>>());
        doc["record_floor"] = self.record_floor.map_or(serde_json::Value::Null, |f| {
            serde_json::json!({
                "nmse_pct": f.nmse_pct, "loaded_jitter_bar": f.loaded_jitter_bar,
                "decay_spread_bar": f.decay_spread_bar,
            })
        });
        doc["held_out"] = serde_json::json!(std::iter::once(&self.base)
            .chain(&self.ranking)
            .filter_map(|f| f.held_out.map(|h| serde_json::json!({
                "model": f.name, "cycles": h.cycles, "folds": h.folds, "rows": h.rows,
                "nmse_pct": h.nmse_pct, "in_sample_nmse_pct": h.in_sample_nmse_pct,
            })))
            .collect::<Vec<_>>());
        doc["switch_s"] = serde_json::json!(self.switch_s);
        doc["consumption_change"] = self.consumption_change.as_ref().map_or(serde_json::Value::Null, |c| {
            serde_json::json!({
                "shape": match c.shape { ChangeShape::Step => "step", ChangeShape::Drift => "drift" },
                "first_cycle_after": c.first_cycle_after, "between_s": [c.between_s.0, c.between_s.1],
                "rate_bar_per_min": [c.rate_bar_per_min.0, c.rate_bar_per_min.1],
                "cycle_rates_bar_per_min": c.cycle_rates, "window_s": [c.window_s.0, c.window_s.1],
                "p_value": c.p_value, "text": c.describe(),
            })
        });
        doc["cycle_floor"] = self.cycle_floor.map_or(serde_json::Value::Null, |f| {
            serde_json::json!({
                "cycles": f.cycles, "points": f.points, "spread_bar": f.spread_bar,
                "systematic_bar": f.systematic_bar, "share_beyond_99": f.share_beyond,
                "p_at_most": f.p_at_most(), "systematic": f.systematic(),
            })
        });
        doc["unmodelled_rate"] = serde_json::json!(self
            .missing
            .iter()
            .filter(|a| !a.scan || a.significant())
            .map(|a| serde_json::json!({
                "phase": a.phase, "from_s": a.from_s, "width_s": a.width_s,
                "mean_bar_per_min": a.mean_bar_per_min, "se_bar_per_min": a.se_bar_per_min,
                "count": a.count, "significant": a.significant(), "scan": a.scan,
                "pressure_bar": [a.pressure_bar.0, a.pressure_bar.1],
            }))
            .collect::<Vec<_>>());
        doc
    }
}

impl RankedFit for MetroFit {
    fn ranked(&self) -> (&str, Vec<f64>, f64, f64, f64) {
        (&self.name, self.effects.iter().map(|e| e.1).collect(), self.delta_bic, self.rss, self.nmse_pct)
    }
}

impl MetroFit {
    /// (name, unit, magnitude, σ) of each mechanism.
    fn json_effects(&self) -> Vec<(&'static str, &'static str, f64, f64)> {
        let mut out: Vec<_> = self.effects.iter().map(|(e, v, u)| (e.name(), e.unit(), *v, *u)).collect();
        if let Some((w, [ue, ut])) = self.wall {
            out.push(("wall_capacity_ratio", "ratio", w.capacity_ratio, ue));
            out.push(("wall_cooling", "s", w.cooling_s, ut));
        }
        out
    }
}

fn plot_err<E: std::fmt::Display>(err: E) -> anyhow::Error {
    anyhow::anyhow!("metro plot: {err}")
}

/// Measured TP3 vs the adiabatic base and the extended model over the whole extract (SVG text).
pub fn curves_svg(rows: &[MetroRow], out: &MetroOutcome) -> Result<String> {
    use pbm_report::chart::{draw_lines, line_legend, title_and_legend, OKABE_ITO};
    use plotters::prelude::*;
    let e = plot_err;
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (1100, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let t_end = rows.last().map_or(1.0, |r| r.t_s / 60.0);
        let series = |y: &[f64]| rows.iter().zip(y).map(|(r, &v)| (r.t_s / 60.0, v)).collect::<Vec<_>>();
        let measured: Vec<f64> = rows.iter().map(|r| r.tp3_bar).collect();
        let lines = [
            ("measured", series(&measured), OKABE_ITO[7]),
            ("adiabatic base", series(&out.base.curve), OKABE_ITO[1]),
            ("extended", series(&out.chosen.curve), OKABE_ITO[0]),
        ];
        let title = format!(
            "MetroPT-3 reservoir pressure: measured, adiabatic, with {}",
            out.cause.replace('_', " ").replace('+', " + ")
        );
        let plot_area = title_and_legend(&root, &title, &line_legend(&lines))?;
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..t_end, 7.8..10.4)
            .map_err(e)?;
        chart.configure_mesh().x_desc("t, min").y_desc("TP3, bar").draw().map_err(e)?;
        draw_lines(&mut chart, &lines)?;
        root.present().map_err(e)?;
    }
    Ok(buf)
}

/// Residual (measured − model) of the base and the extended model against time (SVG text).
pub fn residual_svg(rows: &[MetroRow], out: &MetroOutcome) -> Result<String> {
    use pbm_report::chart::{draw_lines, line_legend, title_and_legend, OKABE_ITO};
    use plotters::prelude::*;
    let e = plot_err;
    let measured: Vec<f64> = rows.iter().map(|r| r.tp3_bar).collect();
    let rb: Vec<f64> = measured.iter().zip(&out.base.curve).map(|(m, b)| m - b).collect();
    let re: Vec<f64> = measured.iter().zip(&out.chosen.curve).map(|(m, b)| m - b).collect();
    let lim = rb.iter().chain(&re).fold(0.05f64, |a, v| a.max(v.abs())) * 1.1;
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (1100, 400)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let t_end = rows.last().map_or(1.0, |r| r.t_s / 60.0);
        let series = |y: &[f64]| rows.iter().zip(y).map(|(r, &v)| (r.t_s / 60.0, v)).collect::<Vec<_>>();
        let lines = [("adiabatic base", series(&rb), OKABE_ITO[1]), ("extended", series(&re), OKABE_ITO[0])];
        let plot_area = title_and_legend(&root, "MetroPT-3 TP3 residual, measured − model", &line_legend(&lines))?;
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_end, -lim..lim)
            .map_err(e)?;
        chart.configure_mesh().x_desc("t, min").y_desc("residual, bar").draw().map_err(e)?;
        draw_lines(&mut chart, &lines)?;
        root.present().map_err(e)?;
    }
    Ok(buf)
}

/// Reads the extract and runs the metro audit (for the demo and other tools).
pub fn audit_metro_file(path: &Path) -> Result<(Vec<MetroRow>, MetroOutcome)> {
    let rows = read_metro(path)?;
    let out = audit_metro(&rows)?;
    Ok((rows, out))
}

/// Writes the JSON verdict and the plots (see [`MetroOptions::plot`]) that were asked for.
pub fn write_metro_outputs(
    rows: &[MetroRow],
    out: &MetroOutcome,
    json: Option<&Path>,
    plot: Option<&Path>,
) -> Result<()> {
    if let Some(p) = json {
        pbm_io::table::write_json(p, &out.to_json())?;
    }
    if let Some(p) = plot {
        let write =
            |p: &Path, svg: String| std::fs::write(p, svg).with_context(|| format!("cannot write {}", p.display()));
        if p.extension().is_some_and(|x| x.eq_ignore_ascii_case("svg")) {
            write(p, curves_svg(rows, out)?)?;
        } else {
            std::fs::create_dir_all(p).with_context(|| format!("cannot create {}", p.display()))?;
            write(&p.join("metro_curves.svg"), curves_svg(rows, out)?)?;
            write(&p.join("metro_residual.svg"), residual_svg(rows, out)?)?;
        }
    }
    Ok(())
}

/// The audit of a MetroPT-3 record in `path` (or the synthetic sweep of `a`): the summary on
/// stdout, the outputs of `a` written.
pub fn run(path: &Path, a: &MetroOptions) -> Result<()> {
    if let Some(cases) = a.synthetic_sweep {
        print!("{}", sweep_summary(&synthetic_sweep(cases, a.seed)?));
        return Ok(());
    }
    let (rows, out) = audit_metro_file(path)?;
    print!("{}", out.summary());
    write_metro_outputs(&rows, &out, a.json.as_deref(), a.plot.as_deref())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_candidates_are_the_mechanisms_the_reservoir_has() {
        let mut with_scope: Vec<Mechanism> =
            Mechanism::ALL.into_iter().filter(|m| m.descriptor().reservoir.is_some()).collect();
        let mut candidates = METRO_EFFECTS.to_vec();
        with_scope.sort();
        candidates.sort();
        assert_eq!(candidates, with_scope);
    }

    /// The cycle floor tells consumption that varies from cycle to cycle (which no model
    /// driven by COMP alone can follow) from a mechanism the model misses: on a record from the
    /// `f64` reference with heat transfer and a consumption that differs by up to ± 8 % between
    /// cycles, the audit's model is far above the transducer noise but at the cycle floor, and
    /// the base model (no heat transfer) is far above both.
    #[test]
    fn the_cycle_floor_separates_varying_consumption_from_a_missing_mechanism() {
        let truth = metro_params(&SYNTHETIC_BASE_U, &[(Mechanism::HeatTransfer, 20.0)]);
        for seed in [7, 8] {
            let rows = synthetic_rows_with(&truth, SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, seed, 0.08);
            let out = audit_metro_with(&rows, false).expect("audit runs");
            eprint!("{}", out.summary());
            assert!(out.cause.split('+').any(|c| c == "heat_transfer"), "{}", out.cause);
            assert!(!out.cause.contains(WALL_HEAT), "{}", out.cause);
            assert!(out.residual_to_noise.1 > 3.0 * NOISE_FLOOR_RATIO, "{:?}", out.residual_to_noise);
            let floor = out.cycle_floor.expect("complete cycles");
            assert!(floor.cycles >= 3 && !floor.systematic(), "{floor:?}");
            let measured: Vec<f64> = rows.iter().map(|r| r.tp3_bar).collect();
            let base = cycle_floor(&rows, &measured, &out.base.curve).expect("complete cycles");
            assert!(base.systematic(), "{base:?}");
            assert!(out.verdict_text().contains("within that variation"), "{}", out.verdict_text());
        }
    }

    /// Issue 17: a lasting change of consumption mid-record is reported with when it began, and
    /// consumption that only varies from cycle to cycle (± 8 %, independently) is not one. The
    /// step is made by joining two records of the `f64` reference at a loading start, the second
    /// with 40 % more outflow.
    #[test]
    fn a_lasting_consumption_change_is_located_and_variation_is_not_one() {
        let truth = metro_params(&SYNTHETIC_BASE_U, &[(Mechanism::HeatTransfer, 30.0)]);
        for seed in 41..49 {
            let rows = synthetic_rows_with(&truth, 3 * SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, seed, 0.08);
            assert!(complete_cycles(&rows).len() >= 10);
            assert_eq!(consumption_change(&rows, &one_off_events(&rows)), None, "seed {seed}");
        }
        let mut leaky = truth;
        leaky.outlet = pbm::Meters(leaky.outlet.0 * 1.4f64.sqrt());
        for seed in [51, 52] {
            let first = synthetic_rows_with(&truth, SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, seed, 0.02);
            let second = synthetic_rows_with(&leaky, SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, seed + 100, 0.02);
            let cut =
                (1..first.len()).rev().find(|&i| first[i].loaded && !first[i - 1].loaded).expect("a loading start");
            let t_join = first[cut].t_s;
            let mut rows = first[..cut].to_vec();
            rows.extend(second.iter().map(|r| MetroRow { t_s: r.t_s + t_join, ..*r }));
            // The cycles on the smaller side of the change are not one-off events.
            let events = one_off_events(&rows);
            assert!(events.is_empty(), "{events:?}");
            let change = consumption_change(&rows, &events).expect("the step is found");
            eprintln!("{} (joined at {t_join} s)", change.describe());
            assert_eq!(change.first_cycle_after, 4, "{change:?}");
            assert_eq!(change.shape, ChangeShape::Step);
            assert!(change.rate_bar_per_min.1 < change.rate_bar_per_min.0, "{change:?}");
            assert!(change.between_s.0 <= t_join && t_join <= change.between_s.1, "{change:?} vs {t_join}");
            let out = audit_metro_with(&rows, false).expect("audit runs");
            assert!(out.verdict_text().contains("a lasting change of the air consumption"), "{}", out.verdict_text());
            assert_eq!(out.to_json()["consumption_change"]["shape"], "step");
        }
    }

    /// Issue 17: a wall that stores heat, hidden in records from the `f64` reference (seeds not
    /// used elsewhere), is found as `wall_heat` on top of heat transfer, with its magnitudes,
    /// and on cycles it was not fitted to the model is within 1.5× the record's floor, where the
    /// one-node model is not. With identical cycles the magnitudes come out within 10 %; with
    /// consumption varying ± 4 % between cycles (≈ the real record's spread) within 35 %, and
    /// low: the fit's constant consumption leans on the slow wall. Records without a wall (the
    /// test above's) never get one.
    #[test]
    fn a_hidden_wall_node_is_found_and_validated_on_held_out_cycles() {
        let mut truth = metro_params(&SYNTHETIC_BASE_U, &[(Mechanism::HeatTransfer, 40.0)]);
        truth.wall = WallNode { capacity_ratio: 0.5, cooling_s: 3000.0 };
        for (seed, spread, tolerance) in [(31, 0.0, 0.1), (31, 0.04, 0.35), (32, 0.04, 0.35)] {
            let rows = synthetic_rows_with(&truth, SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, seed, spread);
            assert!(one_off_events(&rows).is_empty());
            let out = audit_metro(&rows).expect("audit runs");
            eprint!("{}", out.summary());
            assert!(out.cause.starts_with("heat_transfer") && out.cause.ends_with(WALL_HEAT), "{}", out.cause);
            let (w, _) = out.chosen.wall.expect("wall node");
            let tau = out.chosen.effects.iter().find(|e| e.0 == Mechanism::HeatTransfer).expect("heat transfer").1;
            for (got, want) in [(w.capacity_ratio, 0.5), (w.cooling_s, 3000.0), (tau, 40.0)] {
                assert!((got / want - 1.0).abs() < tolerance, "seed {seed}: {got} vs {want}");
            }
            let floor = out.record_floor.expect("floor").nmse_pct;
            let held = out.chosen.held_out.expect("held out").nmse_pct;
            assert!(held < 1.5 * floor, "held out {held} vs floor {floor}");
            let one_node =
                out.ranking.iter().find(|f| f.name == "heat_transfer").and_then(|f| f.held_out).expect("one node");
            assert!(one_node.nmse_pct > 1.5 * held, "{} vs {held}", one_node.nmse_pct);
        }
    }

    /// Without cycle-to-cycle variation the cycle floor is the noise's, and the right model sits
    /// on it.
    #[test]
    fn the_right_model_is_at_the_cycle_floor_of_identical_cycles() {
        let truth = metro_params(&SYNTHETIC_BASE_U, &[(Mechanism::HeatTransfer, 20.0)]);
        let rows = synthetic_rows(&truth, SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, 11);
        let out = audit_metro_with(&rows, false).expect("audit runs");
        let floor = out.cycle_floor.expect("complete cycles");
        assert!(!floor.systematic(), "{floor:?}");
        assert!(out.residual_to_noise.1 <= NOISE_FLOOR_RATIO, "{:?}", out.residual_to_noise);
    }

    /// The rates behind the README's figures (24 seeds never used by the tests above): the right
    /// model within the cycle-to-cycle variation, the base (no heat transfer) caught as
    /// systematic. `cargo test --release -p pbm-lab --lib cycle_floor_rates -- --ignored --nocapture`
    #[test]
    #[ignore = "≈ 2 min on 2 cores; a measurement"]
    fn cycle_floor_rates() {
        let truth = metro_params(&SYNTHETIC_BASE_U, &[(Mechanism::HeatTransfer, 20.0)]);
        let (mut false_systematic, mut caught, mut n) = (0, 0, 0);
        for seed in 100..124u64 {
            let rows = synthetic_rows_with(&truth, SYNTHETIC_ROWS, SYNTHETIC_SIGMA_BAR, seed, 0.08);
            let out = audit_metro_with(&rows, false).expect("audit runs");
            let chosen = out.cycle_floor.expect("complete cycles");
            let measured: Vec<f64> = rows.iter().map(|r| r.tp3_bar).collect();
            let base = cycle_floor(&rows, &measured, &out.base.curve).expect("complete cycles");
            eprintln!(
                "seed {seed}: {} cycles, cause {}, share beyond: chosen {:.2}, base {:.2}",
                chosen.cycles, out.cause, chosen.share_beyond, base.share_beyond
            );
            n += 1;
            false_systematic += usize::from(chosen.systematic());
            caught += usize::from(base.systematic());
        }
        eprintln!("right model called systematic {false_systematic}/{n}; base caught {caught}/{n}");
        assert!(false_systematic <= 1 && caught * 2 >= n, "{false_systematic} {caught} of {n}");
    }
}
