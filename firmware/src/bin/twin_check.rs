//! `twin-check`: runs the core's fixed-point twin (nominal brake, SPEC §3) for a 60 s release
//! at 100 Hz on an embassy-time ticker and compares its state at the golden checkpoints with
//! the values the host computed (`tests/golden/nominal_checkpoints.csv`), bit for bit.
//!
//! Exit status (QEMU semihosting): 0 when every checkpoint matches, 1 otherwise. With the
//! feature `selftest-corrupt-golden` one expected value is off by one LSB, so the run must fail:
//! that proves the check can fail.
#![no_std]
#![no_main]

use defmt::println;
use embassy_executor::Spawner;
use embassy_time::{Duration, Instant, Ticker};
use pbm::{Twin, TwinParams};
use pbm_firmware::console::exit;
use pbm_firmware::golden::{self, Checkpoints};
use pbm_firmware::{executor, time_driver};

/// The host's golden values, compiled into flash.
const GOLDEN_CSV: &str = include_str!("../../../tests/golden/nominal_checkpoints.csv");

#[cortex_m_rt::entry]
fn main() -> ! {
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        println!("twin-check: core peripherals already taken");
        exit(false)
    };
    time_driver::init(peripherals.SYST);
    executor::run(|spawner: Spawner| match release_task() {
        Ok(token) => spawner.spawn(token),
        Err(e) => {
            println!("twin-check: cannot spawn the release task: {}", defmt::Debug2Format(&e));
            exit(false)
        }
    })
}

/// Expected checkpoints, optionally corrupted by the self-test feature.
fn expected() -> Result<Checkpoints, golden::GoldenError> {
    #[allow(unused_mut)]
    let mut checkpoints = golden::parse(GOLDEN_CSV)?;
    #[cfg(feature = "selftest-corrupt-golden")]
    if let Some(last) = checkpoints.as_mut_slice().last_mut() {
        println!("twin-check: SELFTEST: expected p_q24 of the last checkpoint perturbed by +1 LSB");
        last.p_q24 = last.p_q24.wrapping_add(1);
    }
    Ok(checkpoints)
}

#[embassy_executor::task]
async fn release_task() {
    let checkpoints = match expected() {
        Ok(c) => c,
        Err(e) => {
            println!("twin-check: bad golden file: {}", defmt::Display2Format(&e));
            exit(false)
        }
    };
    let mut twin = match Twin::new(&TwinParams::nominal()) {
        Ok(t) => t,
        Err(e) => {
            println!("twin-check: nominal parameters rejected: {}", defmt::Debug2Format(&e));
            exit(false)
        }
    };
    println!("twin-check: nominal release, 100 Hz, {=usize} checkpoints", checkpoints.as_slice().len());
    println!("t_s,updates,p_q24,x_q32,p_bar_g,expected_p_q24,expected_x_q32,result");

    let start = Instant::now();
    let mut ticker = Ticker::every(Duration::from_millis(10));
    let mut updates: u32 = 0;
    let mut failures: u32 = 0;
    for cp in checkpoints.as_slice() {
        let mut sample = None;
        while updates < cp.updates {
            ticker.next().await;
            sample = Some(twin.update(true));
            updates += 1;
        }
        let (p, x) = sample.map_or((0, 0), |s| (s.pressure.0, s.travel.0));
        let ok = p == cp.p_q24 && x == cp.x_q32;
        failures += u32::from(!ok);
        let (sign, bar, micro) = gauge_bar(p);
        println!(
            "{=u32}.{=u32:02},{=u32},{=i32},{=i32},{=str}{=u32}.{=u32:06},{=i32},{=i32},{=str}",
            cp.updates / 100,
            cp.updates % 100,
            cp.updates,
            p,
            x,
            sign,
            bar,
            micro,
            cp.p_q24,
            cp.x_q32,
            if ok { "ok" } else { "MISMATCH" }
        );
    }
    let elapsed_ms = (Instant::now() - start).as_millis();
    println!("twin-check: {=u32} samples in {=u64} ms of simulated time", updates, elapsed_ms);
    if failures == 0 {
        println!("twin-check: PASS (all checkpoints equal the host values bit for bit)");
        exit(true)
    } else {
        println!("twin-check: FAIL ({=u32} checkpoint(s) differ from the host values)", failures);
        exit(false)
    }
}

/// A Q7.24 absolute pressure as gauge bar: sign, whole bars and micro-bars (rounded half away
/// from zero), integer arithmetic only.
fn gauge_bar(p_q24: i32) -> (&'static str, u32, u32) {
    let gauge_q24 = i64::from(p_q24) - (1i64 << 24);
    let micro = (gauge_q24.unsigned_abs() * 1_000_000 + (1 << 23)) >> 24;
    let sign = if gauge_q24 < 0 && micro != 0 { "-" } else { "" };
    (sign, (micro / 1_000_000) as u32, (micro % 1_000_000) as u32)
}
