//! The audit in an open world (issue 17, item 6): seeded cases with an effect the audit's
//! library does not hold ([`Foreign`], written here for the test only, in the f64 reference
//! plant through [`crate::reference::ReferenceTwin::retune`] or on the transducer), alone or mixed with a library
//! mechanism, and what the verdict says of it. The audit must be *honest*: never `none` when the
//! base model is wrong (its NMSE at least 3× what the noise alone gives, i.e. a residual of
//! √3 × the noise σ of the mean release or more). Also counted: a library cause named as
//! explaining everything with no look-alike listed (possibly right — the foreign effect may be
//! indistinguishable — but confident), and whether the library mechanism of a mixed case is
//! named. `host-sim audit-sweep --open-world N --seed S` (bench/audit_sweep.md).

use crate::audit::{audit, data_from_traces, AuditData, AuditOptions, AuditOutcome};
use crate::audit_sweep::{draw_truth, RELEASES_PER_CASE};
use crate::generate::{fleet, sense, simulate_plant_with, GENERATE_STEP_S, TRACE_SAMPLES};
use crate::random::unit;
use anyhow::Result;
use pbm::mechanism::Mechanism;
use pbm::sensor::bar_from_adc;
use pbm::units::{BarG, Meters};
use pbm::AdcCounts;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rayon::prelude::*;

/// Seed offset of the open-world cases (apart from the library sweep's).
pub const OPEN_WORLD_SEED_OFFSET: u64 = 3_000_000;

/// An effect outside the audit's library.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Foreign {
    /// The supply regulator hunts: supply + `amp_bar` · sin(2π `freq_hz` t).
    Hunting {
        /// Amplitude, bar.
        amp_bar: f64,
        /// Frequency, Hz.
        freq_hz: f64,
    },
    /// A seal that leaks only above a pressure.
    LeakAbove {
        /// Equivalent orifice, mm.
        d_mm: f64,
        /// Opening pressure, bar g.
        p_open_bar: f64,
    },
    /// The supply is cut off (inflow stops) for a while.
    SupplyCut {
        /// From, s after the release command.
        t0_s: f64,
        /// For, s.
        dur_s: f64,
    },
    /// The release orifice ices up: its diameter shrinks linearly over 60 s.
    OrificeIcing {
        /// Fraction of the diameter lost at 60 s.
        shrink: f64,
    },
    /// A rough patch of the bore: more friction over 10 mm of travel.
    FrictionPatch {
        /// Friction factor on the patch.
        factor: f64,
        /// Where the patch begins, mm of travel.
        x0_mm: f64,
    },
    /// A seal that tears during the release: a leak growing linearly.
    GrowingLeak {
        /// Equivalent orifice at 60 s, mm.
        d_mm: f64,
    },
    /// A transducer bow (non-linearity): + `bow_bar` · 4 (p/10)(1 − p/10).
    TransducerBow {
        /// Largest departure (at 5 bar g), bar.
        bow_bar: f64,
    },
}

impl Foreign {
    /// Every kind, with the name used in the tables.
    pub const KINDS: [&'static str; 7] =
        ["hunting", "leak_above", "supply_cut", "orifice_icing", "friction_patch", "growing_leak", "transducer_bow"];

    /// The kind's name.
    pub fn name(&self) -> &'static str {
        Self::KINDS[match self {
            Self::Hunting { .. } => 0,
            Self::LeakAbove { .. } => 1,
            Self::SupplyCut { .. } => 2,
            Self::OrificeIcing { .. } => 3,
            Self::FrictionPatch { .. } => 4,
            Self::GrowingLeak { .. } => 5,
            Self::TransducerBow { .. } => 6,
        }]
    }

    /// Kind `k` (modulo the kinds) with magnitudes drawn from `u1`, `u2` in [0, 1).
    pub fn draw(k: usize, u1: f64, u2: f64) -> Self {
        let lerp = |lo: f64, hi: f64, u: f64| lo + (hi - lo) * u;
        match k % Self::KINDS.len() {
            0 => Self::Hunting { amp_bar: lerp(0.1, 0.5, u1), freq_hz: lerp(0.1, 0.5, u2) },
            1 => Self::LeakAbove { d_mm: lerp(0.4, 1.0, u1), p_open_bar: lerp(4.5, 6.5, u2) },
            2 => Self::SupplyCut { t0_s: lerp(2.0, 15.0, u1), dur_s: lerp(0.5, 3.0, u2) },
            3 => Self::OrificeIcing { shrink: lerp(0.15, 0.5, u1) },
            4 => Self::FrictionPatch { factor: lerp(2.0, 4.0, u1), x0_mm: lerp(10.0, 40.0, u2) },
            5 => Self::GrowingLeak { d_mm: lerp(0.4, 1.0, u1) },
            _ => Self::TransducerBow { bow_bar: lerp(0.05, 0.2, u1) },
        }
    }

