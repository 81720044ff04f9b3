//! The whole per-sample path of the brake controller in one place: ADC reading and valve
//! command in, CAN frames out. The firmware's monitor task and `host-sim replay --can-log` both
//! drive this type, so the two cannot drift apart: same monitor, same features, same diagnosis
//! policy, same transmit schedule, same counters, same bytes (and [`crate::can::candump`]
//! writes the same log lines).
//!
//! Per sample ([`Pipeline::step`]): [`Monitor::update`] (twin, residual, plausibility checks,
//! online estimator), the release features of the classifier ([`ReleaseFeatures`], release
//! samples only: after the command ends the last release stays diagnosable), the diagnosis
//! policy below, then the core's CAN transmit schedule ([`CanReporter::step`]: status at 1 Hz,
//! the fault report when it appears or changes and repeated at 1 Hz while the valve command is
//! on).
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
//! - The verdict ([`Pipeline::diagnosis`]): *cannot diagnose: sensor fault* when the
//!   plausibility checks latched one since the command; *cannot diagnose: unfamiliar* when the
//!   release did not start from a vented chamber (the twin's starting point); otherwise the
//!   classifier's verdict on the features ([`classifier::diagnose`]), a class only if it agrees
//!   with the parameters the online estimator measured ([`classifier::consistent`]), else
//!   *unfamiliar*. The report ([`fault_report`]) adds the time since the command and the
//!   estimated supply and leak.
//! - The closed report is then scheduled as it stands until the next release command, with
//!   one exception:
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
use crate::classifier;
use crate::estimator::Phase;
use crate::features::{ReleaseFeatures, ReleaseSample};
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

/// Monitor, release features, diagnosis policy and CAN schedule.
#[derive(Debug, Clone)]
pub struct Pipeline {
    monitor: Monitor,
    /// Online features of the current (or last) release, for the classifier.
    features: ReleaseFeatures,
    reporter: CanReporter,
    valve_was_open: bool,
    /// A diagnosis is open (release command seen, not yet closed).
    diagnosing: bool,
    /// The report of the last closed diagnosis, scheduled for transmission.
    report: Option<FaultReport>,
    /// Samples since the release command at which the last diagnosis was closed.
    closed_at: u32,
}

impl From<&MonitorStep> for ReleaseSample {
    /// What the release features read of a monitor step.
    #[inline(always)]
    fn from(step: &MonitorStep) -> Self {
        Self {
            samples_since_release: step.samples_since_release,
            measured: step.measured,
            residual_q24: step.residual_q24,
            estimates: step.estimates,
        }
    }
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
            features: ReleaseFeatures::new(),
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

    /// The pipeline with the nominal estimator and another twin ([`Monitor::with_twin`]): the
    /// firmware's extended twin from build-time coefficients.
    // Inlined: the ~2.4 KiB result is built in place, not copied through the stack.
    #[inline(always)]
    pub fn with_twin(twin: crate::Twin) -> Result<Self, ParamError> {
        Ok(Self::with_monitor(Monitor::with_twin(twin)?))
    }

    /// Power-up identity for the CAN frames: the locomotive's number and the release count
    /// kept from before this start (a controller keeps it across power cycles; this power-up
    /// and every release command count one more, [`CanReporter::set_identity`]). Call before
    /// the first sample.
    pub fn set_identity(&mut self, power_up: crate::can::PowerUp) {
        self.reporter.set_identity(power_up);
    }

    /// What the fault reports are sealed with now: the fleet number and the release count their
    /// CRC binds (layout 3.2, [`crate::can::Binding`]); a stateless decode of this pipeline's
    /// frames needs it.
    pub fn binding(&self) -> crate::can::Binding {
        self.reporter.binding()
    }

