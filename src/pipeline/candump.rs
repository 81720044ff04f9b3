//! candump log lines (`candump -L` / `canplayer` format), the one formatter shared by the
//! firmware's CAN stand-in and the host's logs: `(SECONDS.MICROS) IFACE ID#DATA`, e.g.
//! `(0000000001.000000) can0 18FF5080#0102030405060708`.
//!
//! Seconds are 10 digits and microseconds 6; extended identifiers 8 upper-case hex digits,
//! standard ones 3; data as upper-case hex pairs; a remote frame as `ID#R` (or `ID#R<len>`).
//! Everything implements [`core::fmt::Display`], so the firmware formats into a fixed buffer
//! and the host into a `String`; no allocation here.

use core::fmt;

use embedded_can::{Frame as _, Id};

use crate::can::CanFrame;

/// Longest line [`Line`] writes, not counting the interface name: 23 (time: up to 14 digits of
/// seconds for `u64::MAX` µs) + 1 + 1 + 8 (id) + 1 + 16 (data).
pub const MAX_LINE_LEN_WITHOUT_IFACE: usize = 50;

/// The time stamp `(SECONDS.MICROS)` of a frame at `time_us` µs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Time(pub u64);

impl fmt::Display for Time {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({:010}.{:06})", self.0 / 1_000_000, self.0 % 1_000_000)
    }
}

/// A frame as `ID#DATA` (`ID#R`, `ID#R<len>` for a remote frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameText<'a>(pub &'a CanFrame);

impl fmt::Display for FrameText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let frame = self.0;
        match frame.id() {
            Id::Standard(id) => write!(f, "{:03X}#", id.as_raw())?,
            Id::Extended(id) => write!(f, "{:08X}#", id.as_raw())?,
        }
        if frame.is_remote_frame() {
            f.write_str("R")?;
            if frame.dlc() > 0 {
                write!(f, "{}", frame.dlc())?;
            }
            return Ok(());
        }
        for b in frame.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
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

impl fmt::Display for Line<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {} {}", Time(self.time_us), self.iface, FrameText(self.frame))
    }
}

/// Time stamp of sample `index` of an input that starts at `base_us`: the monitor's clock is
/// the sample count (100 Hz), so firmware and host stamp the same frame alike.
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
}
