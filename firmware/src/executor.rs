//! An embassy executor that sleeps with `WFI` while no task is ready.
//!
//! The stock `embassy-executor` thread executor sleeps with `WFE` and wakes with `SEV`. QEMU
//! implements `WFE` as a no-op, so that executor spins and virtual time never warps to the next
//! timer deadline. Here the pender sets a flag and the idle loop checks it with interrupts
//! masked before `WFI`: an interrupt that becomes pending after the check still ends `WFI`
//! (PRIMASK does not stop `WFI` from waking), so no wake-up is lost.

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_executor::{raw, Spawner};

/// Set by the pender (from any context) when a task became ready.
static WORK_PENDING: AtomicBool = AtomicBool::new(false);

/// The pender of `embassy_executor::raw::Executor`: marks work pending; the idle loop polls.
#[unsafe(export_name = "__pender")]
fn pender(_context: *mut ()) {
    WORK_PENDING.store(true, Ordering::Release);
}

/// Creates the (single) executor, lets `init` spawn the tasks, then polls forever, sleeping
/// with `WFI` in between.
pub fn run(init: impl FnOnce(Spawner)) -> ! {
    let Some(executor) = cortex_m::singleton!(: raw::Executor = raw::Executor::new(core::ptr::null_mut())) else {
        // A programming error at start-up, not an input: stop there.
        defmt::panic!("executor::run called twice");
    };
    let executor: &'static raw::Executor = executor;
    init(executor.spawner());
    loop {
        // SAFETY: `poll` is only ever called from this loop, never re-entrantly, and the pender
        // above does not call it.
        unsafe { executor.poll() };
        cortex_m::interrupt::disable();
        if !WORK_PENDING.swap(false, Ordering::AcqRel) {
            cortex_m::asm::wfi();
        }
        // SAFETY: interrupts were enabled before the critical check above; re-enabling them
        // lets the pending interrupt (the reason WFI returned) run now.
        unsafe { cortex_m::interrupt::enable() };
    }
}
