//! Online features of a release: per-sample, streaming, no allocation.
//!
//! Two extractors share one definition of the classifier's inputs:
//!
//! - [`ReleaseFeatures`] is what the pipeline carries on the brake controller: the physics
//!   features of [`physics`] (filling slopes, level times, knees, plateau), the residual mean and
//!   RMS (exact integer sums) and the online estimator's parameters, all in `f32` with
//!   correctly rounded operations only (the Cortex-M4F's hardware FPU, the same bits on the
//!   host). [`ReleaseFeatures::ours`] is the input vector of this project's classifier.
//! - [`FeatureExtractor`] (host tools, training) wraps a [`ReleaseFeatures`] and adds the
//!   paper's 21 statistics ([`stats`], `f64`) of the measured pressure and of the residual
//!   measured − twin, for the paper's two statistical classifiers. Its `ours` is the very same
//!   vector the firmware computes.
//!
//! Every feature is defined at every instant since the release command.
//!
//! Both read one [`ReleaseSample`] per sample: the measurement, the residual against the twin
//! and the online estimates. This module does not know who computes them; on the controller it
//! is the monitor, and [`crate::pipeline`] turns each monitor step into a [`ReleaseSample`].

pub mod physics;
pub mod stats;

use crate::estimator::Estimates;
use crate::sensor::SensorFault;
use crate::units::PressureQ24;
pub use physics::{fill_speed_up, PhaseTracker, INDEX_FILL_RATIO, INDEX_P_MAX, N_PHYSICS, PHYSICS_NAMES};
pub use stats::{SignalStats, N_STATS, STAT_NAMES};

/// Number of online-estimator parameters in [`ReleaseFeatures::theta`].
pub const N_THETA: usize = 4;

/// Names of [`ReleaseFeatures::theta`], in order.
pub const THETA_NAMES: [&str; N_THETA] =
    ["inflow_rate_bar_s", "leak_conductance_per_s", "plateau_bar_g", "supply_bar_g"];

/// Length of [`ReleaseFeatures::ours`]: the physics features, residual mean and RMS, and the
/// online estimator's parameters.
pub const N_OURS: usize = N_PHYSICS + 2 + N_THETA;

/// Names of [`ReleaseFeatures::ours`], in order.
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

/// Samples per second (the monitor's 100 Hz clock): `t = index / 100`.
const SAMPLES_PER_S: f32 = 100.0;
/// Right shift from Q7.24 to the Q16 residual of the RMS sums.
const RESIDUAL_SHIFT: u32 = 8;
/// One bar in the Q16 residual unit.
const RESIDUAL_ONE_BAR: f32 = (PressureQ24::ONE_BAR >> RESIDUAL_SHIFT) as f32;

/// One sample of a release as the features read it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReleaseSample {
    /// Samples since the release command: 0 at the command, which starts a new release.
    pub samples_since_release: u32,
    /// Measured chamber pressure, or why the reading is not one.
    pub measured: Result<PressureQ24, SensorFault>,
    /// Measured − twin, Q7.24 bar (not read when `measured` is a sensor fault).
    pub residual_q24: i32,
    /// The online estimates after this sample.
    pub estimates: Estimates,
}

/// The classifier's features of one release, as the pipeline computes them on the target.
///
/// Per sample: one block/band update of the [`PhaseTracker`] in `f32` and two integer sums of
/// the residual. Statistics that need a square root or a logarithm are evaluated only when
/// read ([`Self::ours`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReleaseFeatures {
    phase: PhaseTracker,
    samples: u32,
    faulty_samples: u32,
    last_fault: Option<SensorFault>,
    seen_fault: Option<SensorFault>,
    /// Valid samples in the residual sums.
    residual_n: u32,
    /// Σ residual, Q16 bar (saturating; |residual| < 2^21 in Q16, so exact for 2^42 samples).
    residual_sum_q16: i64,
    /// Σ residual², Q32 bar² (saturating).
    residual_sq_sum_q32: u64,
    theta: [f32; N_THETA],
}

impl ReleaseFeatures {
    /// Features at the release command.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets everything (a new release command).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Adds one sample. A sample with `samples_since_release == 0` starts a new release.
    pub fn update(&mut self, sample: &ReleaseSample) {
        if sample.samples_since_release == 0 {
            self.reset();
        }
        self.push(sample.samples_since_release, sample.measured, sample.residual_q24);
        self.set_estimates(&sample.estimates);
    }

    /// Records the online estimator's current parameters (unknown or non-finite ones read 0).
    pub fn set_estimates(&mut self, e: &Estimates) {
        let v = |x: Option<f32>| x.filter(|v| v.is_finite()).unwrap_or(0.0);
        self.theta = [v(e.inflow_rate_bar_s), v(e.leak_conductance_per_s), v(e.plateau_bar_g), v(e.supply_bar_g)];
    }

    /// The online estimator's parameters ([`THETA_NAMES`]), 0 where not identified yet.
    pub fn theta(&self) -> [f32; N_THETA] {
        self.theta
    }

