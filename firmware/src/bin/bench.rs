//! `bench`: cost of the per-sample pipeline on the Cortex-M4F, in instructions.
//!
//! Run under `qemu-system-arm -icount shift=0` (the runner in .cargo/config.toml): every
//! instruction advances the virtual clock by exactly 1 ns, and SysTick counts that clock at
//! 25 MHz, so one SysTick count is 40 instructions. Each measured call is bracketed by two
//! reads of the free-running SysTick counter (interrupts off); summing over thousands of calls
//! makes the ±1-count quantisation negligible in the mean. A calibration loop of known length
//! checks the conversion. Output: `key=value` lines on standard output, parsed by
//! `cargo xtask fw-bench`.
#![no_std]
#![no_main]

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use defmt::println;
use pbm::classifier::diagnose;
use pbm::estimator::{EstimatorConfig, ReleaseEstimator};
use pbm::features::{ReleaseFeatures, ReleaseSample};
use pbm::mechanism::{Extensions, Mechanism};
use pbm::reservoir::{Reservoir, ReservoirParams};
use pbm::{AdcCounts, BarG, KelvinQ8, Meters, PressureQ24};
use pbm_firmware::adc::ADC_TRACE;
use pbm_firmware::console::exit;
use pbm_firmware::{stack, time_driver};

/// Instructions per SysTick count under `-icount shift=0` (1 ns each) at 25 MHz.
const INSTR_PER_COUNT: u64 = 1_000_000_000 / time_driver::CORE_CLOCK_HZ as u64;
const RELOAD: u32 = 0x00FF_FFFF;

/// Mean, max and total of a series of measurements, instructions.
#[derive(Default)]
struct Stats {
    n: u64,
    total: u64,
    max: u64,
    /// Index (in calls to `add`) of the largest measurement.
    argmax: u64,
    /// Measurements above the per-sample budget of issue 7.
    over_budget: u64,
}

/// Per-sample budget of issue 7, instructions.
const BUDGET_INSTR: u64 = 5000;

impl Stats {
    fn add(&mut self, instr: u64) {
        if instr > self.max {
            self.max = instr;
            self.argmax = self.n;
        }
        if instr > BUDGET_INSTR {
            self.over_budget += 1;
        }
        self.n += 1;
        self.total += instr;
    }
    fn mean(&self) -> u64 {
        self.total.checked_div(self.n).unwrap_or(0)
    }
}

/// Instructions spent in `f` (SysTick counts × 40, minus the bracket's own cost `overhead`).
#[inline(always)]
fn measure<R>(overhead: u64, f: impl FnOnce() -> R) -> (u64, R) {
    let before = SYST::get_current();
    let r = f();
    let after = SYST::get_current();
    let counts = u64::from(before.wrapping_sub(after) & RELOAD);
    ((counts * INSTR_PER_COUNT).saturating_sub(overhead), r)
}

/// A loop of exactly `3 * n` instructions (subs, bne, nop).
#[inline(never)]
fn known_loop(n: u32) {
    // SAFETY: register-only loop.
    unsafe {
        core::arch::asm!(
            "1:",
            "nop",
            "subs {n}, {n}, #1",
            "bne 1b",
            n = inout(reg) n => _,
            options(nomem, nostack),
        );
    }
}

