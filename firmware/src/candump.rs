//! A CAN "driver" that writes each transmitted frame as a candump log line
//! (`(seconds.micros) can0 ID#DATA`, the format `candump -L` writes and `canplayer` reads) to
//! the host's standard output over semihosting. It implements [`embedded_can::blocking::Can`]
//! like a real bxCAN/FDCAN driver, so the CAN task does not know which one it drives.
//!
//! Timestamps are the monitor's sample clock (sample n of a release at n × 10 ms), not the
//! wall clock, so a QEMU run and a host replay of the same trace give identical logs.

use core::fmt::{self, Write as _};

use embedded_can::{ErrorKind, Frame as _, Id};
use pbm::can::CanFrame;

/// Errors of [`CandumpCan`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CandumpError {
    /// This driver only transmits; the monitor never listens on the bus.
    ReceiveUnsupported,
}

impl embedded_can::Error for CandumpError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

/// Transmit-only CAN interface writing candump lines over semihosting.
#[derive(Debug, Default)]
pub struct CandumpCan {
    timestamp_us: u64,
    sent: u32,
}

impl CandumpCan {
    /// A driver at time 0 that has sent nothing.
    pub const fn new() -> Self {
        Self { timestamp_us: 0, sent: 0 }
    }

    /// Sets the timestamp of the frames that follow, in 10 ms samples since the release command.
    pub fn set_sample_time(&mut self, sample: u32) {
        self.timestamp_us = u64::from(sample) * 10_000;
    }

    /// Frames written so far.
    pub fn sent(&self) -> u32 {
        self.sent
    }
}

/// One candump log line (without the newline) for `frame` at `timestamp_us`.
pub struct CandumpLine<'a> {
    /// Time of the frame, µs.
    pub timestamp_us: u64,
    /// Interface name.
    pub interface: &'a str,
    /// The frame.
    pub frame: &'a CanFrame,
}

impl fmt::Display for CandumpLine<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = self.timestamp_us;
        write!(f, "({:010}.{:06}) {} ", t / 1_000_000, t % 1_000_000, self.interface)?;
        match self.frame.id() {
            Id::Standard(id) => write!(f, "{:03X}#", id.as_raw())?,
            Id::Extended(id) => write!(f, "{:08X}#", id.as_raw())?,
        }
        if self.frame.is_remote_frame() {
            return write!(f, "R");
        }
        for b in self.frame.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

impl embedded_can::blocking::Can for CandumpCan {
    type Frame = CanFrame;
    type Error = CandumpError;

    fn transmit(&mut self, frame: &CanFrame) -> Result<(), CandumpError> {
        let mut line: heapless::String<64> = heapless::String::new();
        // 64 bytes hold the longest line (extended id, 8 data bytes: 48 characters + newline).
        let _ = writeln!(line, "{}", CandumpLine { timestamp_us: self.timestamp_us, interface: "can0", frame });
        cortex_m_semihosting::hprint!("{}", line.as_str());
        self.sent = self.sent.wrapping_add(1);
        Ok(())
    }

    fn receive(&mut self) -> Result<CanFrame, CandumpError> {
        Err(CandumpError::ReceiveUnsupported)
    }
}
