//! The whole per-sample path of the brake controller in one place: ADC reading and valve
//! command in, CAN frames out. The firmware's monitor task and `host-sim replay --can-log` both
//! drive this type, so the two cannot drift apart: same monitor, same diagnosis policy, same
//! transmit schedule, same counters, same bytes (and [`crate::can::candump`] writes the same log
//! lines).
//!
//! Per sample ([`Pipeline::step`]): [`Monitor::update`] (twin, residual, online estimator,
//! classifier features), the diagnosis policy below, then the core's CAN transmit schedule
//! ([`CanReporter::step`]: status at 1 Hz, the fault report when it appears or changes and
//! repeated at 1 Hz while the valve command is on).
//!
//! # Diagnosis policy (issue 7 item 2)
//!
//! - A rising edge of the valve command (release requested) opens a diagnosis; the report of
//!   the previous release is withdrawn from the schedule (the display holds what it showed).
//! - The diagnosis is closed, and the classifier run once on the features of the release, by
//!   whichever comes first:
//!   - the valve command falling (release over);
//!   - a timeout of [`DIAGNOSIS_WINDOW_SAMPLES`] samples (60 s, the length of a recorded
//!     release in SPEC §5) since the command: the sample that completes the window closes it;
//!   - the end of the input ([`Pipeline::close`]: the ADC source ended, e.g. a recorded trace
//!     shorter than the window), which runs one more transmit tick so the report goes out.
//! - The closed report (verdict, time since the command, estimated supply and leak) is then
//!   scheduled as it stands until the next release command, with one exception:
//! - **A sensor fault found after the close.** The plausibility checks
//!   ([`crate::plausibility`]) need up to a few seconds of evidence (0.5 s of a frozen run,
//!   1 s of noise, 2.56 s for lost resolution) and date each fault back to its onset. If a
//!   fault is found after the close whose onset lies at or before the closing sample, the
//!   verdict was computed on bad data: the report is replaced by *cannot diagnose: sensor
//!   fault* and sent again. A fault whose onset lies after the closing sample leaves the
//!   verdict standing: it was closed on good data (the status frame still shows the fault).
//!   A sensor fault found before the close always gives *cannot diagnose: sensor fault*.
//!
//! The classifier runs once per release (≈ 30 000 instructions on the Cortex-M4F, about 1 ms at
//! 25 MHz, well inside one 10 ms sample period), so the per-sample cost stays small.

use crate::can::{CanReporter, Outbox};
use crate::monitor::{Monitor, MonitorStep};
use crate::params::{ParamError, TwinParams};
use crate::report::{FaultReport, NoDiagnosis, Verdict};
use crate::units::AdcCounts;

/// Samples from the release command to the timeout that closes a diagnosis (60 s at 100 Hz).
pub const DIAGNOSIS_WINDOW_SAMPLES: u32 = 6000;

/// What one pipeline step produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipelineStep {
    /// The monitor's output for this sample.
    pub monitor: MonitorStep,
    /// Frames to transmit for this sample, in order.
    pub frames: Outbox,
    /// The report of a diagnosis closed at this sample, if one was.
    pub closed: Option<FaultReport>,
}

/// Monitor, diagnosis policy and CAN schedule.
#[derive(Debug, Clone)]
pub struct Pipeline {
    monitor: Monitor,
    reporter: CanReporter,
    valve_was_open: bool,
    /// A diagnosis is open (release command seen, not yet closed).
    diagnosing: bool,
    /// The report of the last closed diagnosis, scheduled for transmission.
    report: Option<FaultReport>,
    /// Samples since the release command at which the last diagnosis was closed.
    closed_at: u32,
}

impl Pipeline {
    /// A pipeline whose twin is the given brake (normally [`TwinParams::nominal`]).
    pub fn new(params: &TwinParams) -> Result<Self, ParamError> {
        Ok(Self::with_monitor(Monitor::new(params)?))
    }

    // Inlined: the ~2.4 KiB result is built in place, not copied through the stack.
    #[inline(always)]
    fn with_monitor(monitor: Monitor) -> Self {
        Self {
            monitor,
            reporter: CanReporter::new(),
            valve_was_open: false,
            diagnosing: false,
            report: None,
            closed_at: 0,
        }
    }

    /// The pipeline for the nominal brake (SPEC §3), from the precomputed nominal constants
    /// ([`Monitor::nominal`]): what `Pipeline::new(&TwinParams::nominal())` builds, without
    /// `f64` set-up code in the firmware image.
    // Inlined: the ~2.4 KiB result is built in place, not copied through the stack.
    #[inline(always)]
    pub fn nominal() -> Result<Self, ParamError> {
        Ok(Self::with_monitor(Monitor::nominal()?))
    }

