//! The NUCLEO-F446RE's drivers behind the application's traits (`pbm_firmware::app`,
//! `pbm_firmware::adc`): what the board build has and the QEMU build does not.
//!
//! Pins (Nucleo-64 Arduino header names in brackets; wiring in firmware/README.md):
//!
//! | signal | pin | peripheral |
//! |---|---|---|
//! | chamber pressure, divided 0.6 × | PA0 [A0] | ADC1_IN0 |
//! | transducer supply, divided 0.6 × | PA1 [A1] | ADC1_IN1 |
//! | release command (opto-isolated, active low) | PA10 [D2] | EXTI10 |
//! | CAN RX / TX to the transceiver | PB8 [D15] / PB9 [D14] | CAN1 (AF9) |

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_futures::select::{select, Either};
use embassy_stm32::adc::{Adc, AdcChannel, Exten, RingBufferedAdc, SampleTime};
use embassy_stm32::can::filter::MasterFilters;
use embassy_stm32::can::{
    Can, Frame, Rx0InterruptHandler, Rx1InterruptHandler, SceInterruptHandler, TxInterruptHandler,
};
use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::gpio::Pull;
use embassy_stm32::peripherals::{self, ADC1, CAN1};
use embassy_stm32::timer::low_level::{MasterMode, Timer};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{bind_interrupts, dma, interrupt, Peri, Peripherals};
use embassy_time::Timer as Delay;
use embedded_can::Frame as _;
use pbm::can::CanFrame;
use pbm::AdcCounts;
use pbm_firmware::adc::{SampleSource, ValveCommand};
use pbm_firmware::app::{self, CycleCounter, FrameSink, Watchdog};

bind_interrupts!(struct Irqs {
    DMA2_STREAM0 => dma::InterruptHandler<peripherals::DMA2_CH0>;
    CAN1_RX0 => Rx0InterruptHandler<CAN1>;
    CAN1_RX1 => Rx1InterruptHandler<CAN1>;
    CAN1_SCE => SceInterruptHandler<CAN1>;
    CAN1_TX => TxInterruptHandler<CAN1>;
    EXTI15_10 => exti::InterruptHandler<interrupt::typelevel::EXTI15_10>;
});

/// CAN bit rate, bit/s (`PBM_CAN_BITRATE` at build time, checked by build.rs; default 250 k).
pub const CAN_BITRATE: u32 = parse_u32(env!("PBM_CAN_BITRATE"));

/// Decimal digits to a number at compile time (the build script wrote them).
const fn parse_u32(s: &str) -> u32 {
    let bytes = s.as_bytes();
    let mut v = 0u32;
    let mut i = 0;
    while i < bytes.len() {
        v = v * 10 + (bytes[i] - b'0') as u32;
        i += 1;
    }
    v
}

/// Divider between the transducer (signal and supply alike) and the ADC pins: 20 kΩ over
/// 30 kΩ, ×0.6, so that a 5.5 V supply still reads below the 3.3 V reference.
const DIVIDER_PERMILLE: u32 = 600;
/// VDDA at which ST measured `VREFINT_CAL` (STM32F446 datasheet, "Reference voltage").
const VREFINT_CAL_VDDA_MV: u32 = 3300;
/// Address of the factory VREFINT calibration (STM32F446 datasheet, table "Internal reference
/// voltage calibration values").
const VREFINT_CAL_ADDR: usize = 0x1FFF_7A2A;
/// VDDA the analog check accepts, mV (a Nucleo's 3.3 V regulator; outside, the ADC scale or the
/// reference itself is wrong).
const VDDA_RANGE_MV: core::ops::RangeInclusive<u32> = 3100..=3500;
/// Transducer supply the analog check accepts, mV (5 V ± 5 %).
const SUPPLY_RANGE_MV: core::ops::RangeInclusive<u32> = 4750..=5250;
/// Samples per second: TIM3 update rate, the monitor's clock (SPEC §5).
const SAMPLE_HZ: u32 = 100;
/// Debounce time of the release-command input.
const DEBOUNCE_MS: u64 = 20;
/// Period at which the release-command level is re-read without an edge.
const VALVE_POLL_MS: u64 = 100;
/// IWDG timeout: three watchdog-loop periods (500 ms), so one missed check resets.
const IWDG_TIMEOUT_US: u32 = 1_500_000;

