//! `monitor`: the brake monitor as embassy tasks, a thin shell over the core's per-sample path
//! [`pbm::pipeline::Pipeline`] (the one `host-sim replay --can-log` runs too).
//!
//! ```text
//!  adc_task ──SAMPLES (4)──▶ monitor_task ──FRAMES (8)──▶ can_task ──▶ CAN (candump on QEMU)
//!  100 Hz ticker             Pipeline::step / close       embedded_can::blocking::Can
//!  ADC + valve command       (monitor, diagnosis, CAN schedule)
//!  watchdog_task: every 500 ms checks that the ADC and monitor tasks advanced, then feeds the
//!  watchdog; a stalled pipeline is not fed (a real IWDG then resets the controller).
//! ```
//!
//! Diagnosis (issue 7 item 2, policy in [`pbm::pipeline`]): the valve command is an input of
//! every sample; its rising edge opens a diagnosis; the command falling, the 60 s window or the
//! end of the ADC input ([`Pipeline::close`]) closes it, runs the int8 classifier once and
//! schedules the fault report frame.
//!
//! Full channels (both bounded, [`SAMPLE_QUEUE`] and [`FRAME_QUEUE`]):
//! - SAMPLES full: the monitor is more than 40 ms behind. The ADC task does not wait (the
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
//! On QEMU the ADC plays the trace compiled into flash (see `build.rs`, `PBM_FW_TRACE`) and the
//! valve command is on for every sample of it: a recorded trace is one release from the
//! command (SPEC §5), exactly as `host-sim replay` reads it. The end of the trace closes the
//! release; the run exits 0 when nothing was dropped or stalled. Standard output is exactly the
//! candump log; logs go to standard error. Nothing here links `core::fmt` (flash budget): logs
//! are built with [`Text`].
#![no_std]
#![no_main]

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use embassy_executor::Spawner;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Ticker};
use embedded_can::blocking::Can as _;
use pbm::can::{CanFrame, Identity};
use pbm::pipeline::Pipeline;
use pbm::report::{FaultReport, NoDiagnosis, Verdict};
use pbm::AdcCounts;
use pbm_firmware::adc::{
    PressureAdc, TraceAdc, TraceValve, ValveCommand, ADC_TRACE, ADC_TRACE_LOCOMOTIVE, ADC_TRACE_NAME,
};
use pbm_firmware::candump::CandumpCan;
use pbm_firmware::console::{exit, Text};
use pbm_firmware::{executor, stack, time_driver};

/// Depth of the ADC → monitor channel (samples).
const SAMPLE_QUEUE: usize = 4;
/// Depth of the monitor → CAN channel (frames; at most two per sample).
const FRAME_QUEUE: usize = 8;
/// Watchdog check period.
const WATCHDOG_PERIOD: Duration = Duration::from_millis(500);

enum AdcMessage {
    /// Sample `index` of the input, with the valve command at that sample.
    Sample { index: u32, adc: AdcCounts, valve_open: bool },
    /// The ADC source ended after `samples` samples: close the diagnosis.
    End { samples: u32 },
}

/// `FRAMES.send(message).await` (waits for room, loses nothing) without holding the message in
/// the task's state across the wait: that copy of a frame into embassy's send future is the
/// image's only `memmove` (1.5 KiB of flash). The message is built only once there is room.
async fn send_frame(message: impl Fn() -> TxMessage) {
    loop {
        core::future::poll_fn(|cx| FRAMES.poll_ready_to_send(cx)).await;
        // The monitor task is the only sender: once there is room, this succeeds.
        if FRAMES.try_send(message()).is_ok() {
            return;
        }
    }
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

/// Progress and error counters, written by the tasks and read by the watchdog.
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

#[cortex_m_rt::entry]
fn main() -> ! {
    stack::paint();
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        Text::new().str("monitor: core peripherals already taken").eprint();
        exit(false)
    };
    time_driver::init(peripherals.SYST);
    Text::new()
        .str("monitor: trace `")
        .str(ADC_TRACE_NAME)
        .str("`, ")
        .u32(ADC_TRACE.len() as u32)
        .str(" samples")
        .eprint();
    executor::run(move |spawner: Spawner| {
        let spawned = (|| -> Result<(), embassy_executor::SpawnError> {
            spawner.spawn(can_task(CandumpCan::new())?);
            spawner.spawn(monitor_task()?);
            spawner.spawn(watchdog_task()?);
            spawner.spawn(adc_task(TraceAdc::new(&ADC_TRACE), TraceValve)?);
            Ok(())
        })();
        if spawned.is_err() {
            Text::new().str("monitor: cannot spawn tasks").eprint();
            exit(false)
        }
    })
}

