//! The monitor application, written once for every build: the QEMU `monitor` binary and the
//! board image (`board/`) run these loops, each in a thin `#[embassy_executor::task]` of its own
//! (embassy tasks cannot be generic), and differ only in the drivers they pass in.
//!
//! ```text
//!  sample_loop ──SAMPLES (4)──▶ monitor_loop ──FRAMES (8)──▶ transmit_loop ──▶ FrameSink
//!  SampleSource (100 Hz)        Pipeline::step / close        (candump on QEMU, bxCAN on the board)
//!  + ValveCommand               (monitor, diagnosis, CAN schedule)
//!  watchdog_loop: every 500 ms checks that the sample and monitor loops advanced, then feeds the
//!  Watchdog; a stalled pipeline is not fed (the board's IWDG then resets the controller).
//! ```
//!
//! Diagnosis (issue 7 item 2, policy in [`pbm::pipeline`]): the valve command is an input of
//! every sample; its rising edge opens a diagnosis; the command falling, the 60 s window or the
//! end of the ADC input ([`Pipeline::close`]) closes it, runs the int8 classifier once and
//! schedules the fault report frame.
//!
//! Full channels (both bounded, [`SAMPLE_QUEUE`] and [`FRAME_QUEUE`]):
//! - SAMPLES full: the monitor is more than 40 ms behind. The sample loop does not wait (the
//!   100 Hz timing is what the twin's clock assumes); it drops that sample and counts it in
//!   `dropped_samples`. The monitor's twin then runs one sample behind the plant; a non-zero
//!   count fails the QEMU run and is reported by the health log. The cost benchmark shows a
//!   sample takes a small fraction of its 10 ms budget, so this is a fault, not load.
//! - FRAMES full: the CAN controller cannot get frames out (bus off, no ACK). The monitor does
//!   not wait either; the frame is dropped and counted in `dropped_frames`. Status frames
//!   repeat every second and the fault report is repeated while the release runs, so the
//!   display catches up when the bus recovers.
//! - The end-of-input message and the frames of the closing diagnosis are the exception: they
//!   are sent with `send().await` (wait for room), because losing them would lose the verdict.
//!
//! Logs are defmt (format strings stay out of flash); the `monitor: …` texts are what
//! `cargo xtask fw-can-equality` and `fw-bench` read from the decoded log.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Ticker};
use pbm::can::CanFrame;
use pbm::pipeline::Pipeline;
use pbm::report::{FaultReport, NoDiagnosis, Verdict};
use pbm::AdcCounts;

use crate::adc::{SampleSource, ValveCommand};

/// Depth of the sample → monitor channel (samples).
pub const SAMPLE_QUEUE: usize = 4;
/// Depth of the monitor → CAN channel (frames; at most three per sample).
pub const FRAME_QUEUE: usize = 8;
/// Watchdog check period.
pub const WATCHDOG_PERIOD: Duration = Duration::from_millis(500);

/// Where the monitor's frames go: a CAN controller (the board) or the candump log (QEMU).
#[allow(async_fn_in_trait)] // single-threaded executor: no `Send` bound is wanted
pub trait FrameSink {
    /// Transmits `frame`, produced at sample `sample` (its time stamp where the sink writes
    /// one); false when it could not be sent.
    async fn send(&mut self, sample: u32, frame: &CanFrame) -> bool;
    /// Frames sent so far.
    fn sent(&self) -> u32;
}

/// The independent watchdog, fed only while the pipeline makes progress.
pub trait Watchdog {
    /// Restarts the watchdog's countdown.
    fn feed(&mut self);
}

/// A watchdog that only counts (QEMU has no IWDG; a stall fails the run instead).
#[derive(Debug, Default)]
pub struct CountingWatchdog;

impl Watchdog for CountingWatchdog {
    fn feed(&mut self) {}
}

/// A free-running cycle counter read around every `Pipeline::step` (the board's DWT CYCCNT),
/// or none ([`NoCycles`]: the QEMU build counts instructions in the `bench` binary instead).
pub trait CycleCounter {
    /// False: no counter, and the measuring code is compiled out.
    const ENABLED: bool;
    /// The counter now (wraps).
    fn now(&self) -> u32;
}

/// No cycle counter.
#[derive(Debug, Default, Clone, Copy)]
pub struct NoCycles;

