//! Peak stack measurement by painting.
//!
//! [`paint`] fills the free RAM between the end of the static data (`__sheap`, after `.bss` and
//! `.uninit`) and the current stack pointer with a pattern; [`peak_used`] later finds the
//! lowest word that no longer holds it. The difference to the top of the stack is the deepest
//! the stack has been. Call [`paint`] first thing in `main`, before interrupts are enabled.

use core::ptr::{addr_of, addr_of_mut};

const PAINT: u32 = 0xC0DE_57AC;
/// Words just below the stack pointer left unpainted (the painting function's own frame).
const GUARD_WORDS: usize = 16;

extern "C" {
    static mut __sheap: u32;
    static _stack_start: u32;
}

/// Paints the unused stack area.
#[inline(never)]
pub fn paint() {
    let sp = cortex_m::register::msp::read() as usize;
    // SAFETY: the words from `__sheap` up to just below the current stack pointer belong to no
    // static and no live stack frame (no heap is used); interrupts that could push frames
    // there are not enabled yet.
    unsafe {
        let mut p = addr_of_mut!(__sheap);
        let end = (sp - GUARD_WORDS * 4) as *mut u32;
        while p < end {
            p.write_volatile(PAINT);
            p = p.add(1);
        }
    }
}

/// Deepest stack use since [`paint`], bytes.
pub fn peak_used() -> usize {
    // SAFETY: reads of words between `__sheap` and the stack top, which is RAM owned by the
    // stack (volatile: the compiler must not assume their content).
    unsafe {
        let top = addr_of!(_stack_start) as usize;
        let mut p = addr_of!(__sheap);
        while (p as usize) < top && p.read_volatile() == PAINT {
            p = p.add(1);
        }
        top - p as usize
    }
}

/// Bytes of static RAM (`.data`, `.bss`, `.uninit`): from the start of RAM to `__sheap`.
pub fn static_ram() -> usize {
    extern "C" {
        static __sdata: u32;
    }
    // Only the addresses of the linker symbols are taken, never their contents.
    addr_of!(__sheap) as usize - addr_of!(__sdata) as usize
}