#[cortex_m_rt::entry]
fn main() -> ! {
    stack::paint();
    let Some(mut p) = cortex_m::Peripherals::take() else {
        println!("bench: core peripherals already taken");
        exit(false)
    };
    cortex_m::interrupt::disable();
    p.SYST.set_clock_source(SystClkSource::Core);
    p.SYST.set_reload(RELOAD);
    p.SYST.clear_current();
    p.SYST.disable_interrupt();
    p.SYST.enable_counter();

    // Calibration: the bracket alone, then 3 × 100 000 instructions.
    let mut bracket = Stats::default();
    for _ in 0..1000 {
        bracket.add(measure(0, || ()).0);
    }
    let overhead = bracket.mean();
    let (cal, ()) = measure(overhead, || known_loop(100_000));
    println!("calibration_expected_instr=300000");
    println!("calibration_measured_instr={=u64}", cal);
    println!("bracket_overhead_instr={=u64}", overhead);

    // The core's per-sample pipeline (the monitor task's work) over the compiled-in trace.
    // The monitor's own pipeline (the nominal brake, or with feature `extensions` the
    // build-time mechanisms), and its twin alone.
    let Ok(mut pipeline) = pbm_firmware::app::pipeline() else {
        println!("bench: twin parameters rejected");
        exit(false)
    };
    let mut twin = pbm_firmware::app::twin();
    let mut per_sample = Stats::default();
    let mut closing = Stats::default();
    let mut twin_only = Stats::default();
    let mut features_cost = Stats::default();
    let mut features = ReleaseFeatures::new();
    let mut estimator_cost = Stats::default();
    let Ok(mut estimator) = ReleaseEstimator::nominal(EstimatorConfig::default()) else {
        println!("bench: estimator configuration rejected");
        exit(false)
    };
    let mut frames = 0usize;
    for &code in ADC_TRACE.iter() {
        let (instr, step) = measure(overhead, || pipeline.step(AdcCounts(code), true));
        // The sample that closes the diagnosis also runs the classifier: counted apart.
        if step.closed.is_some() {
            closing.add(instr);
        } else {
            per_sample.add(instr);
        }
        frames += step.frames.as_slice().len();
        twin_only.add(measure(overhead, || twin.update(true)).0);
        let sample = ReleaseSample::from(&step.monitor);
        features_cost.add(measure(overhead, || features.update(&sample)).0);
        let measured = step.monitor.measured.ok();
        estimator_cost.add(measure(overhead, || estimator.update(measured, true)).0);
    }
    let (close_instr, closed) = measure(overhead, || pipeline.close());
    if let Some((_, outbox)) = closed {
        closing.add(close_instr);
        frames += outbox.as_slice().len();
    }
    let (classify, verdict) = measure(overhead, || diagnose(pipeline.features()));

    // The reservoir model the MetroPT-3 audit named (bench/audit_metro.md: heat transfer and
    // transport delay on the fitted base), one 0.5 s substep per call, over four 90 s phases.
    let metro = ReservoirParams {
        volume_m3: 0.5,
        compressor_g_per_s: 9.04,
        outlet: Meters::from_mm(0.563),
        discharge_coeff: 0.8,
        ext: Extensions::NONE.with(Mechanism::HeatTransfer, 20.3).with(Mechanism::TransportDelay, 9.3),
        wall: pbm::reservoir::WallNode::OFF,
    };
    let Ok(mut reservoir) = Reservoir::new(&metro) else {
        println!("bench: reservoir parameters rejected");
        exit(false)
    };
    reservoir.restart(PressureQ24::from_bar_g(BarG(8.0)), true);
    let mut reservoir_cost = Stats::default();
    let oil = KelvinQ8::from_celsius(75.0);
    for k in 0..720 {
        let loaded = (k / 180) % 2 == 0;
        reservoir_cost.add(measure(overhead, || reservoir.update(loaded, oil)).0);
    }

    // An extended twin's image: its twin must give the host's bits (build.rs hashed the host's
    // extended twin, every mechanism compiled in, over the same schedule).
    #[cfg(pbm_mechanisms)]
    {
        use pbm_firmware::app::mechanisms::{TWIN_CHECK_CLOSED, TWIN_CHECK_OPEN, TWIN_HASH};
        let mut check = pbm_firmware::app::twin();
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for i in 0..TWIN_CHECK_OPEN + TWIN_CHECK_CLOSED {
            let s = check.update(i < TWIN_CHECK_OPEN);
            for b in s.pressure.0.to_le_bytes().into_iter().chain(s.travel.0.to_le_bytes()) {
                h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
        if h != TWIN_HASH {
            println!("ext_twin_check=MISMATCH (image {=u64:x}, host {=u64:x})", h, TWIN_HASH);
            exit(false)
        }
        println!("ext_twin_check=equal");
    }
    println!("samples={=usize}", ADC_TRACE.len());
    println!("frames={=usize}", frames);
    println!("pipeline_instr_per_sample_mean={=u64}", per_sample.mean());
    println!("pipeline_instr_per_sample_max={=u64}", per_sample.max);
    println!("closing_sample_instr={=u64}", closing.max);
    println!("pipeline_max_at_sample={=u64}", per_sample.argmax);
    println!("pipeline_samples_over_budget={=u64}", per_sample.over_budget);
    println!("twin_instr_per_sample_mean={=u64}", twin_only.mean());
    println!("twin_instr_per_sample_max={=u64}", twin_only.max);
    println!("features_instr_per_sample_mean={=u64}", features_cost.mean());
    println!("features_instr_per_sample_max={=u64}", features_cost.max);
    println!("estimator_instr_per_sample_mean={=u64}", estimator_cost.mean());
    println!("estimator_instr_per_sample_max={=u64}", estimator_cost.max);
    println!("estimator_max_at_sample={=u64}", estimator_cost.argmax);
    println!("classify_instr={=u64}", classify);
    println!("reservoir_instr_per_substep_mean={=u64}", reservoir_cost.mean());
    println!("reservoir_instr_per_substep_max={=u64}", reservoir_cost.max);
    println!("verdict={}", defmt::Debug2Format(&verdict));
    println!("static_ram_bytes={=usize}", stack::static_ram());
    println!("peak_stack_bytes={=usize}", stack::peak_used());
    exit(true)
}
