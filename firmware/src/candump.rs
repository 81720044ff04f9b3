//! A CAN "driver" that writes each transmitted frame as a candump log line
//! (`(seconds.micros) can0 ID#DATA`, the format `candump -L` writes and `canplayer` reads) to
//! the host's standard output over semihosting. It implements [`embedded_can::blocking::Can`]
//! like a real bxCAN/FDCAN driver, so the CAN task does not know which one it drives.
//!
//! The line is the core's [`pbm::can::candump::Line`], the formatter `host-sim replay
//! --can-log` uses too, encoded by hand into a stack buffer (no `core::fmt`). Time stamps are
//! the monitor's sample clock ([`sample_time_us`]: sample n of the input at n × 10 ms after the
//! log epoch [`LOG_EPOCH_US`], an absolute time as candump writes), not the wall clock, so a
//! QEMU run and a host replay of the same trace give identical logs.

use embedded_can::ErrorKind;
use pbm::can::candump::{sample_time_us, Line, LOG_EPOCH_US, MAX_LINE_LEN_WITHOUT_IFACE};
use pbm::can::CanFrame;

/// Interface name written in every line.
pub const IFACE: &str = "can0";
/// Line buffer: the longest line with [`IFACE`] plus the newline.
const LINE_BUF: usize = MAX_LINE_LEN_WITHOUT_IFACE + IFACE.len() + 1;

/// Errors of [`CandumpCan`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CandumpError {
    /// This driver only transmits; the monitor never listens on the bus.
    ReceiveUnsupported,
    /// The line did not fit its buffer (cannot happen for a valid frame; counted, not sent).
    LineTooLong,
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

    /// Sets the time stamp of the frames that follow: sample `index` of the input.
    pub fn set_sample_time(&mut self, index: u32) {
        self.timestamp_us = sample_time_us(LOG_EPOCH_US, index);
    }

    /// Frames written so far.
    pub fn sent(&self) -> u32 {
        self.sent
    }
}

impl embedded_can::blocking::Can for CandumpCan {
    type Frame = CanFrame;
    type Error = CandumpError;

    fn transmit(&mut self, frame: &CanFrame) -> Result<(), CandumpError> {
        let mut buf = [0u8; LINE_BUF];
        let line = Line { time_us: self.timestamp_us, iface: IFACE, frame };
        let len = line.encode(&mut buf).ok_or(CandumpError::LineTooLong)?;
        let newline = buf.get_mut(len).ok_or(CandumpError::LineTooLong)?;
        *newline = b'\n';
        crate::console::write_stdout(buf.get(..=len).ok_or(CandumpError::LineTooLong)?);
        self.sent = self.sent.wrapping_add(1);
        Ok(())
    }

    fn receive(&mut self) -> Result<CanFrame, CandumpError> {
        Err(CandumpError::ReceiveUnsupported)
    }
}