impl CycleCounter for NoCycles {
    const ENABLED: bool = false;
    fn now(&self) -> u32 {
        0
    }
}

enum AdcMessage {
    /// Sample `index` of the input, with the valve command at that sample.
    Sample { index: u32, adc: AdcCounts, valve_open: bool },
    /// The ADC source ended after `samples` samples: close the diagnosis.
    End { samples: u32 },
}

enum TxMessage {
    /// A frame produced at sample `sample` (its time stamp).
    Frame {
        sample: u32,
        frame: CanFrame,
    },
    End,
}

static SAMPLES: Channel<CriticalSectionRawMutex, AdcMessage, SAMPLE_QUEUE> = Channel::new();
static FRAMES: Channel<CriticalSectionRawMutex, TxMessage, FRAME_QUEUE> = Channel::new();

/// Progress and error counters, written by the loops and read by the watchdog.
struct Health {
    adc_samples: AtomicU32,
    monitor_steps: AtomicU32,
    dropped_samples: AtomicU32,
    dropped_frames: AtomicU32,
    tx_errors: AtomicU32,
    sensor_fault_samples: AtomicU32,
    diagnoses: AtomicU32,
    watchdog_feeds: AtomicU32,
    stalled: AtomicBool,
    adc_done: AtomicBool,
}

static HEALTH: Health = Health {
    adc_samples: AtomicU32::new(0),
    monitor_steps: AtomicU32::new(0),
    dropped_samples: AtomicU32::new(0),
    dropped_frames: AtomicU32::new(0),
    tx_errors: AtomicU32::new(0),
    sensor_fault_samples: AtomicU32::new(0),
    diagnoses: AtomicU32::new(0),
    watchdog_feeds: AtomicU32::new(0),
    stalled: AtomicBool::new(false),
    adc_done: AtomicBool::new(false),
};

/// Counts a sample the ADC driver lost (a DMA overrun on the board): the twin then runs one
/// sample behind the plant, as for a full channel.
pub fn count_dropped_sample() {
    HEALTH.dropped_samples.fetch_add(1, Ordering::Relaxed);
}

/// `FRAMES.send(message).await` (waits for room, loses nothing) without holding the message in
/// the task's state across the wait: that copy of a frame into embassy's send future is the
/// image's only `memmove` (1.5 KiB of flash). The message is built only once there is room.
async fn send_frame(message: impl Fn() -> TxMessage) {
    loop {
        core::future::poll_fn(|cx| FRAMES.poll_ready_to_send(cx)).await;
        // The monitor loop is the only sender: once there is room, this succeeds.
        if FRAMES.try_send(message()).is_ok() {
            return;
        }
    }
}

/// Takes one sample per [`SampleSource::next`] with the valve command beside it and hands it to
/// the monitor; returns when the source ends (after telling the monitor).
pub async fn sample_loop(source: &mut impl SampleSource, valve: &mut impl ValveCommand) {
    let mut index: u32 = 0;
    loop {
        match source.next().await {
            Some(adc) => {
                let valve_open = valve.release_requested();
                if SAMPLES.try_send(AdcMessage::Sample { index, adc, valve_open }).is_err() {
                    HEALTH.dropped_samples.fetch_add(1, Ordering::Relaxed);
                }
                index = index.wrapping_add(1);
                HEALTH.adc_samples.fetch_add(1, Ordering::Relaxed);
            }
            None => {
                defmt::info!("monitor: ADC source ended after {=u32} samples", index);
                HEALTH.adc_done.store(true, Ordering::Relaxed);
                // The end must not be lost: wait for room.
                SAMPLES.send(AdcMessage::End { samples: index }).await;
                return;
            }
        }
    }
}