    /// One 100 Hz sample: monitor, diagnosis policy, transmit schedule.
    pub fn step(&mut self, adc: AdcCounts, valve_open: bool) -> PipelineStep {
        let monitor = self.monitor.update(adc, valve_open);
        let mut closed = None;
        if valve_open && !self.valve_was_open {
            self.diagnosing = true;
            self.report = None;
            self.reporter.new_release();
        }
        let window_done = valve_open && monitor.samples_since_release.saturating_add(1) >= DIAGNOSIS_WINDOW_SAMPLES;
        if self.diagnosing && (!valve_open || window_done) {
            closed = Some(self.close_diagnosis());
        } else if !self.diagnosing {
            self.withdraw_if_closed_on_bad_data();
        }
        self.valve_was_open = valve_open;
        let frames = self.reporter.step(&self.monitor.status(), self.report.as_ref(), valve_open);
        PipelineStep { monitor, frames, closed }
    }

    /// The input ended (no more samples): closes an open diagnosis and returns its report with
    /// the frames of one last transmit tick (the fault report, and the status if one is due).
    /// `None` (nothing to send) when no diagnosis was open.
    ///
    /// Either way the release ends: the next sample with the command on is a new release (a
    /// new diagnosis; twin, features, estimator and plausibility checks restarted), also when
    /// the timeout had already closed the diagnosis with the command still on.
    pub fn close(&mut self) -> Option<(FaultReport, Outbox)> {
        let closed = if self.diagnosing {
            let report = self.close_diagnosis();
            // Status and report as the last sample left them (before the release ends below).
            Some((report, self.reporter.step(&self.monitor.status(), Some(&report), false)))
        } else {
            None
        };
        self.valve_was_open = false;
        self.monitor.end_release();
        closed
    }

    fn close_diagnosis(&mut self) -> FaultReport {
        let report = self.monitor.diagnosis();
        self.diagnosing = false;
        self.report = Some(report);
        // Samples seen since the command: every sample up to and including this one.
        self.closed_at = self.monitor.samples_in_release();
        report
    }

    /// A sensor fault found after the close whose onset lies at or before it voids the verdict.
    fn withdraw_if_closed_on_bad_data(&mut self) {
        let (Some(report), Some(found)) = (self.report.as_mut(), self.monitor.sensor_fault()) else { return };
        if found.onset <= self.closed_at && matches!(report.verdict, Verdict::Class { .. }) {
            report.verdict = Verdict::CannotDiagnose(NoDiagnosis::SensorFault(found.fault));
        }
    }

    /// The monitor (status, estimator, features).
    pub fn monitor(&self) -> &Monitor {
        &self.monitor
    }

    /// The report of the last closed diagnosis (`None` while one is open or before the first).
    pub fn report(&self) -> Option<&FaultReport> {
        self.report.as_ref()
    }

    /// Samples since the release command at which the last diagnosis was closed (every sample
    /// before it, and it, were part of the verdict).
    pub fn closed_at(&self) -> u32 {
        self.closed_at
    }