/// Samples the pressure and the valve command at 100 Hz.
#[embassy_executor::task]
async fn adc_task(mut adc: TraceAdc, mut valve: TraceValve) {
    let mut ticker = Ticker::every(Duration::from_millis(10));
    let mut index: u32 = 0;
    loop {
        ticker.next().await;
        match adc.read() {
            Ok(code) => {
                let valve_open = valve.release_requested();
                let msg = AdcMessage::Sample { index, adc: code, valve_open };
                if SAMPLES.try_send(msg).is_err() {
                    HEALTH.dropped_samples.fetch_add(1, Ordering::Relaxed);
                }
                index = index.wrapping_add(1);
                HEALTH.adc_samples.fetch_add(1, Ordering::Relaxed);
            }
            Err(_) => {
                Text::new().str("monitor: ADC source ended after ").u32(adc.played() as u32).str(" samples").eprint();
                HEALTH.adc_done.store(true, Ordering::Relaxed);
                // The end must not be lost: wait for room.
                SAMPLES.send(AdcMessage::End { samples: index }).await;
                return;
            }
        }
    }
}

/// Logs a closed diagnosis on standard error.
fn log_report(sample: u32, why: &str, r: &FaultReport) {
    let mut t = Text::new().str("monitor: diagnosis closed (").str(why).str(") at sample ").u32(sample).str(": ");
    t = match r.verdict {
        Verdict::Class { class, confidence_pct } => {
            t.str(class.label()).str(" (confidence ").u32(confidence_pct.into()).str(" %)")
        }
        Verdict::CannotDiagnose(NoDiagnosis::SensorFault(f)) => t.str("cannot diagnose: sensor ").str(f.label()),
        Verdict::CannotDiagnose(NoDiagnosis::TooShort) => t.str("cannot diagnose: release too short"),
        Verdict::CannotDiagnose(NoDiagnosis::Unfamiliar) => t.str("cannot diagnose: unfamiliar release"),
    };
    t.str(", supply ")
        .u32(r.supply_mbar.into())
        .str(" mbar, leak ")
        .u32(r.leak_um.into())
        .str(" um, completed ")
        .str(if r.release_completed { "yes" } else { "no" })
        .eprint();
}

/// Runs the core pipeline (monitor, diagnosis policy, CAN schedule) on every sample.
#[embassy_executor::task]
async fn monitor_task() {
    // Built here, in the task's own static storage, rather than in `main` and moved in: the
    // pipeline is about 2.4 KiB and every move of it is a stack copy.
    let Ok(mut pipeline) = Pipeline::nominal() else {
        Text::new().str("monitor: nominal parameters rejected").eprint();
        exit(false)
    };
    // The locomotive from configuration (QEMU: the trace's metadata); release number 0: QEMU
    // has no non-volatile memory to keep it across runs.
    pipeline.set_identity(Identity { locomotive: ADC_TRACE_LOCOMOTIVE, release: 0 });
    loop {
        match SAMPLES.receive().await {
            AdcMessage::Sample { index, adc, valve_open } => {
                let step = pipeline.step(adc, valve_open);
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

/// Sends frames on the bus.
#[embassy_executor::task]
async fn can_task(mut can: CandumpCan) {
    loop {
        match FRAMES.receive().await {
            TxMessage::Frame { sample, frame } => {
                can.set_sample_time(sample);
                if can.transmit(&frame).is_err() {
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
                Text::new()
                    .str("monitor: ")
                    .u32(load(&h.monitor_steps))
                    .str(" samples, ")
                    .u32(can.sent())
                    .str(" frames sent, ")
                    .u32(load(&h.diagnoses))
                    .str(" diagnoses, ")
                    .u32(load(&h.sensor_fault_samples))
                    .str(" sensor-fault samples, dropped ")
                    .u32(dropped_samples)
                    .str(" samples / ")
                    .u32(dropped_frames)
                    .str(" frames, ")
                    .u32(tx_errors)
                    .str(" tx errors, ")
                    .u32(load(&h.watchdog_feeds))
                    .str(" watchdog feeds, peak stack ")
                    .u32(stack::peak_used() as u32)
                    .str(" bytes")
                    .str(if stalled { ", STALLED" } else { "" })
                    .eprint();
                exit(dropped_samples == 0 && dropped_frames == 0 && tx_errors == 0 && !stalled)
            }
        }
    }
}

/// Feeds the watchdog only while the ADC and monitor tasks make progress.
#[embassy_executor::task]
async fn watchdog_task() {
    let mut ticker = Ticker::every(WATCHDOG_PERIOD);
    let (mut last_adc, mut last_monitor) = (0, 0);
    loop {
        ticker.next().await;
        let adc = HEALTH.adc_samples.load(Ordering::Relaxed);
        let monitor = HEALTH.monitor_steps.load(Ordering::Relaxed);
        let adc_alive = adc != last_adc || HEALTH.adc_done.load(Ordering::Relaxed);
        let monitor_alive = monitor != last_monitor || monitor == adc;
        if adc_alive && monitor_alive {
            // On a board: feed the independent watchdog (IWDG->KR = 0xAAAA).
            HEALTH.watchdog_feeds.fetch_add(1, Ordering::Relaxed);
        } else {
            HEALTH.stalled.store(true, Ordering::Relaxed);
            Text::new()
                .str("monitor: watchdog: pipeline stalled (adc ")
                .u32(adc)
                .str(", monitor ")
                .u32(monitor)
                .str("); not feeding")
                .eprint();
        }
        (last_adc, last_monitor) = (adc, monitor);
    }
}