/// Logs a closed diagnosis.
fn log_report(sample: u32, why: &str, r: &FaultReport) {
    let (what, detail) = match r.verdict {
        Verdict::Class { class, .. } => (class.label(), ""),
        Verdict::CannotDiagnose(NoDiagnosis::SensorFault(f)) => ("cannot diagnose: sensor ", f.label()),
        Verdict::CannotDiagnose(NoDiagnosis::TooShort) => ("cannot diagnose: release too short", ""),
        Verdict::CannotDiagnose(NoDiagnosis::Unfamiliar) => ("cannot diagnose: unfamiliar release", ""),
    };
    let completed = if r.release_completed { "yes" } else { "no" };
    if let Verdict::Class { confidence_pct, .. } = r.verdict {
        defmt::info!(
            "monitor: diagnosis closed ({=str}) at sample {=u32}: {=str} (confidence {=u8} %), supply {=u16} mbar, leak {=u16} um, completed {=str}",
            why,
            sample,
            what,
            confidence_pct,
            r.supply_mbar,
            r.leak_um,
            completed
        );
    } else {
        defmt::info!(
            "monitor: diagnosis closed ({=str}) at sample {=u32}: {=str}{=str}, supply {=u16} mbar, leak {=u16} um, completed {=str}",
            why,
            sample,
            what,
            detail,
            r.supply_mbar,
            r.leak_um,
            completed
        );
    }
}

/// Per-sample cycle statistics over one second (100 samples), logged at `info`; every sample's
/// count at `trace` (build with `DEFMT_LOG=trace` to see them).
struct CycleStats {
    n: u32,
    total: u32,
    max: u32,
    max_at: u32,
}

impl CycleStats {
    fn add(&mut self, index: u32, cycles: u32) {
        defmt::trace!("sample {=u32}: {=u32} cycles", index, cycles);
        if cycles > self.max {
            (self.max, self.max_at) = (cycles, index);
        }
        self.total = self.total.saturating_add(cycles);
        self.n += 1;
        if self.n == 100 {
            defmt::info!(
                "cycles per sample (Pipeline::step, last 100 samples): mean {=u32}, max {=u32} at sample {=u32}; peak stack {=u32} B",
                self.total / self.n,
                self.max,
                self.max_at,
                crate::stack::peak_used() as u32
            );
            *self = Self { n: 0, total: 0, max: 0, max_at: 0 };
        }
    }
}

/// The twin's mechanisms of the extended image (a mechanism's feature, or `extensions`), chosen
/// at build time (`PBM_FW_MECHANISM`, checked by build.rs, which sets `pbm_mechanisms`).
#[cfg(pbm_mechanisms)]
pub mod mechanisms {
    include!(concat!(env!("OUT_DIR"), "/mechanisms.rs"));
}

/// The monitor's twin: the nominal brake, or (a mechanism's feature) the nominal brake with the
/// build-time mechanisms, from coefficients build.rs derived on the host.
pub const fn twin() -> pbm::Twin {
    #[cfg(pbm_mechanisms)]
    return pbm::Twin::from_coeffs(pbm::twin::TwinCoeffs::from_raw(mechanisms::TWIN_RAW));
    #[cfg(not(pbm_mechanisms))]
    pbm::Twin::nominal()
}

/// The monitor's pipeline: [`twin`] and the nominal estimator, from precomputed constants (no
/// `f64` set-up code in the image).
// Inlined: the ~2.4 KiB result is built in place, not copied through the stack.
#[inline(always)]
pub fn pipeline() -> Result<Pipeline, pbm::ParamError> {
    // The extended twin from flash: one copy of its ≈ 350 bytes, where building its
    // coefficients in place would take ≈ 400 more bytes of code than the nominal twin's.
    #[cfg(pbm_mechanisms)]
    static TWIN: pbm::Twin = twin();
    #[cfg(pbm_mechanisms)]
    return Pipeline::with_twin(TWIN);
    #[cfg(not(pbm_mechanisms))]
    Pipeline::nominal()
}

