//! Text output, exit status and panic handling over ARM semihosting.
//!
//! On QEMU (`-semihosting-config enable=on,target=native`) the text goes to QEMU's standard
//! output and [`exit`] ends QEMU with status 0 (success) or 1 (failure): the exit status is the
//! pass/fail result of a firmware run. On a real board semihosting needs an attached debug probe
//! (probe-rs forwards it); without one a semihosting call stops the core at a breakpoint.

use core::fmt::Write as _;

use cortex_m_semihosting::debug;
use cortex_m_semihosting::hio::{self, HostStream};

/// Longest line [`print_line`] writes in one semihosting call; longer text is cut.
pub const LINE_CAPACITY: usize = 192;

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
    write_stdout(line.as_bytes());
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
    write_stderr(line.as_bytes());
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
    // Last resort: the per-sample path is written not to panic (see `tests/pipeline_no_panic.rs`
    // in the core); if it ever does, say where and fail the run instead of hanging until the
    // QEMU timeout. Only the location is printed, formatted by hand: formatting the message
    // would link `core::fmt` into every binary.
    cortex_m::interrupt::disable();
    let mut line = Text::new().str("PANIC");
    if let Some(loc) = info.location() {
        line = line.str(" at ").str(loc.file()).str(":").u32(loc.line());
    }
    line.print();
    exit(false)
}

/// One line of log text built without `core::fmt` (strings and integers formatted by hand), so
/// that the `monitor` application links no formatting machinery. Text beyond
/// [`LINE_CAPACITY`] bytes is dropped.
#[derive(Clone)]
pub struct Text {
    buf: [u8; LINE_CAPACITY],
    len: usize,
}

impl Default for Text {
    fn default() -> Self {
        Self::new()
    }
}

impl Text {
    /// An empty line.
    pub const fn new() -> Self {
        Self { buf: [0; LINE_CAPACITY], len: 0 }
    }

    fn byte(&mut self, b: u8) {
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = b;
            self.len += 1;
        }
    }

    /// Appends `s` (cut at the capacity).
    #[must_use]
    pub fn str(mut self, s: &str) -> Self {
        for &b in s.as_bytes() {
            self.byte(b);
        }
        self
    }

    /// Appends `v` in decimal.
    #[must_use]
    pub fn u32(mut self, v: u32) -> Self {
        // Largest power of ten not above v (1 for 0), then one digit per power.
        let mut p = 1u32;
        while p <= v / 10 {
            p = p.saturating_mul(10);
        }
        loop {
            self.byte(b'0' + (v.checked_div(p).unwrap_or(0) % 10) as u8);
            if p <= 1 {
                return self;
            }
            p /= 10;
        }
    }

    /// Appends `v` in decimal with a sign.
    #[must_use]
    pub fn i32(self, v: i32) -> Self {
        let s = if v < 0 { self.str("-") } else { self };
        s.u32(v.unsigned_abs())
    }

    /// The text so far.
    pub fn as_bytes(&self) -> &[u8] {
        self.buf.get(..self.len).unwrap_or(&[])
    }

    fn finish(mut self) -> ([u8; LINE_CAPACITY], usize) {
        if self.len == LINE_CAPACITY {
            self.len -= 1;
        }
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = b'\n';
            self.len += 1;
        }
        (self.buf, self.len)
    }

    /// Writes the line and a newline to the host's standard output (one semihosting call).
    pub fn print(self) {
        let (buf, len) = self.finish();
        write_stdout(buf.get(..len).unwrap_or(&[]));
    }

    /// Writes the line and a newline to the host's standard error (one semihosting call).
    pub fn eprint(self) {
        let (buf, len) = self.finish();
        write_stderr(buf.get(..len).unwrap_or(&[]));
    }
}

/// Semihosting handles of the host's standard output and error, opened once (every
/// `hio::hstdout()` call opens a new host file handle).
static STREAMS: critical_section::Mutex<core::cell::Cell<[Option<HostStream>; 2]>> =
    critical_section::Mutex::new(core::cell::Cell::new([None, None]));

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

/// Writes raw bytes to the host's standard output over semihosting (no formatting code).
pub fn write_stdout(bytes: &[u8]) {
    write_stream(0, bytes);
}

/// Writes raw bytes to the host's standard error over semihosting (no formatting code).
pub fn write_stderr(bytes: &[u8]) {
    write_stream(1, bytes);
}