    /// The plant's conditions at time `t_s` with chamber pressure `p_bar_g` and travel `x_mm`,
    /// from the release's own `base`.
    fn condition(&self, base: &pbm::TwinParams, p: &mut pbm::TwinParams, t_s: f64, p_bar_g: f64, x_mm: f64) {
        match *self {
            Self::Hunting { amp_bar, freq_hz } => {
                p.supply = BarG(base.supply.0 + amp_bar * (2.0 * core::f64::consts::PI * freq_hz * t_s).sin());
            }
            Self::LeakAbove { d_mm, p_open_bar } => {
                p.leak = Meters(if p_bar_g > p_open_bar { d_mm * 1e-3 } else { base.leak.0 });
            }
            Self::SupplyCut { t0_s, dur_s } => {
                // A closed line: an orifice of a micrometre lets nothing through.
                p.orifice = Meters(if (t0_s..t0_s + dur_s).contains(&t_s) { 1e-6 } else { base.orifice.0 });
            }
            Self::OrificeIcing { shrink } => p.orifice = Meters(base.orifice.0 * (1.0 - shrink * t_s / 60.0)),
            Self::FrictionPatch { factor, x0_mm } => {
                let f = if (x0_mm..x0_mm + 10.0).contains(&x_mm) { factor } else { 1.0 };
                p.coulomb_n = base.coulomb_n * f;
                p.static_n = base.static_n * f;
            }
            Self::GrowingLeak { d_mm } => p.leak = Meters(d_mm * 1e-3 * t_s / 60.0),
            Self::TransducerBow { .. } => {}
        }
    }

    /// What the transducer makes of gauge pressure `p`.
    fn sensed(&self, p: f64) -> f64 {
        match *self {
            Self::TransducerBow { bow_bar } => p + bow_bar * 4.0 * (p / 10.0) * (1.0 - p / 10.0),
            _ => p,
        }
    }
}

/// A noise-free release of `plant` with `foreign`, bar g at 100 Hz.
pub fn simulate_foreign(plant: &pbm::TwinParams, foreign: Foreign) -> Result<Vec<f64>> {
    let (p, _) = simulate_plant_with(plant, GENERATE_STEP_S, TRACE_SAMPLES, |twin, t| {
        let (now, x) = (twin.pressure_bar_g(), twin.state.x * 1e3);
        twin.retune(|q| foreign.condition(plant, q, t, now, x));
    })?;
    Ok(p.into_iter().map(|v| foreign.sensed(v)).collect())
}

/// An open-world case: the foreign effect, the library mechanism mixed in (if any), the data.
#[derive(Debug, Clone)]
pub struct OpenCase {
    /// Seed of the case.
    pub seed: u64,
    /// The effect outside the library.
    pub foreign: Foreign,
    /// A library mechanism mixed in, with its magnitude.
    pub library: Option<(Mechanism, f64)>,
    /// The data (the nominal brake documented).
    pub data: AuditData,
}

/// The case of `seed`: a foreign kind (cycling through the kinds with the seed), its
/// magnitudes, and half the time a library mechanism at a plausible magnitude.
pub fn draw_open_case(seed: u64) -> Result<OpenCase> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0be2_3a11);
    let foreign = Foreign::draw(seed as usize, unit(&mut rng), unit(&mut rng));
    let library = (unit(&mut rng) < 0.5).then(|| draw_truth(seed, &Mechanism::ALL, 1, None)[0]);
    let mut plant = fleet(seed, 1).into_iter().next().map(|l| l.params).unwrap_or_default();
    if let Some((m, v)) = library {
        plant.ext[m] = v;
    }
    let p = simulate_foreign(&plant, foreign)?;
    let mut noise = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_a0d1);
    let traces = (0..RELEASES_PER_CASE)
        .map(|k| {
            let bar = sense(&p, &mut noise).iter().map(|&c| bar_from_adc(AdcCounts(c)).0).collect();
            (format!("release_{k:02}.csv"), pbm::TwinParams::nominal(), bar)
        })
        .collect();
    Ok(OpenCase { seed, foreign, library, data: data_from_traces(&format!("open-world seed {seed}"), traces)? })
}

/// What the audit said of an open-world case.
#[derive(Debug, Clone)]
pub struct OpenResult {
    /// The effect outside the library.
    pub foreign: Foreign,
    /// The library mechanism mixed in.
    pub library: Option<(Mechanism, f64)>,
    /// The verdict.
    pub outcome: AuditOutcome,
}

