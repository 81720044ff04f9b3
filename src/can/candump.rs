//! candump log lines (`candump -L` / `canplayer` format), the one formatter shared by the
//! firmware's CAN stand-in and the host's logs: `(SECONDS.MICROS) IFACE ID#DATA`, e.g.
//! `(0000000001.000000) can0 18FF5080#0102030405060708`.
//!
//! Seconds are at least 10 digits and microseconds 6; extended identifiers 8 upper-case hex
//! digits, standard ones 3; data as upper-case hex pairs; a remote frame as `ID#R` (or
//! `ID#R<len>`).
//!
//! The text is produced by hand-written integer formatting into a caller's byte buffer
//! ([`Line::encode`], [`Time::encode`], [`FrameText::encode`]): the firmware writes its lines
//! without linking `core::fmt` (several KiB of flash on a Cortex-M). The [`core::fmt::Display`]
//! impls the host uses call the same encoders, so both write the same bytes. No allocation.

use core::fmt;

use embedded_can::{Frame as _, Id};

use super::CanFrame;

/// Longest line [`Line`] writes, not counting the interface name: 23 (time: up to 14 digits of
/// seconds for `u64::MAX` µs) + 1 + 1 + 8 (id) + 1 + 16 (data).
pub const MAX_LINE_LEN_WITHOUT_IFACE: usize = 50;
/// Longest [`Time`] text: `(` + 14 digits + `.` + 6 digits + `)`.
pub const MAX_TIME_LEN: usize = 23;
/// Longest [`FrameText`]: 8 hex digits of identifier, `#`, 8 data bytes as 16 hex digits.
pub const MAX_FRAME_TEXT_LEN: usize = 25;

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// Appends bytes to a caller's buffer; every write reports whether it fitted.
struct Cursor<'b> {
    buf: &'b mut [u8],
    len: usize,
}

impl Cursor<'_> {
    fn byte(&mut self, b: u8) -> Option<()> {
        *self.buf.get_mut(self.len)? = b;
        self.len += 1;
        Some(())
    }

    fn bytes(&mut self, s: &[u8]) -> Option<()> {
        let end = self.len.checked_add(s.len())?;
        self.buf.get_mut(self.len..end)?.copy_from_slice(s);
        self.len = end;
        Some(())
    }

    /// `v` in decimal, zero-padded to at least `min_digits` (at most 20) digits.
    fn decimal(&mut self, v: u64, min_digits: usize) -> Option<()> {
        let mut digits = [b'0'; 20];
        let n = decimal_digits(v, &mut digits);
        let n = n.max(min_digits).min(20);
        self.bytes(digits.get(20 - n..)?)
    }

    /// The low `digits` nibbles of `v` in upper-case hex.
    fn hex(&mut self, v: u32, digits: u32) -> Option<()> {
        for i in (0..digits).rev() {
            let nibble = v.checked_shr(4 * i).unwrap_or(0) & 0xF;
            self.byte(HEX[nibble as usize])?;
        }
        Some(())
    }
}

/// Writes the decimal digits of `v` right-aligned into `out` and returns how many there are
/// (at least one). Divides by 10 in 16-bit chunks with `u32` arithmetic, so the firmware links
/// no software 64-bit division.
fn decimal_digits(mut v: u64, out: &mut [u8; 20]) -> usize {
    let mut n = 0;
    while v != 0 || n == 0 {
        let mut rem = 0u32;
        let mut q = 0u64;
        for shift in [48u32, 32, 16, 0] {
            let cur = (rem << 16) | ((v >> shift) as u32 & 0xFFFF);
            q |= u64::from(cur / 10) << shift;
            rem = cur % 10;
        }
        if let Some(d) = out.get_mut(19 - n) {
            *d = b'0' + rem as u8;
        }
        v = q;
        n += 1;
    }
    n
}

/// Runs `encode` on a stack buffer of `N` bytes and hands the text to a formatter.
fn display_via<const N: usize>(
    f: &mut fmt::Formatter<'_>,
    encode: impl FnOnce(&mut [u8]) -> Option<usize>,
) -> fmt::Result {
    let mut buf = [0u8; N];
    let len = encode(&mut buf).ok_or(fmt::Error)?;
    // Only ASCII is ever written.
    f.write_str(core::str::from_utf8(buf.get(..len).ok_or(fmt::Error)?).map_err(|_| fmt::Error)?)
}

/// The time stamp `(SECONDS.MICROS)` of a frame at `time_us` µs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Time(pub u64);

impl Time {
    fn put(self, c: &mut Cursor<'_>) -> Option<()> {
        // All digits of the µs count at once, the point placed before the last six.
        let mut digits = [b'0'; 20];
        let n = decimal_digits(self.0, &mut digits).max(16);
        c.byte(b'(')?;
        c.bytes(digits.get(20 - n..14)?)?;
        c.byte(b'.')?;
        c.bytes(digits.get(14..)?)?;
        c.byte(b')')
    }

    /// Writes the text to the start of `out`; its length, or `None` if `out` is too short
    /// ([`MAX_TIME_LEN`] always suffices).
    pub fn encode(self, out: &mut [u8]) -> Option<usize> {
        let mut c = Cursor { buf: out, len: 0 };
        self.put(&mut c)?;
        Some(c.len)
    }
}

impl fmt::Display for Time {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        display_via::<MAX_TIME_LEN>(f, |b| self.encode(b))
    }
}

/// A frame as `ID#DATA` (`ID#R`, `ID#R<len>` for a remote frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameText<'a>(pub &'a CanFrame);