    /// Adds the sample taken `index` samples after the release command: the measured pressure
    /// (or the sensor fault) and the residual measured − twin (Q7.24 bar).
    pub fn push(&mut self, index: u32, measured: Result<PressureQ24, SensorFault>, residual_q24: i32) {
        let t = index as f32 / SAMPLES_PER_S;
        self.samples = self.samples.saturating_add(1);
        match measured {
            Ok(p) => {
                let p_bar_g = gauge_bar(p);
                let r = i64::from(residual_q24 >> RESIDUAL_SHIFT);
                self.residual_n = self.residual_n.saturating_add(1);
                self.residual_sum_q16 = self.residual_sum_q16.saturating_add(r);
                self.residual_sq_sum_q32 = self.residual_sq_sum_q32.saturating_add(r.unsigned_abs().pow(2));
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
    pub fn t_now(&self) -> f32 {
        self.phase.t_now()
    }

    /// The physics tracker.
    pub fn phase(&self) -> &PhaseTracker {
        &self.phase
    }

    /// Mean and RMS of the residual measured − twin over the valid samples, bar (0 before the
    /// first one).
    pub fn residual_mean_rms(&self) -> (f32, f32) {
        if self.residual_n == 0 {
            return (0.0, 0.0);
        }
        let n = self.residual_n as f32;
        let mean = self.residual_sum_q16 as f32 / n / RESIDUAL_ONE_BAR;
        let rms = libm::sqrtf(self.residual_sq_sum_q32 as f32 / n) / RESIDUAL_ONE_BAR;
        (mean, rms)
    }

    /// Input vector of this project's classifier ([`OURS_NAMES`]).
    pub fn ours(&self) -> [f32; N_OURS] {
        let mut v = [0.0; N_OURS];
        let (physics, rest) = v.split_at_mut(N_PHYSICS);
        physics.copy_from_slice(&self.phase.values());
        let (mean, rms) = self.residual_mean_rms();
        let (residual, theta) = rest.split_at_mut(2);
        residual.copy_from_slice(&[mean, rms]);
        theta.copy_from_slice(&self.theta);
        v
    }
}

impl AsRef<ReleaseFeatures> for ReleaseFeatures {
    fn as_ref(&self) -> &ReleaseFeatures {
        self
    }
}

/// Gauge pressure in bar of a Q7.24 absolute pressure, `f32` (exact power-of-two scaling of
/// the correctly rounded integer conversion).
fn gauge_bar(p: PressureQ24) -> f32 {
    p.0.saturating_sub(PressureQ24::ONE_BAR) as f32 * (1.0 / PressureQ24::ONE_BAR as f32)
}

/// Host-side extractor: the classifier's [`ReleaseFeatures`] plus the paper's 21 statistics
/// of the measured pressure (bar g) and of the residual (bar), in `f64`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FeatureExtractor {
    release: ReleaseFeatures,
    raw: SignalStats,
    residual: SignalStats,
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

    /// Adds one sample (see [`ReleaseFeatures::update`]).
    pub fn update(&mut self, sample: &ReleaseSample) {
        if sample.samples_since_release == 0 {
            self.reset();
        }
        self.release.update(sample);
        if let Ok(p) = sample.measured {
            self.raw.push(p.to_bar_g().0);
            self.residual.push(f64::from(sample.residual_q24) * BAR_PER_Q24);
        }
    }

    /// The classifier's features (what the controller computes).
    pub fn release(&self) -> &ReleaseFeatures {
        &self.release
    }

    /// The online estimator's parameters ([`THETA_NAMES`]), 0 where not identified yet.
    pub fn theta(&self) -> [f64; N_THETA] {
        self.release.theta.map(f64::from)
    }

    /// Samples seen since the release command (valid or not).
    pub fn samples(&self) -> u32 {
        self.release.samples
    }

    /// Samples that were sensor faults.
    pub fn faulty_samples(&self) -> u32 {
        self.release.faulty_samples
    }

    /// The fault of the latest sample, if it was one.
    pub fn last_fault(&self) -> Option<SensorFault> {
        self.release.last_fault
    }

    /// The physics tracker.
    pub fn phase(&self) -> &PhaseTracker {
        &self.release.phase
    }

    /// The 21 statistics of the measured pressure (bar g).
    pub fn raw_stats(&self) -> [f64; N_STATS] {
        self.raw.values()
    }

    /// The 21 statistics of the residual measured − twin (bar).
    pub fn residual_stats(&self) -> [f64; N_STATS] {
        self.residual.values()
    }

    /// Input vector of this project's classifier ([`OURS_NAMES`]), widened exactly to `f64`.
    pub fn ours(&self) -> [f64; N_OURS] {
        self.release.ours().map(f64::from)
    }
}

impl AsRef<ReleaseFeatures> for FeatureExtractor {
    fn as_ref(&self) -> &ReleaseFeatures {
        &self.release
    }
}
