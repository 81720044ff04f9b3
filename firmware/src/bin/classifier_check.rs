//! `classifier-check`: runs the core's int8 classifier (the model compiled into `pbm`) on every
//! golden vector the host wrote (`tests/golden/classifier_golden.txt`, compiled into flash) and
//! compares int8 inputs, logits, class and confidence with the host's, exactly; the implausible
//! vectors must be rejected by the input map. The host test `tests/classifier_golden.rs` checks
//! the same file with the same code ([`pbm_firmware::classifier_golden`]).
//!
//! Exit status (QEMU semihosting): 0 when every vector matches, 1 otherwise. With the feature
//! `selftest-corrupt-golden` one expected logit is off by one, so the run must fail: that proves
//! the check can fail.
#![no_std]
#![no_main]

use defmt::println;
use pbm::classifier::model_weights::MODEL;
use pbm_firmware::classifier_golden::{self, Expected, Vector};
use pbm_firmware::console::exit;

/// The host's golden vectors, compiled into flash (≈ 0.3 MiB of text; this is a test image, not
/// the `monitor` application with its 32 KiB budget).
const GOLDEN: &str = include_str!("../../../tests/golden/classifier_golden.txt");

/// Fewest network outputs the file must hold for the check to count.
const MIN_VECTORS: usize = 100;

#[cortex_m_rt::entry]
fn main() -> ! {
    if let Err(e) = MODEL.validate() {
        println!("classifier-check: the compiled model is inconsistent: {}", defmt::Debug2Format(&e));
        exit(false)
    }
    // The self-test (feature `selftest-corrupt-golden`): the first expected logit is one higher.
    let mut perturbed = false;
    let summary = classifier_golden::check_all(&MODEL, GOLDEN, |v: &mut Vector<'_>| {
        if let (true, false, Expected::Output { logits, .. }) =
            (cfg!(feature = "selftest-corrupt-golden"), perturbed, &mut v.expected)
        {
            if let Some(l) = logits.as_mut_slice().first_mut() {
                println!("classifier-check: SELFTEST: expected logit 0 of line {=usize} perturbed by +1", v.line);
                *l = l.wrapping_add(1);
                perturbed = true;
            }
        }
    });
    println!(
        "classifier-check: {=usize} network outputs equal, {=usize} implausible vectors rejected, {=usize} failures",
        summary.matched, summary.implausible, summary.failures
    );
    match summary.first_failure {
        Some((line, Some(why))) => {
            println!("classifier-check: first failure at line {=usize}: {}", line, defmt::Display2Format(&why))
        }
        Some((line, None)) => println!("classifier-check: line {=usize} is not a golden vector", line),
        None => {}
    }
    if summary.passed(MIN_VECTORS) {
        println!("classifier-check: PASS (int8 classifier equal to the host's golden vectors)");
        exit(true)
    } else {
        println!(
            "classifier-check: FAIL (at least {=usize} outputs and one implausible vector, all equal)",
            MIN_VECTORS
        );
        exit(false)
    }
}
