//! Online features of a release: per-sample, streaming, no allocation.
//!
//! [`FeatureExtractor`] takes the monitor's output one sample at a time and keeps
//!
//! - the paper's 21 statistics ([`stats`]) of the measured pressure (bar g) and of the
//!   residual measured − twin (bar), for the paper's two statistical classifiers, and
//! - the physics features of [`physics`] (filling slopes, level times, knees, plateau),
//!
//! all defined at every instant since the release command. [`FeatureExtractor::ours`] is the
//! input vector of this project's classifier.

pub mod physics;
pub mod stats;

use crate::estimator::Estimates;
use crate::monitor::MonitorStep;
use crate::sensor::SensorFault;
use crate::twin::SAMPLE_PERIOD_S;
use crate::units::PressureQ24;
pub use physics::{PhaseTracker, N_PHYSICS, PHYSICS_NAMES};
pub use stats::{SignalStats, N_STATS, STAT_NAMES};

/// Number of online-estimator parameters in [`FeatureExtractor::theta`].
pub const N_THETA: usize = 4;

/// Names of [`FeatureExtractor::theta`], in order.
pub const THETA_NAMES: [&str; N_THETA] =
    ["inflow_rate_bar_s", "leak_conductance_per_s", "plateau_bar_g", "supply_bar_g"];

/// Length of [`FeatureExtractor::ours`]: the physics features, residual mean and RMS, and the
/// online estimator's parameters.
pub const N_OURS: usize = N_PHYSICS + 2 + N_THETA;

/// Names of [`FeatureExtractor::ours`], in order.
pub const OURS_NAMES: [&str; N_OURS] = {
    let mut names = [""; N_OURS];
    let mut i = 0;
    while i < N_PHYSICS {
        names[i] = PHYSICS_NAMES[i];
        i += 1;
    }
    names[N_PHYSICS] = "residual_mean";
    names[N_PHYSICS + 1] = "residual_rms";
    let mut k = 0;
    while k < N_THETA {
        names[N_PHYSICS + 2 + k] = THETA_NAMES[k];
        k += 1;
    }
    names
};

/// Streaming feature extractor of one release.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FeatureExtractor {
    raw: SignalStats,
    residual: SignalStats,
    phase: PhaseTracker,
    samples: u32,
    faulty_samples: u32,
    last_fault: Option<SensorFault>,
    seen_fault: Option<SensorFault>,
    theta: [f64; N_THETA],
}

/// Bar per Q24 LSB.
const BAR_PER_Q24: f64 = 1.0 / PressureQ24::ONE_BAR as f64;

impl FeatureExtractor {
    /// An extractor at the release command.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets everything (a new release command).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Adds one monitor step. A step with `samples_since_release == 0` starts a new release
    /// (the monitor reports 0 at the release command and while no release is in progress).
    pub fn update(&mut self, step: &MonitorStep) {
        if step.samples_since_release == 0 {
            self.reset();
        }
        self.push(step.samples_since_release, step.measured, step.residual_q24);
        self.set_estimates(&step.estimates);
    }

    /// Records the online estimator's current parameters (unknown ones read 0).
    pub fn set_estimates(&mut self, e: &Estimates) {
        let v = |x: Option<f32>| x.filter(|v| v.is_finite()).map_or(0.0, f64::from);
        self.theta = [v(e.inflow_rate_bar_s), v(e.leak_conductance_per_s), v(e.plateau_bar_g), v(e.supply_bar_g)];
    }

    /// The online estimator's parameters ([`THETA_NAMES`]), 0 where not identified yet.
    pub fn theta(&self) -> [f64; N_THETA] {
        self.theta
    }

    /// Adds the sample taken `index` samples after the release command: the measured pressure
    /// (or the sensor fault) and the residual measured − twin (Q7.24 bar).
    pub fn push(&mut self, index: u32, measured: Result<PressureQ24, SensorFault>, residual_q24: i32) {
        let t = f64::from(index) * SAMPLE_PERIOD_S;
        self.samples = self.samples.saturating_add(1);
        match measured {
            Ok(p) => {
                let p_bar_g = p.to_bar_g().0;
                self.raw.push(p_bar_g);
                self.residual.push(f64::from(residual_q24) * BAR_PER_Q24);
                self.phase.push(t, Some(p_bar_g));
                self.last_fault = None;
            }
            Err(fault) => {
                self.faulty_samples = self.faulty_samples.saturating_add(1);
                self.last_fault = Some(fault);
                self.seen_fault = Some(fault);
                self.phase.push(t, None);
            }
        }
    }

