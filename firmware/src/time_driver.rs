//! embassy-time driver on the Cortex-M SysTick timer.
//!
//! SysTick counts the core clock (25 MHz on QEMU's mps2-an386; set [`CORE_CLOCK_HZ`] for a real
//! board) down from a reload value that makes it wrap every millisecond. The wrap interrupt
//! advances a millisecond counter and fires expired timers; [`Driver::now`] adds the position
//! inside the current millisecond, so time has 1 µs resolution (embassy-time `tick-hz-1_000_000`)
//! and timers fire on the first millisecond tick at or after their deadline. A 100 Hz ticker's
//! deadlines are whole milliseconds, so it fires exactly on time.
//!
//! Under `qemu-system-arm -icount shift=0,sleep=off` the virtual clock jumps to the next SysTick
//! wrap while the core sleeps in `WFI`, so simulated time costs only the instructions executed.

use core::cell::{Cell, RefCell};
use core::task::Waker;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};
use cortex_m_rt::exception;
use critical_section::{CriticalSection, Mutex};
use embassy_time_driver::Driver;
use embassy_time_queue_utils::queue_generic::ConstGenericQueue;

/// Core clock feeding SysTick (QEMU mps2-an386: 25 MHz).
pub const CORE_CLOCK_HZ: u32 = 25_000_000;
/// SysTick counts per millisecond.
const COUNTS_PER_MS: u32 = CORE_CLOCK_HZ / 1000;
/// SysTick counts per embassy tick (1 µs).
const COUNTS_PER_TICK: u32 = CORE_CLOCK_HZ / embassy_time_driver::TICK_HZ as u32;
/// Embassy ticks per millisecond.
const TICKS_PER_MS: u64 = embassy_time_driver::TICK_HZ / 1000;
/// Timers the queue holds at once: one per task waiting on time (ADC ticker, CAN status
/// period, watchdog) plus margin. A full queue makes embassy-time panic, so size it generously.
const TIMER_QUEUE_LEN: usize = 8;

struct SysTickDriver {
    /// Milliseconds since [`init`].
    millis: Mutex<Cell<u64>>,
    /// Earliest deadline in the queue (ticks), `u64::MAX` when empty.
    next_alarm: Mutex<Cell<u64>>,
    queue: Mutex<RefCell<ConstGenericQueue<TIMER_QUEUE_LEN>>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: SysTickDriver = SysTickDriver {
    millis: Mutex::new(Cell::new(0)),
    next_alarm: Mutex::new(Cell::new(u64::MAX)),
    queue: Mutex::new(RefCell::new(ConstGenericQueue::new())),
});

impl SysTickDriver {
    fn now_cs(&self, cs: CriticalSection<'_>) -> u64 {
        let mut millis = self.millis.borrow(cs).get();
        let mut counts = SYST::get_current();
        // A wrap whose interrupt has not run yet (we are in a critical section): count it, and
        // re-read the counter, which is certainly past the wrap now.
        if SCB::is_pendst_pending() {
            millis += 1;
            counts = SYST::get_current();
        }
        let elapsed = (COUNTS_PER_MS - 1).saturating_sub(counts) / COUNTS_PER_TICK;
        millis * TICKS_PER_MS + u64::from(elapsed)
    }

    /// Fires every expired timer and records the next deadline.
    fn fire_expired(&self, cs: CriticalSection<'_>) {
        let now = self.now_cs(cs);
        let next = self.queue.borrow_ref_mut(cs).next_expiration(now);
        self.next_alarm.borrow(cs).set(next);
    }
}

impl Driver for SysTickDriver {
    fn now(&self) -> u64 {
        critical_section::with(|cs| self.now_cs(cs))
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            if self.queue.borrow_ref_mut(cs).schedule_wake(at, waker) {
                self.fire_expired(cs);
            }
        });
    }
}

/// Starts SysTick as the time base (1 ms wrap, interrupt enabled). Call once, first thing.
pub fn init(mut syst: SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(COUNTS_PER_MS - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

#[exception]
fn SysTick() {
    critical_section::with(|cs| {
        let millis = DRIVER.millis.borrow(cs);
        millis.set(millis.get() + 1);
        // Taking the exception cleared its pending bit, so `now_cs` does not count this wrap twice.
        if DRIVER.now_cs(cs) >= DRIVER.next_alarm.borrow(cs).get() {
            DRIVER.fire_expired(cs);
        }
    });
}
