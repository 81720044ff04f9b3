//! `monitor`: the brake monitor as embassy tasks.
//!
//! ```text
//!  adc_task ──SAMPLES (4)──▶ monitor_task ──FRAMES (8)──▶ can_task ──▶ CAN (candump on QEMU)
//!  100 Hz ticker             Monitor::update              embedded_can::blocking::Can
//!                            + CanReporter::step
//!  watchdog_task: every 500 ms checks that the ADC and monitor tasks advanced, then feeds the
//!  watchdog; a stalled pipeline is not fed (a real IWDG then resets the controller).
//! ```
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
//!
//! On QEMU the ADC plays the trace compiled into flash (see `build.rs`, `PBM_FW_TRACE`), every
//! sample with the valve command on (one release, as `host-sim replay` takes a trace). The end of
//! the trace closes the release; the run exits 0 when nothing was dropped or stalled. Standard
//! output is exactly the candump log; logs go to standard error.
#![no_std]
#![no_main]

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use embassy_executor::Spawner;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Ticker};
use embedded_can::blocking::Can as _;
use pbm::can::CanFrame;
use pbm::AdcCounts;
use pbm_firmware::adc::{PressureAdc, TraceAdc, ADC_TRACE, ADC_TRACE_NAME};
use pbm_firmware::candump::CandumpCan;
use pbm_firmware::console::exit;
use pbm_firmware::pipeline::Pipeline;
use pbm_firmware::{eprintln, executor, stack, time_driver};

/// Depth of the ADC → monitor channel (samples).
const SAMPLE_QUEUE: usize = 4;
/// Depth of the monitor → CAN channel (frames; at most two per sample).
const FRAME_QUEUE: usize = 8;
/// Watchdog check period.
const WATCHDOG_PERIOD: Duration = Duration::from_millis(500);

enum AdcMessage {
    /// Sample `index` of the release.
    Sample { index: u32, adc: AdcCounts, valve_open: bool },
    /// The ADC source ended after `samples` samples: close the release.
    End { samples: u32 },
}

enum TxMessage {
    Frame { sample: u32, frame: CanFrame },
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
    watchdog_feeds: AtomicU32::new(0),
    stalled: AtomicBool::new(false),
    adc_done: AtomicBool::new(false),
};

#[cortex_m_rt::entry]
fn main() -> ! {
    stack::paint();
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        eprintln!("monitor: core peripherals already taken");
        exit(false)
    };
    time_driver::init(peripherals.SYST);
    let pipeline = match Pipeline::nominal() {
        Ok(p) => p,
        Err(e) => {
            eprintln!("monitor: nominal parameters rejected: {e}");
            exit(false)
        }
    };
    eprintln!("monitor: trace `{}`, {} samples", ADC_TRACE_NAME, ADC_TRACE.len());
    executor::run(move |spawner: Spawner| {
        let spawned = (|| -> Result<(), embassy_executor::SpawnError> {
            spawner.spawn(can_task(CandumpCan::new())?);
            spawner.spawn(monitor_task(pipeline)?);
            spawner.spawn(watchdog_task()?);
            spawner.spawn(adc_task(TraceAdc::new(&ADC_TRACE))?);
            Ok(())
        })();
        if let Err(e) = spawned {
            eprintln!("monitor: cannot spawn tasks: {e}");
            exit(false)
        }
    })
}

/// Samples the pressure at 100 Hz.
#[embassy_executor::task]
async fn adc_task(mut adc: TraceAdc) {
    let mut ticker = Ticker::every(Duration::from_millis(10));
    let mut index: u32 = 0;
    loop {
        ticker.next().await;
        match adc.read() {
            Ok(code) => {
                // On a board: valve_open = the valve-command input pin.
                let msg = AdcMessage::Sample { index, adc: code, valve_open: true };
                if SAMPLES.try_send(msg).is_err() {
                    HEALTH.dropped_samples.fetch_add(1, Ordering::Relaxed);
                }
                index = index.wrapping_add(1);
                HEALTH.adc_samples.fetch_add(1, Ordering::Relaxed);
            }
            Err(end) => {
                eprintln!("monitor: ADC source ended ({end:?}) after {} samples", adc.played());
                HEALTH.adc_done.store(true, Ordering::Relaxed);
                // The end must not be lost: wait for room.
                SAMPLES.send(AdcMessage::End { samples: index }).await;
                return;
            }
        }
    }
}

/// Runs the core monitor and the CAN schedule on every sample.
#[embassy_executor::task]
async fn monitor_task(mut pipeline: Pipeline) {
    loop {
        match SAMPLES.receive().await {
            AdcMessage::Sample { index, adc, valve_open } => {
                let (step, outbox) = pipeline.step(adc, valve_open);
                if step.measured.is_err() {
                    HEALTH.sensor_fault_samples.fetch_add(1, Ordering::Relaxed);
                }
                for frame in outbox.as_slice() {
                    if FRAMES.try_send(TxMessage::Frame { sample: index, frame: *frame }).is_err() {
                        HEALTH.dropped_frames.fetch_add(1, Ordering::Relaxed);
                    }
                }
                HEALTH.monitor_steps.fetch_add(1, Ordering::Relaxed);
            }
            AdcMessage::End { samples } => {
                let est = pipeline.monitor().estimator().estimates();
                eprintln!(
                    "monitor: release closed after {samples} samples; estimator {:?}, supply {} mbar, leak {} um",
                    est.phase,
                    est.supply_mbar(),
                    est.leak_um()
                );
                FRAMES.send(TxMessage::End).await;
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
                let dropped_samples = h.dropped_samples.load(Ordering::Relaxed);
                let dropped_frames = h.dropped_frames.load(Ordering::Relaxed);
                let tx_errors = h.tx_errors.load(Ordering::Relaxed);
                let stalled = h.stalled.load(Ordering::Relaxed);
                eprintln!(
                    "monitor: {} samples, {} frames sent, {} sensor-fault samples, dropped {} samples / {} frames, \
                     {} tx errors, {} watchdog feeds, peak stack {} bytes{}",
                    h.monitor_steps.load(Ordering::Relaxed),
                    can.sent(),
                    h.sensor_fault_samples.load(Ordering::Relaxed),
                    dropped_samples,
                    dropped_frames,
                    tx_errors,
                    h.watchdog_feeds.load(Ordering::Relaxed),
                    stack::peak_used(),
                    if stalled { ", STALLED" } else { "" }
                );
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
            eprintln!("monitor: watchdog: pipeline stalled (adc {adc}, monitor {monitor}); not feeding");
        }
        (last_adc, last_monitor) = (adc, monitor);
    }
}
