//! Hidden-effect cases for the audit: a seeded draw of a locomotive (SPEC §5 spread), a
//! mechanism and a plausible magnitude ([`crate::plant::Effect::plausible`]), noisy releases
//! from the f64 plant (σ = 0.01 bar, 12-bit ADC, as `host-sim generate`), the audit, and the
//! verdict checked: right name, magnitude within 20 %, extended NMSE ≥ 5× lower than base.
//! `host-sim audit-sweep --cases N --seed S` reports the hit rate.

use crate::audit::{audit, data_from_traces, AuditData, AuditOptions, AuditOutcome};
use crate::generate::{fleet, sense, simulate_plant, GENERATE_STEP_S, TRACE_SAMPLES};
use crate::plant::Effect;
use anyhow::Result;
use pbm::sensor::bar_from_adc;
use pbm::AdcCounts;
use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use rayon::prelude::*;

/// Releases per hidden-effect case.
pub const RELEASES_PER_CASE: usize = 6;
/// Magnitude tolerance, relative.
pub const MAGNITUDE_TOLERANCE: f64 = 0.2;
/// Required NMSE ratio base / extended.
pub const MIN_NMSE_GAIN: f64 = 5.0;

fn unit(rng: &mut impl Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A hidden-effect case: the truth and the noisy data.
#[derive(Debug, Clone)]
pub struct Case {
    /// Seed of the case.
    pub seed: u64,
    /// Hidden mechanisms and magnitudes (empty: clean plant).
    pub truth: Vec<(Effect, f64)>,
    /// The data.
    pub data: AuditData,
}

/// Noisy releases of one locomotive (drawn from `seed`) with the given mechanisms.
pub fn synth_data(seed: u64, truth: &[(Effect, f64)], releases: usize) -> Result<AuditData> {
    let loco = fleet(seed, 1).into_iter().next().map(|l| l.params).unwrap_or_default();
    let mut plant = loco;
    for &(e, v) in truth {
        e.set(&mut plant.ext, v);
    }
    let (p, _) = simulate_plant(&plant, GENERATE_STEP_S, TRACE_SAMPLES)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_a0d1);
    let traces = (0..releases)
        .map(|k| {
            let adc = sense(&p, &mut rng);
            let bar: Vec<f64> = adc.iter().map(|&c| bar_from_adc(AdcCounts(c)).0).collect();
            // The documented configuration is the nominal brake at the nominal regulator setting.
            (format!("release_{k:02}.csv"), pbm::TwinParams::nominal(), bar)
        })
        .collect();
    data_from_traces(&format!("synthetic seed {seed}"), traces)
}

/// The case of `seed`: one mechanism drawn uniformly from `pool`, magnitude from its plausible range.
pub fn draw_case(seed: u64, pool: &[Effect]) -> Result<Case> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let i = ((unit(&mut rng) * pool.len() as f64) as usize).min(pool.len().saturating_sub(1));
    let effect = pool.get(i).copied().unwrap_or(Effect::TransportDelay);
    let value = effect.draw(unit(&mut rng), unit(&mut rng));
    let truth = vec![(effect, value)];
    Ok(Case { seed, data: synth_data(seed, &truth, RELEASES_PER_CASE)?, truth })
}

/// How a case came out.
#[derive(Debug, Clone)]
pub struct CaseResult {
    /// The case's truth.
    pub truth: Vec<(Effect, f64)>,
    /// The audit's verdict.
    pub outcome: AuditOutcome,
    /// Right name(s).
    pub name_ok: bool,
    /// Magnitude(s) within tolerance.
    pub magnitude_ok: bool,
    /// NMSE gain ≥ [`MIN_NMSE_GAIN`].
    pub gain_ok: bool,
}

impl CaseResult {
    /// All three criteria.
    pub fn hit(&self) -> bool {
        self.name_ok && self.magnitude_ok && self.gain_ok
    }
}

