//! The QEMU build's link to the host over ARM semihosting: the defmt log, the CAN "bus", the
//! exit status and the panic handler.
//!
//! - **Log**: the global defmt logger. Its encoded frames go to the host's standard *error*
//!   (semihosting `:tt` in append mode); the runner (`firmware/qemu-run.sh`) pipes them through
//!   `defmt-print`, which looks the format strings up in the ELF. The strings themselves never
//!   reach flash (issue 19).
//! - **CAN bus**: [`write_stdout`] writes raw bytes to the host's standard output; the candump
//!   "driver" (`candump.rs`) puts its lines there, so standard output is exactly the candump log
//!   that `cargo xtask fw-can-equality` compares byte for byte with the host's.
//! - **Exit**: [`exit`] ends QEMU with status 0 (success) or 1 (failure): the exit status is the
//!   pass/fail result of a run.
//!
//! On a real board semihosting needs an attached debugger (without one a semihosting call stops
//! the core at a breakpoint), which is why the board build (`board/`) uses defmt-rtt instead.

use core::cell::{Cell, UnsafeCell};
use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m_semihosting::debug;
use cortex_m_semihosting::hio::{self, HostStream};

/// Ends the run: QEMU exits with status 0 when `success`, 1 otherwise.
pub fn exit(success: bool) -> ! {
    debug::exit(if success { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    // Only reached without a semihosting host (no debugger): park the core.
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    // Last resort: the per-sample path is written not to panic (see `tests/pipeline_no_panic.rs`
    // in the core); if it ever does, say where and fail the run instead of hanging until the
    // QEMU timeout. Only the location is logged: formatting the message would link `core::fmt`.
    cortex_m::interrupt::disable();
    match info.location() {
        Some(loc) => defmt::error!("PANIC at {=str}:{=u32}", loc.file(), loc.line()),
        None => defmt::error!("PANIC"),
    }
    exit(false)
}

/// Semihosting handles of the host's standard output and error, opened once (every
/// `hio::hstdout()` call opens a new host file handle).
static STREAMS: critical_section::Mutex<Cell<[Option<HostStream>; 2]>> =
    critical_section::Mutex::new(Cell::new([None, None]));

fn write_stream(which: usize, bytes: &[u8]) {
    critical_section::with(|cs| {
        let cell = STREAMS.borrow(cs);
        let mut streams = cell.get();
        let Some(&cached) = streams.get(which) else { return };
        let stream = match cached {
            Some(s) => Some(s),
            None => {
                let opened = if which == 0 { hio::hstdout().ok() } else { hio::hstderr().ok() };
                if let Some(slot) = streams.get_mut(which) {
                    *slot = opened;
                }
                cell.set(streams);
                opened
            }
        };
        if let Some(mut stream) = stream {
            let _ = stream.write_all(bytes);
        }
    });
}

/// Writes raw bytes to the host's standard output over semihosting (the candump log).
pub fn write_stdout(bytes: &[u8]) {
    write_stream(0, bytes);
}

/// Writes raw bytes to the host's standard error over semihosting (the defmt stream).
fn write_stderr(bytes: &[u8]) {
    write_stream(1, bytes);
}

/// Bytes of encoded log collected before one semihosting write: a semihosting call per encoder
/// write would be one host round trip per few bytes.
const LOG_BUF: usize = 64;

/// The defmt logger state: taken flag, the critical section held while a frame is written, the
/// frame encoder and the output buffer.
struct SemihostingLogger {
    taken: AtomicBool,
    restore: UnsafeCell<critical_section::RestoreState>,
    encoder: UnsafeCell<defmt::Encoder>,
    buf: UnsafeCell<([u8; LOG_BUF], usize)>,
}

// SAFETY: every access to the cells happens between `acquire` and `release`, inside the critical
// section `acquire` enters (single core), and `taken` refuses re-entry.
unsafe impl Sync for SemihostingLogger {}

static LOGGER: SemihostingLogger = SemihostingLogger {
    taken: AtomicBool::new(false),
    restore: UnsafeCell::new(critical_section::RestoreState::invalid()),
    encoder: UnsafeCell::new(defmt::Encoder::new()),
    buf: UnsafeCell::new(([0; LOG_BUF], 0)),
};

impl SemihostingLogger {
    /// Appends encoded bytes, writing the buffer out whenever it fills.
    ///
    /// # Safety
    /// Only between `acquire` and `release` (the logger's critical section).
    unsafe fn push(&self, bytes: &[u8]) {
        // SAFETY: exclusive by the caller's contract.
        let (buf, len) = unsafe { &mut *self.buf.get() };
        for &b in bytes {
            if let Some(slot) = buf.get_mut(*len) {
                *slot = b;
                *len += 1;
            }
            if *len == LOG_BUF {
                write_stderr(buf);
                *len = 0;
            }
        }
    }

    /// Writes out what the buffer holds.
    ///
    /// # Safety
    /// Only between `acquire` and `release`.
    unsafe fn drain(&self) {
        // SAFETY: exclusive by the caller's contract.
        let (buf, len) = unsafe { &mut *self.buf.get() };
        write_stderr(buf.get(..*len).unwrap_or(&[]));
        *len = 0;
    }
}

#[defmt::global_logger]
struct Logger;

// SAFETY: `acquire` enters a critical section and refuses re-entry; the other methods are only
// called by defmt between `acquire` and `release`, inside that section.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        // SAFETY: paired with the `critical_section::release` in `release`.
        let restore = unsafe { critical_section::acquire() };
        if LOGGER.taken.swap(true, Ordering::Relaxed) {
            // Only a panic while a frame is being written gets here (the critical section keeps
            // interrupts out): the panic handler's own log line. Fail the run without it rather
            // than panic again.
            exit(false)
        }
        // SAFETY: inside the critical section, logger taken.
        unsafe {
            LOGGER.restore.get().write(restore);
            let encoder = &mut *LOGGER.encoder.get();
            encoder.start_frame(|b| LOGGER.push(b));
        }
    }

    unsafe fn flush() {
        // SAFETY: called between acquire and release.
        unsafe { LOGGER.drain() };
    }

    unsafe fn release() {
        // SAFETY: called once after acquire, inside its critical section.
        unsafe {
            let encoder = &mut *LOGGER.encoder.get();
            encoder.end_frame(|b| LOGGER.push(b));
            LOGGER.drain();
            LOGGER.taken.store(false, Ordering::Relaxed);
            critical_section::release(LOGGER.restore.get().read());
        }
    }

    unsafe fn write(bytes: &[u8]) {
        // SAFETY: called between acquire and release.
        unsafe {
            let encoder = &mut *LOGGER.encoder.get();
            encoder.write(bytes, |b| LOGGER.push(b));
        }
    }
}