/// The peripherals the monitor uses, before the start-up check.
pub struct BoardParts {
    adc: Peri<'static, ADC1>,
    pressure_pin: Peri<'static, peripherals::PA0>,
    supply_pin: Peri<'static, peripherals::PA1>,
    dma: Peri<'static, peripherals::DMA2_CH0>,
    tim3: Peri<'static, peripherals::TIM3>,
    valve_pin: Peri<'static, peripherals::PA10>,
    valve_exti: Peri<'static, peripherals::EXTI10>,
    can: Peri<'static, CAN1>,
    can_rx: Peri<'static, peripherals::PB8>,
    can_tx: Peri<'static, peripherals::PB9>,
    iwdg: Peri<'static, peripherals::IWDG>,
}

/// The drivers, started.
pub struct Running {
    /// The 100 Hz sample source.
    pub adc: TriggeredAdc,
    /// The release-command input (debounced by `debounce_valve`).
    pub valve_input: ExtiInput<'static, embassy_stm32::mode::Async>,
    /// The CAN controller, on the bus.
    pub can: BxCan,
    /// The independent watchdog, running.
    pub watchdog: Iwdg,
}

impl BoardParts {
    /// Takes the monitor's peripherals out of `p`.
    pub fn new(p: Peripherals) -> Self {
        Self {
            adc: p.ADC1,
            pressure_pin: p.PA0,
            supply_pin: p.PA1,
            dma: p.DMA2_CH0,
            tim3: p.TIM3,
            valve_pin: p.PA10,
            valve_exti: p.EXTI10,
            can: p.CAN1,
            can_rx: p.PB8,
            can_tx: p.PB9,
            iwdg: p.IWDG,
        }
    }

    /// The analog check (repeated every second until it passes), then every driver started:
    /// ADC paced by TIM3, CAN on the bus with every filter closed, the release-command input,
    /// and the IWDG (last: from here on only progress feeds it).
    pub async fn start(mut self) -> Running {
        let mut adc = Adc::new(self.adc);
        let supply_code = loop {
            match analog_check(&mut adc, &mut self.supply_pin).await {
                Ok((vdda_mv, supply_mv, code)) => {
                    defmt::info!("analog check: VDDA {=u32} mV, transducer supply {=u32} mV: ok", vdda_mv, supply_mv);
                    break code;
                }
                Err(why) => {
                    defmt::error!("analog check failed: {=str}; monitor not started, retrying in 1 s", why);
                    Delay::after_secs(1).await;
                }
            }
        };

        // TIM3 counts at 1 MHz and wraps every 10 000 counts: its update event, routed to TRGO,
        // starts one scan of ADC1 (pressure, supply) exactly every 10 ms; DMA2 stream 0 moves the
        // two codes into a ring of two scans, so no software timing touches the sample clock.
        let tim3 = Timer::new(self.tim3);
        let clock = tim3.get_clock_frequency().0;
        if clock % 1_000_000 != 0 {
            defmt::panic!("TIM3 clock {=u32} Hz is no whole number of MHz: 100 Hz would not be exact", clock);
        }
        let regs = tim3.regs_core();
        regs.psc().write_value((clock / 1_000_000 - 1) as u16);
        regs.arr().write(|w| w.set_arr((1_000_000 / SAMPLE_HZ - 1) as u16));
        // Load the prescaler now (it is buffered until an update event).
        regs.egr().write(|w| w.set_ug(true));
        tim3.set_master_mode(MasterMode::UPDATE);

        // `cortex_m::singleton!` gives the DMA its 'static buffer once; `start` runs once.
        let Some(ring) = cortex_m::singleton!(: [u16; 4] = [0; 4]) else {
            defmt::panic!("BoardParts::start called twice");
        };
        let mut ring_adc = adc.into_ring_buffered(
            self.dma,
            ring,
            Irqs,
            [
                (self.pressure_pin.degrade_adc(), SampleTime::CYCLES480),
                (self.supply_pin.degrade_adc(), SampleTime::CYCLES480),
            ]
            .into_iter(),
            embassy_stm32::triggers::TIM3_TRGO,
            Exten::RISING_EDGE,
        );
        // `start` also sets SWSTART: one scan at once, then one on every TIM3 update. The extra
        // first scan is sample 0, before any release command can have been seen.
        ring_adc.start();
        tim3.start();
        // The timer keeps running for the controller's life; dropping the driver would stop its
        // clock.
        core::mem::forget(tim3);

        let valve_input = ExtiInput::new(self.valve_pin, self.valve_exti, Pull::Up, Irqs);

        let can = start_can(self.can, self.can_rx, self.can_tx).await;

        // Frozen while a debugger halts the core, so breakpoints do not reset the controller.
        embassy_stm32::pac::DBGMCU.apb1fzr().modify(|w| w.set_iwdg(true));
        let mut iwdg = IndependentWatchdog::new(self.iwdg, IWDG_TIMEOUT_US);
        iwdg.unleash();

        Running {
            adc: TriggeredAdc { adc: ring_adc, supply_sum: u32::from(supply_code) * SUPPLY_AVERAGE },
            valve_input,
            can: BxCan { can, sent: 0 },
            watchdog: Iwdg(iwdg),
        }
    }
}

