//! Transmit schedule: per 100 Hz monitor sample, which frames to send. Firmware and host both
//! drive this, so the same inputs give the same frames (counters included).
//!
//! Rates (one sample = 10 ms):
//! - status/heartbeat: every [`STATUS_PERIOD_SAMPLES`] samples (1 Hz), starting with the
//!   first sample;
//! - fault report: at once when a report appears or its content changes (verdict, confidence,
//!   reason, completed flag, or supply/leak at CAN resolution; the time field alone is not a
//!   change), but at most once per [`FAULT_MIN_GAP_SAMPLES`] (10 Hz) whatever the inputs do —
//!   a converging estimate or a chattering valve command cannot flood the bus; a change inside
//!   the gap is sent when the gap ends (only the newest report: a superseded one is dropped). While a release
//!   is active the current report is repeated every [`FAULT_REPEAT_SAMPLES`] samples (1 Hz)
//!   so a display that joins late, or lost a frame, catches up. After the release it is not
//!   repeated: the display holds the last report.

use super::codec::{encode_fault, encode_status, quantize_fault};
use super::frame::CanFrame;
use crate::report::{FaultReport, StatusReport};

/// Samples between status frames (1 s at 100 Hz).
pub const STATUS_PERIOD_SAMPLES: u32 = 100;
/// Samples between repeats of an unchanged fault report during a release (1 s).
pub const FAULT_REPEAT_SAMPLES: u32 = 100;
/// Minimum samples between two fault reports (100 ms).
pub const FAULT_MIN_GAP_SAMPLES: u32 = 10;

/// Frames to send for one sample, in transmit order (fault report first). At most two.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Outbox {
    frames: [CanFrame; 2],
    len: usize,
}

impl Outbox {
    const fn empty() -> Self {
        Self { frames: [CanFrame::from_extended(embedded_can::ExtendedId::ZERO, [0; 8]); 2], len: 0 }
    }

    fn push(&mut self, f: CanFrame) {
        if let Some(slot) = self.frames.get_mut(self.len) {
            *slot = f;
            self.len += 1;
        }
    }

    /// The frames, possibly none.
    pub fn as_slice(&self) -> &[CanFrame] {
        self.frames.get(..self.len).unwrap_or(&[])
    }
}

/// Decides, sample by sample, which fault-report and status frames to send, and keeps their
/// rolling counters.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct CanReporter {
    /// Samples until the next status frame (0 = this sample).
    status_countdown: u32,
    status_counter: u8,
    fault_counter: u8,
    /// Last fault report sent, quantised, with its time field zeroed (the change key).
    last_fault_key: Option<FaultReport>,
    samples_since_fault: u32,
}

impl CanReporter {
    /// A reporter that has sent nothing yet (both counters start at 0).
    pub const fn new() -> Self {
        Self {
            status_countdown: 0,
            status_counter: 0,
            fault_counter: 0,
            last_fault_key: None,
            samples_since_fault: FAULT_MIN_GAP_SAMPLES,
        }
    }

    /// A new release command: the next fault report belongs to a new diagnosis and is sent at
    /// once, even when its content equals the previous release's report.
    pub fn new_release(&mut self) {
        self.last_fault_key = None;
    }

    /// Call once per monitor sample with the current status, the current fault report (if the
    /// monitor has one) and whether a release is in progress (valve command on).
    pub fn step(&mut self, status: &StatusReport, fault: Option<&FaultReport>, release_active: bool) -> Outbox {
        let mut out = Outbox::empty();
        if let Some(report) = fault {
            let key = FaultReport { time_since_release_cs: 0, ..quantize_fault(report) };
            // The 10 Hz bound holds for every report, including the first of a new release:
            // a chattering valve command cannot push reports faster than that.
            let gap_done = self.samples_since_fault >= FAULT_MIN_GAP_SAMPLES;
            let due = match self.last_fault_key {
                None => gap_done,
                Some(last) if last != key => gap_done,
                Some(_) => release_active && self.samples_since_fault >= FAULT_REPEAT_SAMPLES,
            };
            if due {
                out.push(encode_fault(report, self.fault_counter));
                self.fault_counter = (self.fault_counter + 1) & 0xF;
                self.last_fault_key = Some(key);
                self.samples_since_fault = 0;
            }
        }
        if self.status_countdown == 0 {
            out.push(encode_status(status, self.status_counter));
            self.status_counter = (self.status_counter + 1) & 0xF;
            self.status_countdown = STATUS_PERIOD_SAMPLES - 1;
        } else {
            self.status_countdown -= 1;
        }
        self.samples_since_fault = self.samples_since_fault.saturating_add(1);
        out
    }
}