/// Runs the core pipeline (monitor, diagnosis policy, CAN schedule) on every sample; returns
/// after the end of the input (never on a board). `cycles` times each `Pipeline::step`;
/// `power_up` is the locomotive and the release count kept from before (the CAN frames carry
/// both).
pub async fn monitor_loop<C: CycleCounter>(cycles: C, power_up: pbm::can::PowerUp) {
    // Built here, in the task's own static storage, rather than in `main` and moved in: the
    // pipeline is about 2.4 KiB and every move of it is a stack copy.
    let Ok(mut pipeline) = pipeline() else {
        defmt::panic!("monitor: twin parameters rejected");
    };
    pipeline.set_identity(power_up);
    let mut stats = CycleStats { n: 0, total: 0, max: 0, max_at: 0 };
    loop {
        match SAMPLES.receive().await {
            AdcMessage::Sample { index, adc, valve_open } => {
                let start = cycles.now();
                let step = pipeline.step(adc, valve_open);
                if C::ENABLED {
                    stats.add(index, cycles.now().wrapping_sub(start));
                }
                if step.monitor.measured.is_err() {
                    HEALTH.sensor_fault_samples.fetch_add(1, Ordering::Relaxed);
                }
                if let Some(report) = &step.closed {
                    HEALTH.diagnoses.fetch_add(1, Ordering::Relaxed);
                    log_report(index, if valve_open { "timeout" } else { "valve closed" }, report);
                }
                for frame in step.frames.as_slice() {
                    if FRAMES.try_send(TxMessage::Frame { sample: index, frame: *frame }).is_err() {
                        HEALTH.dropped_frames.fetch_add(1, Ordering::Relaxed);
                    }
                }
                HEALTH.monitor_steps.fetch_add(1, Ordering::Relaxed);
            }
            AdcMessage::End { samples } => {
                // The last transmit tick is stamped with the last sample's time, as on the host.
                let last = samples.saturating_sub(1);
                if let Some((report, frames)) = pipeline.close() {
                    HEALTH.diagnoses.fetch_add(1, Ordering::Relaxed);
                    log_report(last, "end of input", &report);
                    for frame in frames.as_slice() {
                        send_frame(|| TxMessage::Frame { sample: last, frame: *frame }).await;
                    }
                }
                send_frame(|| TxMessage::End).await;
                return;
            }
        }
    }
}

/// Sends the monitor's frames; after the end of the input, logs the health counters (and the
/// peak stack, `peak_stack` bytes) and returns whether the run was clean: nothing dropped, no
/// transmit failed, no stall. Never returns on a board (its input never ends).
pub async fn transmit_loop(sink: &mut impl FrameSink, peak_stack: impl Fn() -> u32) -> bool {
    loop {
        match FRAMES.receive().await {
            TxMessage::Frame { sample, frame } => {
                if !sink.send(sample, &frame).await {
                    HEALTH.tx_errors.fetch_add(1, Ordering::Relaxed);
                }
            }
            TxMessage::End => {
                let h = &HEALTH;
                let load = |a: &AtomicU32| a.load(Ordering::Relaxed);
                let dropped_samples = load(&h.dropped_samples);
                let dropped_frames = load(&h.dropped_frames);
                let tx_errors = load(&h.tx_errors);
                let stalled = h.stalled.load(Ordering::Relaxed);
                defmt::info!(
                    "monitor: {=u32} samples, {=u32} frames sent, {=u32} diagnoses, {=u32} sensor-fault samples, dropped {=u32} samples / {=u32} frames, {=u32} tx errors, {=u32} watchdog feeds, peak stack {=u32} bytes{=str}",
                    load(&h.monitor_steps),
                    sink.sent(),
                    load(&h.diagnoses),
                    load(&h.sensor_fault_samples),
                    dropped_samples,
                    dropped_frames,
                    tx_errors,
                    load(&h.watchdog_feeds),
                    peak_stack(),
                    if stalled { ", STALLED" } else { "" }
                );
                return dropped_samples == 0 && dropped_frames == 0 && tx_errors == 0 && !stalled;
            }
        }
    }
}

/// Feeds `dog` every [`WATCHDOG_PERIOD`] only while the sample and monitor loops make progress;
/// a stalled pipeline is logged and the watchdog starves (on the board the IWDG then resets
/// the controller).
pub async fn watchdog_loop(dog: &mut impl Watchdog) {
    let mut ticker = Ticker::every(WATCHDOG_PERIOD);
    let (mut last_adc, mut last_monitor) = (0, 0);
    loop {
        ticker.next().await;
        let adc = HEALTH.adc_samples.load(Ordering::Relaxed);
        let monitor = HEALTH.monitor_steps.load(Ordering::Relaxed);
        let adc_alive = adc != last_adc || HEALTH.adc_done.load(Ordering::Relaxed);
        let monitor_alive = monitor != last_monitor || monitor == adc;
        if adc_alive && monitor_alive {
            dog.feed();
            HEALTH.watchdog_feeds.fetch_add(1, Ordering::Relaxed);
        } else {
            HEALTH.stalled.store(true, Ordering::Relaxed);
            defmt::error!(
                "monitor: watchdog: pipeline stalled (adc {=u32}, monitor {=u32}); not feeding",
                adc,
                monitor
            );
        }
        (last_adc, last_monitor) = (adc, monitor);
    }
}