    /// Samples seen since the release command (valid or not).
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// Samples that were sensor faults.
    pub fn faulty_samples(&self) -> u32 {
        self.faulty_samples
    }

    /// The fault of the latest sample, if it was one.
    pub fn last_fault(&self) -> Option<SensorFault> {
        self.last_fault
    }

    /// The most recent sensor fault of this release, even if later samples were valid.
    pub fn seen_fault(&self) -> Option<SensorFault> {
        self.seen_fault
    }

    /// Seconds since the release command (time of the latest sample).
    pub fn t_now(&self) -> f64 {
        self.phase.t_now()
    }

    /// The 21 statistics of the measured pressure (bar g).
    pub fn raw_stats(&self) -> [f64; N_STATS] {
        self.raw.values()
    }

    /// The 21 statistics of the residual measured − twin (bar).
    pub fn residual_stats(&self) -> [f64; N_STATS] {
        self.residual.values()
    }

    /// The physics tracker.
    pub fn phase(&self) -> &PhaseTracker {
        &self.phase
    }

    /// Input vector of this project's classifier ([`OURS_NAMES`]).
    pub fn ours(&self) -> [f64; N_OURS] {
        let mut v = [0.0; N_OURS];
        v[..N_PHYSICS].copy_from_slice(&self.phase.values());
        let r = self.residual.values();
        v[N_PHYSICS] = r[0];
        v[N_PHYSICS + 1] = r[6];
        v[N_PHYSICS + 2..].copy_from_slice(&self.theta);
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::monitor::Monitor;
    use crate::sensor::adc_from_bar;
    use crate::units::{AdcCounts, BarG};
    use crate::{Twin, TwinParams};

    #[test]
    fn nominal_release_through_the_monitor() {
        let params = TwinParams::nominal();
        let mut plant = Twin::new(&params).unwrap();
        let mut monitor = Monitor::new(&params).unwrap();
        let mut fx = FeatureExtractor::new();
        let mut p = plant.state().p_q24;
        for _ in 0..6000 {
            let step = monitor.update(adc_from_bar(PressureQ24(p).to_bar_g()), true);
            fx.update(&step);
            p = plant.update(true).pressure.0;
        }
        assert_eq!(fx.samples(), 6000);
        let raw = fx.raw_stats();
        assert!((raw[3] - 7.7).abs() < 0.01, "max {}", raw[3]);
        let res = fx.residual_stats();
        assert!(res[6] < 0.01, "residual RMS of the twin against itself {}", res[6]);
        let (_, p_break) = fx.phase().breakaway().unwrap();
        assert!((3.9..4.5).contains(&p_break), "breakaway {p_break}");
        let (t_end, _) = fx.phase().end_stop().unwrap();
        assert!((20.0..24.0).contains(&t_end), "end stop {t_end}");
        let v = fx.ours();
        assert!((v[12] - 0.79).abs() < 0.02, "choked filling slope {}", v[12]);
        assert!((v[25] - 1.0).abs() < 0.02 && (v[26] - 1.0).abs() < 0.03, "{} {}", v[25], v[26]);
        assert_eq!(OURS_NAMES[N_PHYSICS + 1], "residual_rms");
        assert_eq!(OURS_NAMES[N_OURS - 1], "supply_bar_g");
        let theta = fx.theta();
        assert!((theta[2] - 7.7).abs() < 0.02, "estimated plateau {}", theta[2]);
        assert_eq!(v[N_PHYSICS + 2..], theta);
    }

    #[test]
    fn sensor_faults_are_counted_not_accumulated() {
        let mut monitor = Monitor::new(&TwinParams::nominal()).unwrap();
        let mut fx = FeatureExtractor::new();
        for i in 0..100 {
            let adc = if i >= 90 { AdcCounts(0) } else { adc_from_bar(BarG(0.01 * f64::from(i))) };
            fx.update(&monitor.update(adc, true));
        }
        assert_eq!(fx.faulty_samples(), 10);
        assert_eq!(fx.last_fault(), Some(SensorFault::OpenCircuit));
        assert!((fx.raw_stats()[0] - 0.445).abs() < 0.003, "mean of the 90 valid samples");
        // A new release command resets everything.
        monitor.update(adc_from_bar(BarG(0.0)), false);
        fx.update(&monitor.update(adc_from_bar(BarG(0.0)), true));
        assert_eq!((fx.samples(), fx.faulty_samples()), (1, 0));
    }
}