/// VDDA from VREFINT and its factory calibration, then the transducer supply through its
/// divider: (VDDA mV, supply mV, supply ADC code) when both are in range.
async fn analog_check(
    adc: &mut Adc<'static, ADC1>,
    supply_pin: &mut Peri<'static, peripherals::PA1>,
) -> Result<(u32, u32, u16), &'static str> {
    let mut vrefint = adc.enable_vrefint();
    // VREFINT needs 10 µs to settle after it is switched on (STM32F446 datasheet, t_START).
    Delay::after_micros(10).await;
    let raw = u32::from(adc.blocking_read(&mut vrefint, SampleTime::CYCLES480));
    // SAFETY: a 16-bit word of the system memory's read-only calibration area, present on every
    // STM32F446.
    let cal = u32::from(unsafe { core::ptr::read_volatile(VREFINT_CAL_ADDR as *const u16) });
    if raw == 0 {
        return Err("VREFINT reads 0 (no analog supply?)");
    }
    let vdda_mv = VREFINT_CAL_VDDA_MV * cal / raw;
    if !VDDA_RANGE_MV.contains(&vdda_mv) {
        defmt::error!("VDDA {=u32} mV (VREFINT {=u32}, calibration {=u32})", vdda_mv, raw, cal);
        return Err("VDDA out of 3.1..3.5 V");
    }
    let code = adc.blocking_read(supply_pin, SampleTime::CYCLES480);
    let supply_mv = u32::from(code) * vdda_mv * 1000 / (4095 * DIVIDER_PERMILLE);
    if !SUPPLY_RANGE_MV.contains(&supply_mv) {
        defmt::error!("transducer supply {=u32} mV", supply_mv);
        return Err("transducer supply out of 4.75..5.25 V");
    }
    Ok((vdda_mv, supply_mv, code))
}

/// Scans the supply average runs over (a power of two): the supply moves slowly, and averaging
/// keeps its conversion noise out of the ratio.
const SUPPLY_AVERAGE: u32 = 16;
/// Lowest and highest averaged supply code accepted while running, from the nominal VDDA (the
/// start-up check measured the real one): outside, every reading is reported as an open circuit.
const SUPPLY_CODE_RANGE: core::ops::RangeInclusive<u32> = supply_code(4500)..=supply_code(5500);

const fn supply_code(mv: u32) -> u32 {
    mv * DIVIDER_PERMILLE * 4095 / (1000 * VREFINT_CAL_VDDA_MV)
}

/// ADC1 scans (pressure, supply) on TIM3's 100 Hz trigger, moved by DMA into a ring buffer.
pub struct TriggeredAdc {
    adc: RingBufferedAdc<'static, ADC1>,
    /// Sum of the last [`SUPPLY_AVERAGE`] supply codes (exponential average).
    supply_sum: u32,
}

impl TriggeredAdc {
    /// The SPEC's code (12 bits referenced to the transducer's own 5 V supply, SPEC §5) from the
    /// two conversions: the pressure code scaled by the supply code (same divider on both), so
    /// neither the supply's tolerance nor VDDA moves the reading.
    fn ratiometric(&mut self, pressure: u16, supply: u16) -> AdcCounts {
        self.supply_sum = self.supply_sum - self.supply_sum / SUPPLY_AVERAGE + u32::from(supply);
        let supply = self.supply_sum / SUPPLY_AVERAGE;
        if !SUPPLY_CODE_RANGE.contains(&supply) {
            // No supply, no reading: code 0 is an open circuit to the core's sensor map, a
            // sensor fault (never a brake fault).
            return AdcCounts(0);
        }
        let code = (u32::from(pressure) * 4095 + supply / 2) / supply;
        AdcCounts(code.min(4095) as u16)
    }
}

