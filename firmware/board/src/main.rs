//! The brake monitor on a NUCLEO-F446RE (STM32F446RE, Cortex-M4F at 180 MHz, bxCAN).
//!
//! The application is the QEMU image's: [`pbm_firmware::app`] runs the same sample, monitor,
//! transmit and watchdog loops around the same `pbm::pipeline::Pipeline` and sends the same
//! frames. Only the drivers differ (`drivers.rs`):
//!
//! | QEMU (`firmware/src/bin/monitor.rs`) | this board |
//! |---|---|
//! | trace in flash, read on an embassy-time ticker | ADC1 on PA0, converted on TIM3's 100 Hz update (TRGO), DMA2 stream 0 into a ring buffer; ratiometric to the transducer supply on PA1 |
//! | valve command on for the whole trace | release command on PA10 (Arduino D2), EXTI edges, 20 ms debounce |
//! | candump lines on semihosting stdout | bxCAN1 on PB8/PB9 (D15/D14), `PBM_CAN_BITRATE` (default 250 kbit/s), every acceptance filter closed |
//! | watchdog counter | IWDG (1.5 s), fed only while the loops advance |
//! | SysTick time driver | embassy-stm32's TIM2 time driver |
//! | defmt over semihosting | defmt over RTT (probe-rs), panic-probe |
//! | instructions per sample from `bench` | DWT cycles per `Pipeline::step`, logged every second |
//!
//! Start-up: the clocks (HSE 8 MHz from the ST-LINK, PLL to 180 MHz), then the analog check —
//! VDDA from VREFINT against its factory calibration, and the transducer supply through its
//! divider — repeated every second until both are in range; only then do the loops start, and
//! the IWDG with them. A controller whose analog front end is out of range sends no frames,
//! which the cab display sees as a silent monitor.
#![no_std]
#![no_main]

mod drivers;

use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_stm32::time::Hertz;
use embassy_stm32::Config;
use panic_probe as _;
use pbm_firmware::app;
use pbm_firmware::{executor, stack};

use drivers::{BoardParts, BxCan, DwtCycles, Iwdg, TriggeredAdc};

/// Clocks: HSE 8 MHz (the ST-LINK's MCO, bypass) → PLL 180 MHz SYSCLK; APB1 45 MHz (bxCAN;
/// timers 90 MHz: TIM2 time driver, TIM3 ADC trigger); APB2 90 MHz (ADC clock 22.5 MHz).
fn clock_config() -> Config {
    use embassy_stm32::rcc::{
        AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPDiv, PllPreDiv, PllSource, Sysclk,
    };
    let mut config = Config::default();
    config.rcc.hse = Some(Hse { freq: Hertz(8_000_000), mode: HseMode::Bypass });
    config.rcc.pll_src = PllSource::HSE;
    config.rcc.pll =
        Some(Pll { prediv: PllPreDiv::DIV4, mul: PllMul::MUL180, divp: Some(PllPDiv::DIV2), divq: None, divr: None });
    config.rcc.ahb_pre = AHBPrescaler::DIV1;
    config.rcc.apb1_pre = APBPrescaler::DIV4;
    config.rcc.apb2_pre = APBPrescaler::DIV2;
    config.rcc.sys = Sysclk::PLL1_P;
    config
}

/// `defmt::panic!` (and embassy-stm32's checks, which use it) has logged its message: stop the
/// core the way panic-probe does, so that probe-rs prints the backtrace and exits non-zero.
/// Other panics go to panic-probe directly (location in the backtrace; panic-probe is built
/// without `print-defmt`, whose message formatting would link ≈ 9 KiB of `core::fmt`).
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    panic_probe::hard_fault()
}

