//! `monitor`: the brake monitor in QEMU. The application is [`pbm_firmware::app`] (the same
//! loops the board image runs); this binary only picks the QEMU drivers:
//!
//! - samples: the trace compiled into flash (`build.rs`, `PBM_FW_TRACE`) read on a 100 Hz
//!   embassy-time ticker, with the valve command on for every sample: a recorded trace is one
//!   release from the command (SPEC §5), exactly as `host-sim replay` reads it;
//! - CAN: [`CandumpCan`], candump lines on semihosting standard output, stamped with the sample
//!   clock;
//! - watchdog: a counter (a stall fails the run instead of resetting it).
//!
//! The end of the trace closes the release; the run exits 0 when nothing was dropped or
//! stalled. Standard output is exactly the candump log; the defmt log goes to standard error
//! (decoded by the runner, `firmware/qemu-run.sh`).
#![no_std]
#![no_main]

use embassy_executor::Spawner;
use embedded_can::blocking::Can as _;
use pbm::can::{CanFrame, PowerUp};
use pbm_firmware::adc::{Paced, TraceAdc, TraceValve, ADC_TRACE, ADC_TRACE_LOCOMOTIVE, ADC_TRACE_NAME};
use pbm_firmware::app::{self, CountingWatchdog, FrameSink, NoCycles};
use pbm_firmware::candump::CandumpCan;
use pbm_firmware::console::exit;
use pbm_firmware::{executor, stack, time_driver};

/// The candump "driver" as the application's frame sink: the sample index is the time stamp.
struct Candump(CandumpCan);

impl FrameSink for Candump {
    async fn send(&mut self, sample: u32, frame: &CanFrame) -> bool {
        self.0.set_sample_time(sample);
        self.0.transmit(frame).is_ok()
    }

    fn sent(&self) -> u32 {
        self.0.sent()
    }
}

#[cortex_m_rt::entry]
fn main() -> ! {
    stack::paint();
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        defmt::error!("monitor: core peripherals already taken");
        exit(false)
    };
    time_driver::init(peripherals.SYST);
    defmt::info!("monitor: trace `{=str}`, {=usize} samples", ADC_TRACE_NAME, ADC_TRACE.len());
    executor::run(move |spawner: Spawner| {
        let spawned = (|| -> Result<(), embassy_executor::SpawnError> {
            spawner.spawn(can_task()?);
            spawner.spawn(monitor_task()?);
            spawner.spawn(watchdog_task()?);
            spawner.spawn(adc_task()?);
            Ok(())
        })();
        if spawned.is_err() {
            defmt::error!("monitor: cannot spawn tasks");
            exit(false)
        }
    })
}

/// Samples the recorded trace at 100 Hz.
#[embassy_executor::task]
async fn adc_task() {
    app::sample_loop(&mut Paced::new(TraceAdc::new(&ADC_TRACE)), &mut TraceValve).await;
}

/// Runs the core pipeline on every sample.
#[embassy_executor::task]
async fn monitor_task() {
    // The locomotive from configuration (QEMU: the trace's metadata); release count 0: QEMU
    // has no non-volatile memory to keep it across runs.
    app::monitor_loop(NoCycles, PowerUp { locomotive: ADC_TRACE_LOCOMOTIVE, release_count: 0 }).await;
}

/// Writes the frames as candump lines; ends the run after the end of the trace.
#[embassy_executor::task]
async fn can_task() {
    let clean = app::transmit_loop(&mut Candump(CandumpCan::new()), || stack::peak_used() as u32).await;
    exit(clean)
}

/// Checks the pipeline's progress every 500 ms.
#[embassy_executor::task]
async fn watchdog_task() {
    app::watchdog_loop(&mut CountingWatchdog).await;
}