/// √3: a base residual this many times the noise σ of the mean release is an NMSE 3× what the
/// noise alone gives.
pub const WRONG_MODEL_RATIO: f64 = 1.732_050_807_568_877_2;

impl OpenResult {
    /// The base model is wrong by the measure (base NMSE ≥ 3× the noise floor's).
    pub fn model_wrong(&self) -> bool {
        self.outcome.residual_to_noise.0 >= WRONG_MODEL_RATIO
    }

    /// Honest: not `none` while the base model is wrong.
    pub fn honest(&self) -> bool {
        !(self.model_wrong() && self.outcome.cause == "none")
    }

    /// A library cause named as explaining everything with nothing listed that fits as well.
    pub fn confident_library(&self) -> bool {
        !matches!(self.outcome.cause.as_str(), "none" | "unexplained")
            && self.outcome.explains_all()
            && self.outcome.alternatives.is_empty()
    }

    /// The mixed-in library mechanism is among the causes named.
    pub fn library_named(&self) -> bool {
        self.library.is_some_and(|(m, _)| self.outcome.cause_effects.iter().any(|e| e.0 == m))
    }

    /// One line for the log.
    pub fn line(&self, seed: u64) -> String {
        let mixed = self.library.map_or(String::new(), |(m, v)| format!(" + {m}={v:.4}"));
        format!(
            "open {seed:>8} {:<15}{:<28} → {:<40} residual {:>6.1}× {}",
            self.foreign.name(),
            mixed,
            self.outcome.cause,
            self.outcome.residual_to_noise.0,
            if self.honest() { "honest" } else { "NONE WHILE WRONG" }
        )
    }
}

/// Audits an open-world case.
pub fn check_open_case(case: &OpenCase) -> Result<OpenResult> {
    Ok(OpenResult {
        foreign: case.foreign,
        library: case.library,
        outcome: audit(&case.data, AuditOptions::default())?,
    })
}

/// Runs `cases` open-world cases from `seed` and prints the table.
pub fn run(cases: u64, seed: u64, verbose: bool) -> Result<Vec<OpenResult>> {
    let start = std::time::Instant::now();
    let results: Vec<OpenResult> = (0..cases)
        .into_par_iter()
        .map(|k| {
            let s = seed + OPEN_WORLD_SEED_OFFSET + k;
            let r = check_open_case(&draw_open_case(s)?)?;
            eprintln!("{}", r.line(s));
            if verbose && !r.honest() {
                eprint!("{}", r.outcome.summary());
            }
            Ok(r)
        })
        .collect::<Result<_>>()?;
    let count = |f: &dyn Fn(&OpenResult) -> bool, kind: Option<&str>| {
        results.iter().filter(|r| kind.is_none_or(|k| r.foreign.name() == k) && f(r)).count()
    };
    println!(
        "open-world sweep: {} cases from seed {} (kinds outside the library, half mixed with a library mechanism), in {:.0} s",
        results.len(),
        seed,
        start.elapsed().as_secs_f64()
    );
    println!(
        "  {:<16} {:>5} {:>6} {:>6} {:>6} {:>11} {:>9} {:>8} {:>9}",
        "kind", "cases", "wrong", "honest", "none", "unexplained", "partial", "full", "lib named"
    );
    for kind in Foreign::KINDS.iter().map(|k| Some(*k)).chain([None]) {
        let n = count(&|_| true, kind);
        let partial =
            |r: &OpenResult| !matches!(r.outcome.cause.as_str(), "none" | "unexplained") && !r.outcome.explains_all();
        let full =
            |r: &OpenResult| !matches!(r.outcome.cause.as_str(), "none" | "unexplained") && r.outcome.explains_all();
        println!(
            "  {:<16} {:>5} {:>6} {:>6} {:>6} {:>11} {:>9} {:>8} {:>9}",
            kind.unwrap_or("all"),
            n,
            count(&|r| r.model_wrong(), kind),
            count(&|r| r.honest(), kind),
            count(&|r| r.outcome.cause == "none", kind),
            count(&|r| r.outcome.cause == "unexplained", kind),
            count(&partial, kind),
            format!("{}/{}", count(&full, kind), count(&|r| r.confident_library(), kind)),
            format!("{}/{}", count(&|r| r.library_named(), kind), count(&|r| r.library.is_some(), kind)),
        );
    }
    println!(
        "honest (never `none` while the base NMSE is ≥ 3× the noise floor's): {}/{} = {:.1} %; \"full\" is named-as-explaining-all / of those with no look-alike listed",
        count(&|r| r.honest(), None),
        results.len(),
        100.0 * count(&|r| r.honest(), None) as f64 / results.len().max(1) as f64
    );
    Ok(results)
}