impl FrameText<'_> {
    fn put(&self, c: &mut Cursor<'_>) -> Option<()> {
        let frame = self.0;
        match frame.id() {
            Id::Standard(id) => c.hex(u32::from(id.as_raw()), 3)?,
            Id::Extended(id) => c.hex(id.as_raw(), 8)?,
        }
        c.byte(b'#')?;
        if frame.is_remote_frame() {
            c.byte(b'R')?;
            if frame.dlc() > 0 {
                c.decimal(frame.dlc() as u64, 1)?;
            }
            return Some(());
        }
        for &b in frame.data() {
            c.hex(u32::from(b), 2)?;
        }
        Some(())
    }

    /// Writes the text to the start of `out`; its length, or `None` if `out` is too short
    /// ([`MAX_FRAME_TEXT_LEN`] always suffices).
    pub fn encode(&self, out: &mut [u8]) -> Option<usize> {
        let mut c = Cursor { buf: out, len: 0 };
        self.put(&mut c)?;
        Some(c.len)
    }
}

impl fmt::Display for FrameText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        display_via::<MAX_FRAME_TEXT_LEN>(f, |b| self.encode(b))
    }
}

/// One complete log line, without the newline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Line<'a> {
    /// Time of the frame, µs.
    pub time_us: u64,
    /// Interface name (`can0`).
    pub iface: &'a str,
    /// The frame.
    pub frame: &'a CanFrame,
}

impl Line<'_> {
    /// Writes the line (no newline) to the start of `out`; its length, or `None` if `out` is
    /// too short ([`MAX_LINE_LEN_WITHOUT_IFACE`] + the interface name's length always suffices).
    pub fn encode(&self, out: &mut [u8]) -> Option<usize> {
        let mut c = Cursor { buf: out, len: 0 };
        Time(self.time_us).put(&mut c)?;
        c.byte(b' ')?;
        c.bytes(self.iface.as_bytes())?;
        c.byte(b' ')?;
        FrameText(self.frame).put(&mut c)?;
        Some(c.len)
    }
}

impl fmt::Display for Line<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // The interface name can be any length: write the fixed-size parts around it.
        write!(f, "{} {} {}", Time(self.time_us), self.iface, FrameText(self.frame))
    }
}

/// Start of the monitor's log clock: 2026-01-01T00:00:00Z in µs since the Unix epoch. Logs carry
/// absolute (epoch-based) time stamps, as `candump -L` writes them, so that can-utils
/// `log2asc`/`asc2log` convert them faithfully (zero-based stamps make `log2asc` date the log
/// 1970 and start a second header after the first second). A fixed start, not the wall clock:
/// firmware and host logs of the same input stay byte-identical and reproducible.
pub const LOG_EPOCH_US: u64 = 1_767_225_600_000_000;

/// Time stamp of sample `index` of an input that starts at `base_us` (normally
/// [`LOG_EPOCH_US`]): the monitor's clock is the sample count (100 Hz), so firmware and host
/// stamp the same frame alike.
pub fn sample_time_us(base_us: u64, index: u32) -> u64 {
    base_us.saturating_add(u64::from(index) * 10_000)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    #[test]
    fn lines_have_the_candump_layout() {
        let f = CanFrame::new_extended(0x18FF_5080, &[1, 2, 3, 4, 5, 6, 7, 0xAB]).unwrap();
        let line = Line { time_us: 61_990_000, iface: "can0", frame: &f }.to_string();
        assert_eq!(line, "(0000000061.990000) can0 18FF5080#01020304050607AB");
        assert_eq!(line.len(), 50);
        let longest = Line { time_us: u64::MAX, iface: "", frame: &f }.to_string();
        assert_eq!(longest.len(), MAX_LINE_LEN_WITHOUT_IFACE);
        let s = CanFrame::new_standard(0x12, &[]).unwrap();
        assert_eq!(FrameText(&s).to_string(), "012#");
        let r = <CanFrame as embedded_can::Frame>::new_remote(embedded_can::StandardId::ZERO, 3).unwrap();
        assert_eq!(FrameText(&r).to_string(), "000#R3");
        assert_eq!(Time(u64::MAX).to_string(), "(18446744073709.551615)");
        assert_eq!(sample_time_us(10, 5999), 59_990_010);
        assert_eq!(sample_time_us(u64::MAX, 1), u64::MAX);
    }

    /// The hand-written encoder against `core::fmt`'s integer formatting, over many times and
    /// frames; and a buffer one byte short is refused, never overrun.
    #[test]
    fn encoder_matches_core_fmt() {
        use std::format;
        let mut seed = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for i in 0..5000u32 {
            let time_us = match i % 4 {
                0 => u64::from(i) * 10_000,
                1 => next(),
                2 => next() % 100_000_000_000,
                _ => u64::MAX - u64::from(i),
            };
            let r = next();
            let data = r.to_le_bytes();
            let len = (r >> 60) as usize % 9;
            let frame = if i % 3 == 0 {
                CanFrame::new_standard((r >> 40) as u16 & 0x7FF, &data[..len]).unwrap()
            } else {
                CanFrame::new_extended((r >> 32) as u32 & 0x1FFF_FFFF, &data[..len]).unwrap()
            };
            let id = match frame.id() {
                Id::Standard(id) => format!("{:03X}", id.as_raw()),
                Id::Extended(id) => format!("{:08X}", id.as_raw()),
            };
            let hex: std::string::String = frame.data().iter().map(|b| format!("{b:02X}")).collect();
            let expected = format!("({:010}.{:06}) can0 {id}#{hex}", time_us / 1_000_000, time_us % 1_000_000);
            let line = Line { time_us, iface: "can0", frame: &frame };
            let mut buf = [0u8; 64];
            let n = line.encode(&mut buf).unwrap();
            assert_eq!(core::str::from_utf8(&buf[..n]).unwrap(), expected);
            assert_eq!(line.to_string(), expected);
            assert!(line.encode(&mut buf[..n - 1]).is_none());
        }
    }
}