impl SampleSource for TriggeredAdc {
    async fn next(&mut self) -> Option<AdcCounts> {
        let mut scan = [0u16; 2];
        loop {
            match self.adc.read(&mut scan).await {
                Ok(_) => {
                    let [pressure, supply] = scan;
                    return Some(self.ratiometric(pressure, supply));
                }
                Err(_) => {
                    // The DMA lapped the reader (a task held the executor for > 10 ms): the
                    // scan is lost; count it and resume with the next trigger.
                    app::count_dropped_sample();
                    defmt::warn!("ADC ring overrun: a sample was lost");
                    self.adc.clear();
                    self.adc.start();
                }
            }
        }
    }
}

/// The debounced release command, written by [`debounce_valve`] and read once per sample.
static VALVE_OPEN: AtomicBool = AtomicBool::new(false);

/// Follows the release-command input (active low: the optocoupler pulls PA10 down while the
/// command is on): after every EXTI edge it waits [`DEBOUNCE_MS`] for the contact to settle and
/// takes the level. It also looks every [`VALVE_POLL_MS`] without an edge, so that a bounce
/// that ends during the settling wait (its last edge unseen) cannot leave a stale level.
pub async fn debounce_valve(mut input: ExtiInput<'static, embassy_stm32::mode::Async>) {
    loop {
        let open = input.is_low();
        if VALVE_OPEN.swap(open, Ordering::Relaxed) != open {
            defmt::info!("release command {=str}", if open { "on" } else { "off" });
        }
        if let Either::First(()) = select(input.wait_for_any_edge(), Delay::after_millis(VALVE_POLL_MS)).await {
            Delay::after_millis(DEBOUNCE_MS).await;
        }
    }
}

/// The release command as the sample loop reads it.
pub struct DebouncedValve;

impl ValveCommand for DebouncedValve {
    fn release_requested(&mut self) -> bool {
        VALVE_OPEN.load(Ordering::Relaxed)
    }
}

/// bxCAN1 at [`CAN_BITRATE`], every acceptance filter closed (the monitor transmits only and acts
/// on nothing it receives; frames on the bus are still acknowledged), automatic bus-off recovery.
async fn start_can(
    can: Peri<'static, CAN1>,
    rx: Peri<'static, peripherals::PB8>,
    tx: Peri<'static, peripherals::PB9>,
) -> Can<'static> {
    let mut can = Can::new(can, rx, tx, Irqs);
    close_filters(&mut can.modify_filters());
    let Ok(timing) = embassy_stm32::can::util::calc_can_timings(embassy_stm32::rcc::frequency::<CAN1>(), CAN_BITRATE)
    else {
        defmt::panic!("no bit timing for {=u32} bit/s from the APB1 clock", CAN_BITRATE);
    };
    can.modify_config().set_bit_timing(timing).set_automatic_retransmit(true);
    // Bus-off recovery by the hardware (128 × 11 recessive bits), not by software.
    embassy_stm32::pac::CAN1.mcr().modify(|w| w.set_abom(true));
    can.enable().await;
    can
}

/// Disables every filter bank: the bxCAN then stores no received frame at all.
fn close_filters(filters: &mut MasterFilters<'_>) {
    filters.clear();
}

/// The monitor's frames onto bxCAN1.
pub struct BxCan {
    can: Can<'static>,
    sent: u32,
}

impl FrameSink for BxCan {
    async fn send(&mut self, _sample: u32, frame: &CanFrame) -> bool {
        // The same identifier and payload as the QEMU candump line (the core built the frame).
        let Ok(out) = Frame::new_data(frame.id(), frame.data()) else {
            return false;
        };
        // Waits for a free transmit mailbox: the monitor's bounded frame queue absorbs the wait
        // and counts what it cannot hold.
        self.can.write(&out).await;
        self.sent = self.sent.wrapping_add(1);
        true
    }

    fn sent(&self) -> u32 {
        self.sent
    }
}

/// The independent watchdog.
pub struct Iwdg(IndependentWatchdog<'static, peripherals::IWDG>);

impl Watchdog for Iwdg {
    fn feed(&mut self) {
        self.0.pet();
    }
}

/// The DWT cycle counter (CYCCNT, core clock cycles).
#[derive(Clone, Copy)]
pub struct DwtCycles(());

impl DwtCycles {
    /// Switches the counter on (trace enable, then CYCCNT).
    pub fn enable(dcb: &mut cortex_m::peripheral::DCB, dwt: &mut cortex_m::peripheral::DWT) -> Self {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        Self(())
    }
}

impl CycleCounter for DwtCycles {
    const ENABLED: bool = true;
    fn now(&self) -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }
}