    /// A diagnosis is open.
    pub fn diagnosing(&self) -> bool {
        self.diagnosing
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::can::reporter::FAULT_MIN_GAP_SAMPLES;
    use crate::can::{decode_frame, Report};
    use crate::report::{NoDiagnosis, Verdict};
    use crate::sensor::adc_from_bar;
    use crate::units::{BarG, PressureQ24};
    use crate::{FaultClass, Twin};
    use std::vec::Vec;

    fn fault_reports(frames: &[crate::can::CanFrame]) -> usize {
        frames.iter().filter(|f| matches!(decode_frame(*f), Ok((Report::Fault(_), _)))).count()
    }

    #[test]
    fn timeout_closes_the_diagnosis_of_a_full_release() {
        let mut plant = Twin::new(&TwinParams::nominal().with_orifice_mm(0.6)).unwrap();
        let mut pipe = Pipeline::nominal().unwrap();
        let mut p = PressureQ24::ATMOSPHERE;
        let mut reports = 0;
        for i in 0..DIAGNOSIS_WINDOW_SAMPLES + 150 {
            let s = pipe.step(adc_from_bar(p.to_bar_g()), true);
            p = plant.update(true).pressure;
            reports += fault_reports(s.frames.as_slice());
            assert_eq!(s.closed.is_some(), i == DIAGNOSIS_WINDOW_SAMPLES - 1, "sample {i}");
            if let Some(r) = s.closed {
                assert!(matches!(r.verdict, Verdict::Class { class: FaultClass::OrificeBlock, .. }), "{r:?}");
                assert_eq!(r.time_since_release_cs, 6000);
                assert_eq!(fault_reports(s.frames.as_slice()), 1, "sent at once");
            }
        }
        assert!(!pipe.diagnosing());
        assert_eq!(reports, 2, "sent at the timeout, repeated after 1 s while the valve is open");
        assert!(pipe.close().is_none(), "nothing open at the end of the input");
    }

    /// A reading with transducer-like noise (±3 codes, deterministic): noise-free input is a
    /// frozen sensor to the plausibility checks.
    fn noisy(p_bar: f64, i: u32) -> AdcCounts {
        const PATTERN: [i16; 7] = [0, 3, -2, 1, -3, 2, -1];
        let c = adc_from_bar(BarG(p_bar)).0 as i16 + PATTERN[(i as usize * 5 + i as usize / 7) % 7];
        AdcCounts(c as u16)
    }

    #[test]
    fn end_of_input_and_valve_closing_close_the_diagnosis() {
        let mut pipe = Pipeline::nominal().unwrap();
        for i in 0..50 {
            assert!(pipe.step(noisy(0.01 * f64::from(i), i), true).closed.is_none());
        }
        let (report, frames) = pipe.close().unwrap();
        assert_eq!(report.verdict, Verdict::CannotDiagnose(NoDiagnosis::TooShort));
        assert_eq!(fault_reports(frames.as_slice()), 1);
        // A new release, then the valve closes: closed at that sample, sent once the 100 ms
        // minimum gap since the last report has passed.
        assert!(pipe.step(noisy(0.0, 0), true).closed.is_none());
        assert!(pipe.report().is_none(), "the old report is withdrawn at the new command");
        let s = pipe.step(noisy(0.0, 1), false);
        assert!(s.closed.is_some());
        let mut n = fault_reports(s.frames.as_slice());
        for i in 0..10 {
            n += fault_reports(pipe.step(noisy(0.0, i), false).frames.as_slice());
        }
        assert_eq!(n, 1, "sent within the gap");
        // Valve stays closed: no repeats.
        let n: usize = (0..300).map(|i| fault_reports(pipe.step(noisy(0.0, i), false).frames.as_slice())).sum();
        assert_eq!(n, 0);
    }

    #[test]
    fn a_release_that_does_not_start_vented_is_unfamiliar() {
        let mut pipe = Pipeline::nominal().unwrap();
        for i in 0..300 {
            pipe.step(noisy(2.0 + 0.001 * f64::from(i), i), true);
        }
        let (report, _) = pipe.close().unwrap();
        assert_eq!(report.verdict, Verdict::CannotDiagnose(NoDiagnosis::Unfamiliar));
    }

    #[test]
    fn close_at_end_of_input_restarts_the_twin_at_the_next_command() {
        let mut pipe = Pipeline::nominal().unwrap();
        for i in 0..500 {
            pipe.step(noisy(0.0, i), true);
        }
        pipe.close().unwrap();
        let s = pipe.step(noisy(0.0, 0), true);
        assert_eq!(s.monitor.samples_since_release, 0, "a new release for the monitor too");
        assert_eq!(s.monitor.twin.pressure, PressureQ24::ATMOSPHERE, "twin restarted from the vented state");
        assert!(pipe.diagnosing());
    }

    /// Review finding (issue 16): the end of the input must end the release for every part of
    /// the pipeline, whether its diagnosis was still open (a short input) or already closed by
    /// the timeout with the command still on. The next sample with the command on is then a
    /// fresh release: a new diagnosis, the twin back in the applied state, sample 0, features,
    /// online estimator and plausibility checks restarted (a fault latched in the previous
    /// release is forgotten).
    #[test]
    fn close_then_a_new_command_starts_a_fresh_release() {
        use crate::report::EstimatorState;
        let fresh_first = Pipeline::nominal().unwrap().step(noisy(0.0, 0), true);
        for samples in [500, DIAGNOSIS_WINDOW_SAMPLES + 100] {
            let mut pipe = Pipeline::nominal().unwrap();
            let mut plant = Twin::new(&TwinParams::nominal()).unwrap();
            let mut p = PressureQ24::ATMOSPHERE;
            for i in 0..samples {
                // The sensor freezes for the last second: a fault latched in this release.
                let adc = if i + 100 >= samples { adc_from_bar(p.to_bar_g()) } else { noisy(p.to_bar_g().0, i) };
                pipe.step(adc, true);
                if i + 100 < samples {
                    p = plant.update(true).pressure;
                }
            }
            assert!(pipe.monitor().sensor_fault().is_some(), "{samples}: the frozen second latched a fault");
            assert_eq!(pipe.close().is_some(), samples < DIAGNOSIS_WINDOW_SAMPLES, "{samples}");
            let s = pipe.step(noisy(0.0, 0), true);
            assert!(pipe.diagnosing(), "{samples}: a new diagnosis is open");
            assert_eq!(s.monitor.samples_since_release, 0, "{samples}: sample 0 of a new release");
            assert_eq!(s.monitor.twin, fresh_first.monitor.twin, "{samples}: twin restarted from the applied state");
            assert_eq!(pipe.monitor().features().samples(), 1, "{samples}: features restarted");
            assert_eq!(s.monitor.estimates, fresh_first.monitor.estimates, "{samples}: estimator restarted");
            assert_eq!(pipe.monitor().status().estimator, EstimatorState::Converging, "{samples}");
            assert_eq!(s.monitor.sensor, None, "{samples}: the previous release's fault is forgotten");
            assert_eq!(pipe.monitor().sensor_fault(), None, "{samples}");
        }
    }

    #[test]
    fn a_chattering_valve_command_never_exceeds_the_report_rate() {
        let mut pipe = Pipeline::nominal().unwrap();
        let mut sent_at = Vec::new();
        for i in 0..3000u32 {
            let open = (i / 2) % 2 == 0; // 25 Hz chatter
            if fault_reports(pipe.step(noisy(0.2, i), open).frames.as_slice()) > 0 {
                sent_at.push(i);
            }
        }
        assert!(sent_at.len() > 100, "reports still go out: {}", sent_at.len());
        assert!(sent_at.windows(2).all(|w| w[1] - w[0] >= FAULT_MIN_GAP_SAMPLES), "{sent_at:?}");
    }

    /// A 60 s orifice-block release with noise, then the sensor freezes at `freeze_at`.
    fn release_then_freeze(freeze_at: u32) -> (Vec<Option<FaultReport>>, Pipeline) {
        let mut plant = Twin::new(&TwinParams::nominal().with_orifice_mm(0.6)).unwrap();
        let mut pipe = Pipeline::nominal().unwrap();
        let mut p = PressureQ24::ATMOSPHERE;
        let mut frozen = None;
        let mut sent = Vec::new();
        for i in 0..DIAGNOSIS_WINDOW_SAMPLES + 600 {
            let mut adc = noisy(p.to_bar_g().0, i);
            if i >= freeze_at {
                adc = *frozen.get_or_insert(adc);
            }
            let s = pipe.step(adc, true);
            for f in s.frames.as_slice() {
                if let Ok((Report::Fault(r), _)) = decode_frame(f) {
                    sent.push(Some(r));
                }
            }
            p = plant.update(true).pressure;
        }
        (sent, pipe)
    }

    #[test]
    fn a_verdict_closed_on_good_data_stands_one_closed_on_bad_data_is_withdrawn() {
        let class = |r: &FaultReport| matches!(r.verdict, Verdict::Class { class: FaultClass::OrificeBlock, .. });
        let frozen = Verdict::CannotDiagnose(NoDiagnosis::SensorFault(crate::sensor::SensorFault::Frozen));
        // Frozen 1 s after the close: the verdict stands; the status shows the fault.
        let (sent, pipe) = release_then_freeze(DIAGNOSIS_WINDOW_SAMPLES + 100);
        assert!(sent.iter().flatten().all(class), "{sent:?}");
        assert_eq!(pipe.monitor().status().sensor_fault, Some(crate::sensor::SensorFault::Frozen));
        // Frozen 0.3 s before the close (detected 0.2 s after it): withdrawn and sent again.
        let (sent, pipe) = release_then_freeze(DIAGNOSIS_WINDOW_SAMPLES - 30);
        assert!(class(sent[0].as_ref().unwrap()), "first sent at the close: {sent:?}");
        assert_eq!(sent.last().unwrap().unwrap().verdict, frozen);
        assert_eq!(pipe.report().unwrap().verdict, frozen);
        // Frozen 5 s before the close: never a class.
        let (sent, _) = release_then_freeze(DIAGNOSIS_WINDOW_SAMPLES - 500);
        assert!(sent.iter().flatten().all(|r| r.verdict == frozen), "{sent:?}");
    }
}