#[cortex_m_rt::entry]
fn main() -> ! {
    stack::paint();
    let p = embassy_stm32::init(clock_config());
    let Some(mut core) = cortex_m::Peripherals::take() else {
        defmt::panic!("core peripherals already taken");
    };
    let cycles = DwtCycles::enable(&mut core.DCB, &mut core.DWT);
    defmt::info!(
        "pbm-board: NUCLEO-F446RE, CAN {=u32} bit/s, monitor starts after the analog check",
        drivers::CAN_BITRATE
    );
    executor::run(move |spawner: Spawner| match start_task(spawner, BoardParts::new(p), cycles) {
        Ok(token) => spawner.spawn(token),
        Err(_) => defmt::panic!("cannot spawn the start task"),
    })
}

/// Checks the analog front end, then starts the drivers and the application's loops.
#[embassy_executor::task]
async fn start_task(spawner: Spawner, parts: BoardParts, cycles: DwtCycles) {
    let running = parts.start().await;
    let spawned = (|| -> Result<(), embassy_executor::SpawnError> {
        spawner.spawn(valve_task(running.valve_input)?);
        spawner.spawn(can_task(running.can)?);
        spawner.spawn(monitor_task(cycles)?);
        spawner.spawn(watchdog_task(running.watchdog)?);
        spawner.spawn(adc_task(running.adc)?);
        Ok(())
    })();
    if spawned.is_err() {
        // Five tasks, five pools of one: only a programming error gets here. The IWDG (already
        // running) resets the controller.
        defmt::panic!("cannot spawn the monitor tasks");
    }
    defmt::info!("pbm-board: monitor running (100 Hz, TIM3-triggered ADC)");
}

/// The 100 Hz samples: hardware-timed conversions, DMA, the debounced release command.
#[embassy_executor::task]
async fn adc_task(mut adc: TriggeredAdc) {
    app::sample_loop(&mut adc, &mut drivers::DebouncedValve).await;
    // A board's ADC never ends; if it ever did, the watchdog sees no progress and resets.
    defmt::error!("pbm-board: ADC source ended");
}

/// Debounces the release-command input from its EXTI edges.
#[embassy_executor::task]
async fn valve_task(input: embassy_stm32::exti::ExtiInput<'static, embassy_stm32::mode::Async>) {
    drivers::debounce_valve(input).await;
}

/// Runs the core pipeline on every sample and reports its cycle counts.
#[embassy_executor::task]
async fn monitor_task(cycles: DwtCycles) {
    app::monitor_loop(cycles, pbm::can::PowerUp { locomotive: LOCOMOTIVE, release_count: 0 }).await;
}

/// The locomotive's fleet number (0–4095; the session frame carries all 12 bits, every frame
/// the low 6): `PBM_LOCOMOTIVE` at build time, 0 without it. The release count starts at 0 on every power-up: this image keeps no non-volatile
/// counter yet, so every power-up after the first repeats the release count (and release
/// number) of the one before, which a display that heard it refuses as an old recording
/// (`can/README.md`). A controller in service must keep the count across power cycles.
const LOCOMOTIVE: u16 = match option_env!("PBM_LOCOMOTIVE") {
    Some(text) => parse_locomotive(text.as_bytes()),
    None => 0,
};

/// `text` as a decimal 0–4095 (a build error otherwise).
const fn parse_locomotive(text: &[u8]) -> u16 {
    let mut value: u32 = 0;
    let mut i = 0;
    while i < text.len() {
        let d = text[i];
        assert!(d.is_ascii_digit(), "PBM_LOCOMOTIVE must be a decimal number 0-4095");
        value = value * 10 + (d - b'0') as u32;
        assert!(value <= 4095, "PBM_LOCOMOTIVE must be 0-4095");
        i += 1;
    }
    value as u16
}

/// Sends the monitor's frames on bxCAN1.
#[embassy_executor::task]
async fn can_task(mut can: BxCan) {
    app::transmit_loop(&mut can, || stack::peak_used() as u32).await;
}

/// Feeds the IWDG while the pipeline advances.
#[embassy_executor::task]
async fn watchdog_task(mut dog: Iwdg) {
    app::watchdog_loop(&mut dog).await;
}
