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

/// Core clock feeding SysTick (QEMU mps2-an386: 25 MHz).
pub const CORE_CLOCK_HZ: u32 = 25_000_000;
/// SysTick counts per millisecond.
const COUNTS_PER_MS: u32 = CORE_CLOCK_HZ / 1000;
/// SysTick counts per embassy tick (1 µs).
const COUNTS_PER_TICK: u32 = CORE_CLOCK_HZ / embassy_time_driver::TICK_HZ as u32;
/// Embassy ticks per millisecond.
const TICKS_PER_MS: u64 = embassy_time_driver::TICK_HZ / 1000;
/// Timers the queue holds at once: one per task waiting on time (ADC ticker, CAN status
/// period, watchdog) plus margin. Should it ever be full, the latest-pushed timer is woken early
/// to make room (as embassy's generic queue does): a task woken early re-checks its time.
const TIMER_QUEUE_LEN: usize = 8;

/// The timer queue: one deadline per waiting task, in fixed slots. (embassy-time-queue-utils'
/// generic queue does the same on a `heapless::Vec`, whose `swap_remove` pulls a 1.5 KiB
/// `memmove` into the image; fixed slots move nothing.)
struct TimerQueue {
    slots: [Option<(u64, Waker)>; TIMER_QUEUE_LEN],
}

impl TimerQueue {
    const fn new() -> Self {
        Self { slots: [const { None }; TIMER_QUEUE_LEN] }
    }

    /// Registers `waker` for `at` (a task already queued keeps the earlier deadline). True when
    /// the queue changed so that the next alarm may be earlier (the caller re-arms).
    fn schedule_wake(&mut self, at: u64, waker: &Waker) -> bool {
        for (deadline, queued) in self.slots.iter_mut().flatten() {
            if queued.will_wake(waker) {
                if *deadline > at {
                    *deadline = at;
                    return true;
                }
                return false;
            }
        }
        let free = self.slots.iter().position(Option::is_none).unwrap_or(TIMER_QUEUE_LEN - 1);
        if let Some(slot) = self.slots.get_mut(free) {
            if let Some((_, early)) = slot.replace((at, waker.clone())) {
                early.wake();
            }
        }
        true
    }

    /// Wakes every task whose deadline is at or before `now`; the earliest deadline left
    /// (`u64::MAX` when none).
    fn next_expiration(&mut self, now: u64) -> u64 {
        let mut next = u64::MAX;
        for slot in self.slots.iter_mut() {
            match slot {
                Some((at, _)) if *at <= now => {
                    if let Some((_, waker)) = slot.take() {
                        waker.wake();
                    }
                }
                Some((at, _)) => next = next.min(*at),
                None => {}
            }
        }
        next
    }
}

struct SysTickDriver {
    /// Milliseconds since [`init`].
    millis: Mutex<Cell<u64>>,
    /// Earliest deadline in the queue (ticks), `u64::MAX` when empty.
    next_alarm: Mutex<Cell<u64>>,
    queue: Mutex<RefCell<TimerQueue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: SysTickDriver = SysTickDriver {
    millis: Mutex::new(Cell::new(0)),
    next_alarm: Mutex::new(Cell::new(u64::MAX)),
    queue: Mutex::new(RefCell::new(TimerQueue::new())),
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
