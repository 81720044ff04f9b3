//! The early warning measured on the slow-degradation scenario: lead time before the
//! classifier's first fault call, and false warnings on healthy locomotives.
//!
//! The releases are simulated and replayed in memory (no files), through the same core
//! pipeline as `fleet ingest` ([`pbm_lab::replay::replay_samples`]).

use crate::record::{verdict_label, ReleaseRecord, Source};
use crate::scenario::{plan, simulate, DegradationOptions, DegradedRelease, Wear};
use crate::trend::{warnings, Parameter, WarningRule};
use anyhow::Result;
use pbm::can::PowerUp;
use pbm::report::Verdict;
use pbm::FaultClass;
use pbm_lab::replay::{replay_samples, ReplayError};
use rayon::prelude::*;

/// The monitor's view of one simulated release.
#[derive(Debug, Clone, PartialEq)]
pub struct Observed {
    /// The release as drawn.
    pub truth: DegradedRelease,
    /// What the monitor made of it.
    pub record: ReleaseRecord,
}

/// Replays ADC samples (100 Hz, from the release command) through a fresh core pipeline;
/// returns the closed verdict and the estimator's last estimates (orifice, leak, supply).
pub fn replay_adc(adc: &[u16]) -> Result<(Option<Verdict>, [Option<f64>; 3])> {
    let mut last = None;
    let samples = adc.iter().enumerate().map(|(i, &a)| Ok((i as f64 * pbm::twin::SAMPLE_PERIOD_S, a)));
    let r = replay_samples(samples, false, PowerUp::default(), |s| {
        last = Some(s.step.estimates);
        Ok(())
    });
    let r = match r {
        Ok(r) => r,
        Err(ReplayError::Input(e)) => return Err(e.into()),
        Err(ReplayError::Output(e)) => return Err(e),
    };
    let f = |v: Option<f32>| v.map(f64::from).filter(|x| x.is_finite());
    let est = last.map_or([None; 3], |e| [f(e.orifice_mm), f(e.leak_mm), f(e.supply_bar_g)]);
    Ok((r.diagnosis.map(|d| d.verdict), est))
}

/// Simulates and replays every release of a scenario (in parallel; the result does not depend
/// on the thread count).
pub fn observe(o: &DegradationOptions) -> Result<Vec<Observed>> {
    let releases = plan(o)?;
    releases
        .into_par_iter()
        .map(|truth| {
            let adc = simulate(o.seed, &truth)?;
            let (verdict, [orifice_mm, leak_mm, supply_bar_g]) = replay_adc(&adc)?;
            let record = ReleaseRecord {
                locomotive: truth.locomotive.clone(),
                source: Source::Trace,
                origin: format!("scenario seed {}", o.seed),
                release_key: truth.release.to_string(),
                release_no: truth.release as i64,
                time_s: None,
                verdict,
                orifice_mm,
                leak_mm,
                supply_bar_g,
                label: Some(truth.label.label().to_owned()),
                content_hash: None,
                numbered: true,
                detail: Default::default(),
            };
            Ok(Observed { truth, record })
        })
        .collect()
}

/// The parameter that a wear drives toward a fault.
pub fn parameter_of(w: Wear) -> Option<Parameter> {
    match w {
        Wear::Healthy | Wear::Sensor => None,
        Wear::Leak => Some(Parameter::Leak),
        Wear::Clog => Some(Parameter::Orifice),
    }
}

/// `true` when a verdict names a fault of the family that `p` drifting causes.
fn calls_fault(verdict: &str, p: Parameter) -> bool {
    let leak = [FaultClass::AirLeak, FaultClass::LeakAndBlock];
    let block = [FaultClass::OrificeBlock, FaultClass::LeakAndBlock];
    let family: &[FaultClass] = match p {
        Parameter::Leak => &leak,
        Parameter::Orifice => &block,
        Parameter::Supply => &[FaultClass::LowSupply],
    };
    family.iter().any(|c| c.label() == verdict)
}

/// The figures of one degrading locomotive.
#[derive(Debug, Clone, PartialEq)]
pub struct LeadTime {
    /// Locomotive.
    pub locomotive: String,
    /// The drifting parameter.
    pub parameter: Parameter,
    /// First release whose true parameter is past the SPEC §4 fault edge.
    pub truth_fault_release: Option<usize>,
    /// First release the classifier called a fault of the family (`None`: never).
    pub first_call: Option<usize>,
    /// First release the warning fired on the parameter (`None`: never).
    pub first_warning: Option<usize>,
}

impl LeadTime {
    /// Releases from the warning to the classifier's first call (positive: the warning came
    /// first). A warning with no call at all counts from the end of the record.
    pub fn lead(&self, releases: usize) -> Option<i64> {
        let w = self.first_warning? as i64;
        Some(self.first_call.map_or(releases as i64, |c| c as i64) - w)
    }
}

/// The measurement over one scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// Per degrading locomotive.
    pub lead_times: Vec<LeadTime>,
    /// Warnings on healthy locomotives (each parameter's first alarm counts once).
    pub false_warnings: usize,
    /// Of those, per parameter ([`Parameter::ALL`] order).
    pub false_by_parameter: [usize; 3],
    /// Releases of healthy locomotives watched (after the baseline).
    pub healthy_releases: usize,
    /// Releases per locomotive.
    pub releases: usize,
}

impl Measurement {
    /// False warnings per 1000 healthy releases.
    pub fn false_per_1000(&self) -> f64 {
        if self.healthy_releases == 0 {
            0.0
        } else {
            1000.0 * self.false_warnings as f64 / self.healthy_releases as f64
        }
    }
}

/// Runs the warning rule over the observed releases of a scenario.
pub fn measure(o: &DegradationOptions, observed: &[Observed], rule: &WarningRule) -> Measurement {
    let mut m = Measurement {
        lead_times: Vec::new(),
        false_warnings: 0,
        false_by_parameter: [0; 3],
        healthy_releases: 0,
        releases: o.releases,
    };
    for (i, wear) in o.wear.iter().enumerate() {
        let mut mine: Vec<&Observed> = observed.iter().filter(|x| x.truth.loco_index == i).collect();
        mine.sort_by_key(|x| x.truth.release);
        let records: Vec<ReleaseRecord> = mine.iter().map(|x| x.record.clone()).collect();
        let found = warnings(&records, rule);
        match parameter_of(*wear) {
            None => {
                m.healthy_releases += records.len().saturating_sub(rule.baseline);
                m.false_warnings += found.len();
                for w in &found {
                    m.false_by_parameter[w.parameter as usize] += 1;
                }
            }
            Some(p) => {
                let truth_fault_release = mine.iter().position(|x| x.truth.label != FaultClass::Normal);
                let first_call = mine.iter().position(|x| calls_fault(&verdict_label(x.record.verdict.as_ref()), p));
                let first_warning = found.iter().find(|w| w.parameter == p).map(|w| w.release_index);
                m.lead_times.push(LeadTime {
                    locomotive: mine.first().map(|x| x.truth.locomotive.clone()).unwrap_or_default(),
                    parameter: p,
                    truth_fault_release,
                    first_call,
                    first_warning,
                });
            }
        }
    }
    m
}
