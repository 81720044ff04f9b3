//! The per-sample monitor: ADC reading and valve command in; the twin's prediction, the
//! residual, the plausibility checks of the signal and the online estimates out.
//!
//! Every sample feeds the twin (restarted at each release command), the plausibility checks
//! ([`SignalCheck`]) and the online [`ReleaseEstimator`]; [`MonitorStep`] carries what they
//! said about the sample and [`Monitor::status`] the status report. The release features, the
//! classifier and the diagnosis policy are built on top of it by [`crate::pipeline`], which is
//! the entry point the firmware and `host-sim replay` call.

use crate::estimator::{Estimates, EstimatorConfig, ReleaseEstimator};
use crate::params::{ParamError, TwinParams};
use crate::plausibility::{Detected, SignalCheck};
use crate::report::StatusReport;
use crate::sensor::{pressure_from_adc, SensorFault};
use crate::twin::{Twin, TwinSample};
use crate::units::{AdcCounts, PressureQ24};

/// Firmware/protocol version reported in the status frame.
pub const VERSION: (u8, u8) = (0, 1);

/// What one monitor step produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonitorStep {
    /// Measured chamber pressure, or why the reading is not one (range check of this sample).
    pub measured: Result<PressureQ24, SensorFault>,
    /// Why the signal cannot be trusted now: this sample's range fault, else the plausibility
    /// fault latched since the release command ([`crate::plausibility`]); `None` when trusted.
    pub sensor: Option<SensorFault>,
    /// The twin's prediction for this sample.
    pub twin: TwinSample,
    /// Measured − twin, Q7.24 bar (0 when the reading is a sensor fault).
    pub residual_q24: i32,
    /// Samples since the release command (0 when no release is in progress).
    pub samples_since_release: u32,
    /// The online estimates after this sample.
    pub estimates: Estimates,
}

/// The monitor: twin of the nominal brake run beside the measurement.
#[derive(Debug, Clone)]
pub struct Monitor {
    twin: Twin,
    valve_was_open: bool,
    samples_since_release: u32,
    last_measured: Result<PressureQ24, SensorFault>,
    /// Plausibility checks of the signal.
    check: SignalCheck,
    /// What the checks said about the last sample.
    last_sensor: Option<SensorFault>,
    estimator: ReleaseEstimator,
}

impl Monitor {
    /// A monitor whose twin is the given brake (normally [`TwinParams::nominal`]).
    pub fn new(params: &TwinParams) -> Result<Self, ParamError> {
        let twin = Twin::new(params)?;
        // `Twin::new` has validated `params`, and the default estimator configuration is valid,
        // so this cannot fail; should it ever, report it as the parameter it depends on most.
        let estimator =
            ReleaseEstimator::new(params, EstimatorConfig::default()).map_err(|_| ParamError::DischargeCoeff)?;
        Ok(Self::from_parts(twin, estimator))
    }

    /// The monitor of the nominal brake, from the precomputed nominal constants
    /// ([`Twin::nominal`], [`ReleaseEstimator::nominal`]): equal to
    /// `Monitor::new(&TwinParams::nominal())` without its `f64` set-up.
    // Inlined: the ~2.4 KiB result is built in place, not copied through the stack.
    #[inline(always)]
    pub fn nominal() -> Result<Self, ParamError> {
        let estimator =
            ReleaseEstimator::nominal(EstimatorConfig::default()).map_err(|_| ParamError::DischargeCoeff)?;
        Ok(Self::from_parts(Twin::nominal(), estimator))
    }

    /// The monitor of the nominal brake's estimator with another twin (built from coefficients
    /// a build script derived, [`crate::twin::TwinCoeffs::from_raw`]): the firmware's extended
    /// twin without `f64` set-up code. The estimator keeps its nominal design constants.
    // Inlined: the ~2.4 KiB result is built in place, not copied through the stack.
    #[inline(always)]
    pub fn with_twin(twin: Twin) -> Result<Self, ParamError> {
        let estimator =
            ReleaseEstimator::nominal(EstimatorConfig::default()).map_err(|_| ParamError::DischargeCoeff)?;
        Ok(Self::from_parts(twin, estimator))
    }

    // Inlined: the ~2.4 KiB result is built in place, not copied through the stack.
    #[inline(always)]
    fn from_parts(twin: Twin, estimator: ReleaseEstimator) -> Self {
        Self {
            twin,
            valve_was_open: false,
            samples_since_release: 0,
            last_measured: Ok(PressureQ24::ATMOSPHERE),
            check: SignalCheck::new(),
            last_sensor: None,
            estimator,
        }
    }

