//! Text output, exit status and panic handling over ARM semihosting.
//!
//! On QEMU (`-semihosting-config enable=on,target=native`) the text goes to QEMU's standard
//! output and [`exit`] ends QEMU with status 0 (success) or 1 (failure): the exit status is the
//! pass/fail result of a firmware run. On a real board semihosting needs an attached debug probe
//! (probe-rs forwards it); without one a semihosting call stops the core at a breakpoint.

use core::fmt::Write as _;

use cortex_m_semihosting::debug;

/// Longest line [`print_line`] writes in one semihosting call; longer text is cut.
pub const LINE_CAPACITY: usize = 160;

/// Writes `args` and a newline to the host's standard output in one semihosting call (so lines
/// of concurrent writers never interleave). Text beyond [`LINE_CAPACITY`] bytes is dropped.
pub fn print_line(args: core::fmt::Arguments<'_>) {
    let mut line: heapless::String<LINE_CAPACITY> = heapless::String::new();
    // A full buffer only truncates the line; the monitor must not stop for a log line.
    let _ = line.write_fmt(args);
    if line.push('\n').is_err() {
        line.pop();
        let _ = line.push('\n');
    }
    cortex_m_semihosting::hprint!("{}", line.as_str());
}

/// As [`print_line`], to the host's standard error (logs of the `monitor` binary, whose standard
/// output carries only the candump log).
pub fn eprint_line(args: core::fmt::Arguments<'_>) {
    let mut line: heapless::String<LINE_CAPACITY> = heapless::String::new();
    let _ = line.write_fmt(args);
    if line.push('\n').is_err() {
        line.pop();
        let _ = line.push('\n');
    }
    cortex_m_semihosting::heprint!("{}", line.as_str());
}

/// `eprintln!`-like wrapper around [`eprint_line`].
#[macro_export]
macro_rules! eprintln {
    ($($arg:tt)*) => {
        $crate::console::eprint_line(format_args!($($arg)*))
    };
}

/// `println!`-like wrapper around [`print_line`].
#[macro_export]
macro_rules! println {
    ($($arg:tt)*) => {
        $crate::console::print_line(format_args!($($arg)*))
    };
}

/// Ends the run: QEMU exits with status 0 when `success`, 1 otherwise.
pub fn exit(success: bool) -> ! {
    debug::exit(if success { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    // Only reached without a semihosting host (no debugger): park the core.
    loop {
        cortex_m::asm::wfi();
    }
}

/// Formats a Q7.24 absolute pressure as gauge bar with six decimals, integer arithmetic only
/// (no float formatting code in flash).
pub struct GaugeBar(pub i32);

impl core::fmt::Display for GaugeBar {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let gauge_q24 = i64::from(self.0) - (1i64 << 24);
        // Round half away from zero to micro-bar.
        let micro = (gauge_q24.abs() * 1_000_000 + (1 << 23)) >> 24;
        let sign = if gauge_q24 < 0 && micro != 0 { "-" } else { "" };
        write!(f, "{sign}{}.{:06}", micro / 1_000_000, micro % 1_000_000)
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    // Last resort: the per-sample path is written not to panic (see the core's tests); if it
    // ever does, say where and fail the run instead of hanging until the QEMU timeout.
    cortex_m::interrupt::disable();
    print_line(format_args!("PANIC: {info}"));
    exit(false)
}