/// Runs the audit on a case and checks it.
pub fn check_case(case: &Case) -> Result<CaseResult> {
    let outcome = audit(&case.data, AuditOptions::default())?;
    let mut names: Vec<Effect> = outcome.cause_effects.iter().map(|e| e.0).collect();
    names.sort();
    let mut want: Vec<Effect> = case.truth.iter().map(|e| e.0).collect();
    want.sort();
    let name_ok = names == want;
    let magnitude_ok = name_ok
        && case.truth.iter().all(|&(e, v)| {
            outcome.cause_effects.iter().any(|&(f, m, _)| {
                f == e && {
                    // Relative to the deviation from "off" for the ratio/absolute-temperature effects.
                    let (tv, fm) = (v - e.off_value(), m - e.off_value());
                    let rel_ok = (m - v).abs() <= MAGNITUDE_TOLERANCE * v.abs();
                    let dev_ok = (fm - tv).abs() <= MAGNITUDE_TOLERANCE * tv.abs();
                    rel_ok && (dev_ok || matches!(e, Effect::GasTemperature | Effect::SensorGain))
                }
            })
        });
    let gain = outcome.base.nmse_pct / outcome.chosen.nmse_pct;
    let gain_ok = case.truth.is_empty() || gain >= MIN_NMSE_GAIN;
    Ok(CaseResult { truth: case.truth.clone(), outcome, name_ok, magnitude_ok, gain_ok })
}

/// Options of `host-sim audit-sweep`.
#[derive(Debug, Clone, clap::Args)]
pub struct SweepArgs {
    /// Number of hidden-effect cases.
    #[arg(long, default_value_t = 200)]
    pub cases: u64,
    /// First seed (case k uses seed + k).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Mechanisms to draw from (comma-separated; default all).
    #[arg(long, value_delimiter = ',')]
    pub effects: Vec<String>,
    /// Also run this many null cases (clean plant; the audit must say `none`).
    #[arg(long, default_value_t = 0)]
    pub null_cases: u64,
}

/// `host-sim audit-sweep`.
pub fn run(a: &SweepArgs) -> Result<()> {
    let pool: Vec<Effect> = if a.effects.is_empty() {
        Effect::ALL.to_vec()
    } else {
        a.effects.iter().map(|n| crate::plant::effect_by_name(n.trim())).collect::<Result<_>>()?
    };
    let start = std::time::Instant::now();
    let results: Vec<Result<CaseResult>> = (0..a.cases)
        .into_par_iter()
        .map(|k| {
            let case = draw_case(a.seed + k, &pool)?;
            let r = check_case(&case)?;
            let (e, v) = r.truth[0];
            eprintln!(
                "case {:>4} {:<20} {:>9.4} → {:<36} {:>9.4}  NMSE {:.3} → {:.3} %  {}",
                a.seed + k,
                e.name(),
                v,
                r.outcome.cause,
                r.outcome.magnitude(),
                r.outcome.base.nmse_pct,
                r.outcome.chosen.nmse_pct,
                if r.hit() { "hit" } else { "MISS" }
            );
            Ok(r)
        })
        .collect();
    let mut per: Vec<(Effect, usize, usize, usize)> = pool.iter().map(|&e| (e, 0, 0, 0)).collect();
    let (mut hits, mut names, mut total) = (0, 0, 0);
    let mut gains = Vec::new();
    for r in results {
        let r = r?;
        total += 1;
        hits += usize::from(r.hit());
        names += usize::from(r.name_ok);
        gains.push(r.outcome.base.nmse_pct / r.outcome.chosen.nmse_pct);
        if let Some(row) = per.iter_mut().find(|p| p.0 == r.truth[0].0) {
            row.1 += 1;
            row.2 += usize::from(r.name_ok);
            row.3 += usize::from(r.hit());
        }
    }
    let mut nulls = 0;
    for k in 0..a.null_cases {
        let data = synth_data(a.seed + 1_000_000 + k, &[], RELEASES_PER_CASE)?;
        let out = audit(&data, AuditOptions::default())?;
        nulls += usize::from(out.cause == "none");
        eprintln!("null case {k}: {}", out.cause);
    }
    gains.sort_by(f64::total_cmp);
    println!("hidden-effect sweep: {total} cases from seed {} in {:.0} s", a.seed, start.elapsed().as_secs_f64());
    println!(
        "hit rate (name, magnitude ±20 %, NMSE gain ≥ 5×): {hits}/{total} = {:.1} %; right name {names}/{total} = {:.1} %",
        100.0 * hits as f64 / total.max(1) as f64,
        100.0 * names as f64 / total.max(1) as f64
    );
    if !gains.is_empty() {
        println!("median NMSE gain {:.1}×", gains[gains.len() / 2]);
    }
    for (e, n, ok, hit) in per {
        println!("  {:<20} {hit:>3}/{n:<3} hits, {ok:>3} right names", e.name());
    }
    if a.null_cases > 0 {
        println!("null cases answered `none`: {nulls}/{}", a.null_cases);
    }
    Ok(())
}
