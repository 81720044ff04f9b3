//! The per-sample work of the monitor task, in one place so that the firmware task and the
//! cost benchmark run exactly the same code: the core's [`Monitor::update`] (twin, residual,
//! estimator) and the core's CAN transmit schedule ([`CanReporter::step`], frame encoding).

use pbm::can::{CanReporter, Outbox};
use pbm::monitor::{Monitor, MonitorStep};
use pbm::{AdcCounts, ParamError, TwinParams};

/// Monitor plus CAN schedule.
#[derive(Debug, Clone)]
pub struct Pipeline {
    monitor: Monitor,
    reporter: CanReporter,
}

impl Pipeline {
    /// The pipeline for the nominal brake (SPEC §3).
    pub fn nominal() -> Result<Self, ParamError> {
        Ok(Self { monitor: Monitor::new(&TwinParams::nominal())?, reporter: CanReporter::new() })
    }

    /// One 100 Hz sample: the monitor step and the frames to transmit for it.
    ///
    /// The fault report comes from the classifier once the core's monitor provides a verdict;
    /// until then only status frames are scheduled.
    pub fn step(&mut self, adc: AdcCounts, valve_open: bool) -> (MonitorStep, Outbox) {
        let step = self.monitor.update(adc, valve_open);
        let frames = self.reporter.step(&self.monitor.status(), None, valve_open);
        (step, frames)
    }

    /// The monitor (status, estimator, fault report helpers).
    pub fn monitor(&self) -> &Monitor {
        &self.monitor
    }
}