    /// One 100 Hz sample: monitor, release features, diagnosis policy, transmit schedule.
    pub fn step(&mut self, adc: AdcCounts, valve_open: bool) -> PipelineStep {
        let monitor = self.monitor.update(adc, valve_open);
        if valve_open {
            // Only release samples: after the valve closes the last release stays diagnosable.
            // Sample 0 (the command) restarts the features.
            self.features.update(&ReleaseSample::from(&monitor));
        }
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
            // One more transmit tick within the last sample: the report if the schedule allows.
            Some((report, self.reporter.close_tick(&report)))
        } else {
            None
        };
        self.valve_was_open = false;
        self.monitor.end_release();
        closed
    }

    /// The fault report of the current (or last) release by the policy of the module docs: a
    /// class, or 'cannot diagnose' (a sensor fault found by the range or plausibility checks,
    /// too short, unfamiliar release). Valid at any time since the release command (early
    /// diagnosis); the pipeline closes it at the end of the release or at the timeout.
    pub fn diagnosis(&self) -> FaultReport {
        let verdict = match self.monitor.sensor_fault() {
            Some(d) => Verdict::CannotDiagnose(NoDiagnosis::SensorFault(d.fault)),
            // The twin starts every release from a vented chamber; this one did not.
            None if self.monitor.unvented_start() => Verdict::CannotDiagnose(NoDiagnosis::Unfamiliar),
            None => match classifier::diagnose(&self.features) {
                // The class must agree with the parameters the estimator measured.
                Verdict::Class { class, .. }
                    if !classifier::consistent(class, &self.monitor.estimator().estimates()) =>
                {
                    Verdict::CannotDiagnose(NoDiagnosis::Unfamiliar)
                }
                v => v,
            },
        };
        fault_report(&self.monitor, verdict)
    }

    fn close_diagnosis(&mut self) -> FaultReport {
        let report = self.diagnosis();
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

    /// The monitor (status, estimator, plausibility checks).
    pub fn monitor(&self) -> &Monitor {
        &self.monitor
    }

    /// Online features of the current (or last) release.
    pub fn features(&self) -> &ReleaseFeatures {
        &self.features
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

/// A fault report for `verdict` with what the monitor knows of the current (or last) release:
/// the time since the release command and the estimated supply and leak.
/// `release_completed`: the estimator has seen the final plateau.
pub fn fault_report(monitor: &Monitor, verdict: Verdict) -> FaultReport {
    let est = monitor.estimator().estimates();
    FaultReport {
        verdict,
        time_since_release_cs: monitor.samples_in_release().min(u32::from(u16::MAX)) as u16,
        supply_mbar: est.supply_mbar(),
        leak_um: est.leak_um(),
        release_completed: est.phase == Phase::Plateau,
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::can::reporter::FAULT_MIN_GAP_SAMPLES;
    use crate::can::{decode_frame, Binding, Report};
    use crate::report::{NoDiagnosis, Verdict};
    use crate::sensor::{adc_from_bar, SensorFault};
    use crate::units::{BarG, PressureQ24};
    use crate::{FaultClass, Twin};
    use std::vec::Vec;

    /// Decodes a frame of locomotive 0 in any release (the tests' pipelines count releases).
    fn decode_any(f: &crate::can::CanFrame) -> Option<Report> {
        (0..64u32).find_map(|release_count| decode_frame(f, Binding { fleet: 0, release_count }).ok().map(|(r, _)| r))
    }

    /// Fault report frames among `frames` (by identifier: a chattering valve command counts
    /// more than 64 releases, beyond what [`decode_any`] tries).
    fn fault_reports(frames: &[crate::can::CanFrame]) -> usize {
        frames.iter().filter(|f| crate::can::MessageKind::of(*f) == Ok(crate::can::MessageKind::Fault)).count()
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
            assert_eq!(pipe.features().samples(), 1, "{samples}: features restarted");
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
                if let Some(Report::Fault(r)) = decode_any(f) {
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
        let frozen = Verdict::CannotDiagnose(NoDiagnosis::SensorFault(SensorFault::Frozen));
        // Frozen 1 s after the close: the verdict stands; the status shows the fault.
        let (sent, pipe) = release_then_freeze(DIAGNOSIS_WINDOW_SAMPLES + 100);
        assert!(sent.iter().flatten().all(class), "{sent:?}");
        assert_eq!(pipe.monitor().status().sensor_fault, Some(SensorFault::Frozen));
        // Frozen 0.3 s before the close (detected 0.2 s after it): withdrawn and sent again.
        let (sent, pipe) = release_then_freeze(DIAGNOSIS_WINDOW_SAMPLES - 30);
        assert!(class(sent[0].as_ref().unwrap()), "first sent at the close: {sent:?}");
        assert_eq!(sent.last().unwrap().unwrap().verdict, frozen);
        assert_eq!(pipe.report().unwrap().verdict, frozen);
        // Frozen 5 s before the close: never a class.
        let (sent, _) = release_then_freeze(DIAGNOSIS_WINDOW_SAMPLES - 500);
        assert!(sent.iter().flatten().all(|r| r.verdict == frozen), "{sent:?}");
    }

    // Release features computed through the monitor (`crate::features`), and the classifier's
    // verdict rules on them (`crate::classifier::diagnose_with`): the layers the pipeline joins.

    #[test]
    fn nominal_release_through_the_monitor() {
        use crate::features::{FeatureExtractor, N_OURS, N_PHYSICS, OURS_NAMES};
        let params = TwinParams::nominal();
        let mut plant = Twin::new(&params).unwrap();
        let mut monitor = Monitor::new(&params).unwrap();
        let mut fx = FeatureExtractor::new();
        let mut p = plant.state().p.0;
        for _ in 0..6000 {
            let step = monitor.update(adc_from_bar(PressureQ24(p).to_bar_g()), true);
            fx.update(&ReleaseSample::from(&step));
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
        use crate::features::FeatureExtractor;
        let mut monitor = Monitor::new(&TwinParams::nominal()).unwrap();
        let mut fx = FeatureExtractor::new();
        for i in 0..100 {
            let adc = if i >= 90 { AdcCounts(0) } else { adc_from_bar(BarG(0.01 * f64::from(i))) };
            fx.update(&ReleaseSample::from(&monitor.update(adc, true)));
        }
        assert_eq!(fx.faulty_samples(), 10);
        assert_eq!(fx.last_fault(), Some(SensorFault::OpenCircuit));
        assert!((fx.raw_stats()[0] - 0.445).abs() < 0.003, "mean of the 90 valid samples");
        // A new release command resets everything.
        monitor.update(adc_from_bar(BarG(0.0)), false);
        fx.update(&ReleaseSample::from(&monitor.update(adc_from_bar(BarG(0.0)), true)));
        assert_eq!((fx.samples(), fx.faulty_samples()), (1, 0));
    }

    /// The release features of `samples` ADC codes through a monitor of the nominal brake.
    fn release(adc: impl Fn(u32) -> AdcCounts, samples: u32) -> ReleaseFeatures {
        let mut m = Monitor::new(&TwinParams::nominal()).unwrap();
        let mut fx = ReleaseFeatures::new();
        for i in 0..samples {
            fx.update(&ReleaseSample::from(&m.update(adc(i), true)));
        }
        fx
    }

    #[test]
    fn cannot_diagnose_sensor_faults_short_releases_and_implausible_features() {
        let fx = release(|_| AdcCounts(0), 3000);
        assert_eq!(
            classifier::diagnose(&fx),
            Verdict::CannotDiagnose(NoDiagnosis::SensorFault(SensorFault::OpenCircuit))
        );
        // 5 % of the samples shorted, the latest valid: still no diagnosis.
        let fx =
            release(|i| if i % 20 == 0 { AdcCounts(4095) } else { adc_from_bar(BarG(0.001 * f64::from(i))) }, 3001);
        assert_eq!(
            classifier::diagnose(&fx),
            Verdict::CannotDiagnose(NoDiagnosis::SensorFault(SensorFault::ShortCircuit))
        );
        let fx = release(|_| adc_from_bar(BarG(0.0)), 50);
        assert_eq!(classifier::diagnose(&fx), Verdict::CannotDiagnose(NoDiagnosis::TooShort));
        // A release whose plateau sags by 0.3 bar over 4 s (a supply that hunts or is cut):
        // with the valve open and a steady supply the pressure never falls, so no class
        // describes it.
        let ramp = |i: u32| (0.004 * f64::from(i)).min(7.7);
        let sag = |i: u32| {
            let phase = (f64::from(i) - 3000.0) / 400.0;
            if (0.0..1.0).contains(&phase) {
                ramp(i) - 0.3 * libm::sin(core::f64::consts::PI * phase)
            } else {
                ramp(i)
            }
        };
        let noise = |i: u32| if i % 2 == 0 { 0.01 } else { -0.01 };
        let fx = release(|i| adc_from_bar(BarG(sag(i) + noise(i))), 4000);
        assert!(fx.phase().max_drop() > 0.25, "{}", fx.phase().max_drop());
        assert_eq!(classifier::diagnose(&fx), Verdict::CannotDiagnose(NoDiagnosis::Unfamiliar));
        let fx = release(|i| adc_from_bar(BarG(ramp(i) + noise(i))), 4000);
        assert!(fx.phase().max_drop() < 0.02, "{}", fx.phase().max_drop());
        let speed_up = crate::features::fill_speed_up(&fx.ours());
        assert!(speed_up.is_some_and(|r| (0.95..1.05).contains(&r)), "{speed_up:?}");
        // A fill that speeds up: 0.4 bar/s to 1 bar, then 0.8 bar/s (a supply still rising).
        let rising = |i: u32| {
            let t = f64::from(i) / 100.0;
            if t < 2.5 {
                0.4 * t
            } else {
                (1.0 + 0.8 * (t - 2.5)).min(7.7)
            }
        };
        let fx = release(|i| adc_from_bar(BarG(rising(i) + noise(i))), 4000);
        let speed_up = crate::features::fill_speed_up(&fx.ours());
        assert!(speed_up.is_some_and(|r| r > 1.8), "{speed_up:?}");
        assert_eq!(classifier::diagnose(&fx), Verdict::CannotDiagnose(NoDiagnosis::Unfamiliar));
        // A chamber that jumps to 9 bar and stays there is no brake of the training set.
        let fx = release(|_| adc_from_bar(BarG(9.0)), 6000);
        assert_eq!(classifier::diagnose(&fx), Verdict::CannotDiagnose(NoDiagnosis::Unfamiliar));
    }

    #[test]
    fn fault_report_carries_the_estimates() {
        let mut plant = Twin::new(&TwinParams::nominal().with_leak_mm(0.8)).unwrap();
        let mut m = Monitor::new(&TwinParams::nominal()).unwrap();
        let mut p = PressureQ24::ATMOSPHERE;
        let mut step = m.update(adc_from_bar(p.to_bar_g()), true);
        for _ in 0..5999 {
            p = plant.update(true).pressure;
            step = m.update(adc_from_bar(p.to_bar_g()), true);
        }
        let e = step.estimates;
        let too_short = Verdict::CannotDiagnose(NoDiagnosis::TooShort);
        let r = fault_report(&m, too_short);
        assert_eq!(r.verdict, too_short);
        assert_eq!(r.supply_mbar, e.supply_mbar());
        assert_eq!(r.leak_um, e.leak_um());
        assert!(r.leak_um > 750 && r.leak_um < 850 && r.supply_mbar > 7500, "{r:?}");
        assert!(r.release_completed);
        assert_eq!(r.time_since_release_cs, 6000);
        // Valve closed: estimates kept for the report.
        m.update(adc_from_bar(p.to_bar_g()), false);
        assert_eq!(fault_report(&m, too_short).leak_um, r.leak_um);
    }
}