    /// Processes one 100 Hz sample. `valve_open` is the release command. A rising edge of the
    /// command starts a release: the twin restarts from the applied, vented state.
    ///
    /// The twin is sampled like the ADC: the sample taken `n` periods after the command is
    /// compared with the twin after `n` updates, so sample 0 (at the command) is the vented chamber.
    pub fn update(&mut self, adc: AdcCounts, valve_open: bool) -> MonitorStep {
        if valve_open && !self.valve_was_open {
            self.twin.reset();
            self.samples_since_release = 0;
        }
        let twin = TwinSample { pressure: self.twin.state().p, travel: self.twin.state().x };
        let measured = pressure_from_adc(adc);
        let sensor = self.check.update(adc, valve_open);
        let residual_q24 = match measured {
            Ok(p) => p.0.saturating_sub(twin.pressure.0),
            Err(_) => 0,
        };
        // A refused regression is recorded by the estimator and reported through `status`;
        // the sample itself is still monitored.
        let _ = self.estimator.update(measured.ok(), valve_open);
        let step = MonitorStep {
            measured,
            sensor,
            twin,
            residual_q24,
            samples_since_release: if valve_open { self.samples_since_release } else { 0 },
            estimates: self.estimator.estimates(),
        };
        self.twin.update(valve_open);
        if valve_open {
            self.samples_since_release = self.samples_since_release.saturating_add(1);
        }
        self.valve_was_open = valve_open;
        self.last_measured = measured;
        self.last_sensor = sensor;
        step
    }

    /// The release command ended without a falling edge being seen (e.g. the input stopped):
    /// the next sample with the command on starts a new release, as after a falling edge, for
    /// the twin, the online estimator and the plausibility checks alike.
    pub fn end_release(&mut self) {
        self.valve_was_open = false;
        self.check.end_release();
        self.estimator.end_release();
    }

    /// The status/heartbeat report for the current state.
    pub fn status(&self) -> StatusReport {
        let pressure_mbar = match self.last_measured {
            Ok(p) => {
                let mbar = (i64::from(p.0) - i64::from(PressureQ24::ONE_BAR)) * 1000 >> 24;
                mbar.clamp(0, i64::from(u16::MAX)) as u16
            }
            Err(_) => 0,
        };
        StatusReport {
            sensor_fault: self.last_sensor,
            estimator: self.estimator.state(),
            pressure_mbar,
            version: VERSION,
        }
    }

    /// The online estimator (estimates, phase, last error).
    pub fn estimator(&self) -> &ReleaseEstimator {
        &self.estimator
    }

    /// Samples seen with the release command on since the last command (kept after it ends).
    pub fn samples_in_release(&self) -> u32 {
        self.samples_since_release
    }

    /// The sensor fault latched since the last release command, with its onset.
    pub fn sensor_fault(&self) -> Option<Detected> {
        self.check.latched()
    }

    /// The release did not start from a vented chamber as far as the reading tells
    /// ([`SignalCheck::unvented_start`]): not a release the twin can judge.
    pub fn unvented_start(&self) -> bool {
        self.check.unvented_start()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::adc_from_bar;
    use crate::units::BarG;

    #[test]
    fn release_restarts_twin_and_tracks_residual() {
        let mut m = Monitor::new(&TwinParams::nominal()).unwrap();
        let first = m.update(adc_from_bar(BarG(0.0)), true);
        assert_eq!(first.samples_since_release, 0);
        assert_eq!(first.twin.pressure, PressureQ24::ATMOSPHERE);
        // 0 bar g reads as 410 counts = 0.0015 bar: a residual of one ADC half-step.
        assert!(first.residual_q24.abs() < PressureQ24::ONE_BAR / 300);
        for _ in 0..99 {
            m.update(adc_from_bar(BarG(0.5)), true);
        }
        let s = m.update(AdcCounts(0), true);
        assert_eq!(s.samples_since_release, 100);
        assert_eq!(s.measured, Err(SensorFault::OpenCircuit));
        assert_eq!(m.status().sensor_fault, Some(SensorFault::OpenCircuit));
    }

    #[test]
    fn estimates_reach_the_step_and_the_status() {
        use crate::report::EstimatorState;
        let params = TwinParams::nominal().with_leak_mm(0.8);
        let mut plant = Twin::new(&params).unwrap();
        let mut m = Monitor::new(&TwinParams::nominal()).unwrap();
        assert_eq!(m.status().estimator, EstimatorState::Idle);
        let mut p = PressureQ24::ATMOSPHERE;
        let mut step = m.update(adc_from_bar(p.to_bar_g()), true);
        assert_eq!(m.status().estimator, EstimatorState::Converging);
        for _ in 0..5999 {
            p = plant.update(true).pressure;
            step = m.update(adc_from_bar(p.to_bar_g()), true);
        }
        let e = step.estimates;
        let leak = e.leak_mm.unwrap();
        assert!((leak - 0.8).abs() < 0.05, "{e:?}");
        assert!((e.orifice_mm.unwrap() - 1.25).abs() < 0.05, "{e:?}");
        assert!((e.supply_bar_g.unwrap() - 7.7).abs() < 0.2, "{e:?}");
        assert_eq!(m.status().estimator, EstimatorState::Settled);
        assert_eq!(m.samples_in_release(), 6000);
        // Valve closed: idle, estimates kept for the report.
        m.update(adc_from_bar(p.to_bar_g()), false);
        assert_eq!(m.status().estimator, EstimatorState::Idle);
        assert_eq!(m.estimator().estimates().leak_um(), e.leak_um());
    }
}
