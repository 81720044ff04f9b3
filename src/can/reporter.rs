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
//!
//! The rate bound is the reporter's own: whatever `step` and [`CanReporter::close_tick`] are
//! called with, two fault reports are at least [`FAULT_MIN_GAP_SAMPLES`] apart and two status
//! frames exactly [`STATUS_PERIOD_SAMPLES`] (at most 11 frames per second; a receiver flags
//! anything faster as a flood).
//!
//! Freshness (see `can/README.md`): every status frame carries a 12-bit heartbeat counter, the
//! sender's [`Identity`] (locomotive, release number) and the number of fault reports sent;
//! every fault report carries its 4-bit counter and its time since the release command, and
//! its CRC covers the fleet number and release count in full ([`Binding`]). The release number counts release commands
//! ([`CanReporter::new_release`]) and power-ups ([`CanReporter::set_identity`]) from the value
//! kept across power cycles, so each release and each power cycle has its own number. The
//! session frame carries that count in full (the status frame has room for its low 6 bits
//! only), right after the status frame of a power-up, of a new release number, and every
//! [`SESSION_EVERY_STATUS_FRAMES`] status frames.

use super::codec::{
    encode_session, encode_status, fault_content_bits, seal_fault, Binding, Identity, SessionLink, StatusLink,
};
use super::frame::CanFrame;
use super::layout::SESSION_EVERY_STATUS_FRAMES;
use crate::report::{FaultReport, StatusReport};

/// Samples between status frames (1 s at 100 Hz).
pub const STATUS_PERIOD_SAMPLES: u32 = 100;
/// Samples between repeats of an unchanged fault report during a release (1 s).
pub const FAULT_REPEAT_SAMPLES: u32 = 100;
/// Minimum samples between two fault reports (100 ms).
pub const FAULT_MIN_GAP_SAMPLES: u32 = 10;

/// Frames to send for one sample, in transmit order (fault report, status, session: also the
/// order of their identifiers' bus priority). At most three.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Outbox {
    frames: [CanFrame; 3],
    len: usize,
}

impl Outbox {
    const fn empty() -> Self {
        Self { frames: [CanFrame::from_extended(embedded_can::ExtendedId::ZERO, [0; 8]); 3], len: 0 }
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

/// What a monitor powers up with ([`CanReporter::set_identity`]): the number of the locomotive
/// it is fitted to and the release count it kept in non-volatile memory (0 for a new
/// controller).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct PowerUp {
    /// The locomotive's fleet number (12 bits are sent in the session frame, the low 6 in every
    /// frame).
    pub locomotive: u16,
    /// Release commands and power-ups before this power-up.
    pub release_count: u32,
}

/// Decides, sample by sample, which fault-report, status and session frames to send, and
/// keeps their rolling counters and the release count.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CanReporter {
    /// Samples until the next status frame (0 = this sample).
    status_countdown: u32,
    status_counter: u16,
    fault_counter: u8,
    identity: Identity,
    /// The locomotive's fleet number (12 bits) the session frame carries; `identity.locomotive`
    /// is its low 6 bits.
    fleet_number: u16,
    /// Release commands and power-ups since the controller was new ([`Self::set_identity`]);
    /// `identity.release` is its low 6 bits.
    release_count: u32,
    /// A session frame is due with the next status frame: the release count changed since
    /// the last one (a power-up, a release command).
    session_due: bool,
    /// Content bits of the last fault report sent ([`fault_content_bits`]: at CAN resolution,
    /// without counter and time): the change key.
    last_fault_key: Option<u64>,
    samples_since_fault: u32,
    /// Samples since the release command (the command's sample is 0): the time field of every
    /// fault report sent is at least this, so a closed diagnosis repeated (or withdrawn) while
    /// the valve stays open carries the time it is sent, not the frozen time of its close: a
    /// receiver's freshness check needs a time that moves on.
    samples_since_release: u32,
}

impl Default for CanReporter {
    fn default() -> Self {
        Self::new()
    }
}

impl CanReporter {
    /// A reporter that has sent nothing yet (both counters start at 0; release count 0 until
    /// [`Self::set_identity`]).
    pub const fn new() -> Self {
        Self {
            status_countdown: 0,
            status_counter: 0,
            fault_counter: 0,
            identity: Identity { locomotive: 0, release: 0 },
            fleet_number: 0,
            release_count: 0,
            session_due: true,
            last_fault_key: None,
            samples_since_fault: FAULT_MIN_GAP_SAMPLES,
            samples_since_release: 0,
        }
    }

    /// Power-up with the locomotive's number and the release count kept (in non-volatile
    /// memory) from before it (0 for a new controller). The power-up itself counts as a new
    /// release, so frames after a restart can never be mistaken for frames of the release
    /// before it; the next release command counts one more.
    pub fn set_identity(&mut self, power_up: PowerUp) {
        self.release_count = power_up.release_count.wrapping_add(1);
        self.session_due = true;
        self.fleet_number = power_up.locomotive & 0xFFF;
        self.identity =
            Identity { locomotive: (power_up.locomotive & 0x3F) as u8, release: self.release_count as u8 }.masked();
    }

    /// The release count now (what the controller keeps in non-volatile memory for the next
    /// power-up).
    pub fn release_count(&self) -> u32 {
        self.release_count
    }

    /// The identity the frames carry now.
    pub fn identity(&self) -> Identity {
        self.identity
    }

    /// What the fault reports are sealed with now: the fleet number and the release count
    /// (layout 3.2; the identity is their low 6 bits).
    pub fn binding(&self) -> Binding {
        Binding { fleet: self.fleet_number, release_count: self.release_count }
    }

    /// A new release command: the release number goes up by one, and the next fault report
    /// belongs to a new diagnosis and is sent at once, even when its content equals the
    /// previous release's report.
    pub fn new_release(&mut self) {
        self.release_count = self.release_count.wrapping_add(1);
        self.session_due = true;
        self.identity.release = (self.release_count & 0x3F) as u8;
        self.last_fault_key = None;
        self.samples_since_release = 0;
    }

    /// Call once per monitor sample with the current status, the current fault report (if the
    /// monitor has one) and whether a release is in progress (valve command on).
    pub fn step(&mut self, status: &StatusReport, fault: Option<&FaultReport>, release_active: bool) -> Outbox {
        let mut out = self.fault_frame(fault, release_active, self.samples_since_fault, self.samples_since_release);
        if self.status_countdown == 0 {
            let link =
                StatusLink { counter: self.status_counter, identity: self.identity, fault_count: self.fault_counter };
            out.push(encode_status(status, link));
            if self.session_due || self.status_counter % SESSION_EVERY_STATUS_FRAMES == 0 {
                let (counter, locomotive) = (self.status_counter, self.fleet_number);
                out.push(encode_session(SessionLink { counter, locomotive, release_count: self.release_count }));
                self.session_due = false;
            }
            self.status_counter = (self.status_counter + 1) & 0xFFF;
            self.status_countdown = STATUS_PERIOD_SAMPLES - 1;
        } else {
            self.status_countdown -= 1;
        }
        self.samples_since_fault = self.samples_since_fault.saturating_add(1);
        self.samples_since_release = self.samples_since_release.saturating_add(1);
        out
    }

    /// One more transmit tick within the last sample (the input ended): the fault report if
    /// the schedule allows it, no status frame (the status period is not shortened).
    pub fn close_tick(&mut self, fault: &FaultReport) -> Outbox {
        // `step` already counted the last sample as elapsed.
        let out = self.fault_frame(
            Some(fault),
            false,
            self.samples_since_fault.saturating_sub(1),
            self.samples_since_release.saturating_sub(1),
        );
        if !out.as_slice().is_empty() {
            self.samples_since_fault = 1;
        }
        out
    }

    fn fault_frame(&mut self, fault: Option<&FaultReport>, release_active: bool, elapsed: u32, now: u32) -> Outbox {
        let mut out = Outbox::empty();
        if let Some(report) = fault {
            let key = fault_content_bits(report);
            // The 10 Hz bound holds for every report, including the first of a new release:
            // a chattering valve command cannot push reports faster than that.
            let gap_done = elapsed >= FAULT_MIN_GAP_SAMPLES;
            let due = match self.last_fault_key {
                None => gap_done,
                Some(last) if last != key => gap_done,
                Some(_) => release_active && elapsed >= FAULT_REPEAT_SAMPLES,
            };
            if due {
                let now = now.min(u32::from(u16::MAX)) as u16;
                let time = report.time_since_release_cs.max(now);
                out.push(seal_fault(key, time, self.fault_counter, self.binding()));
                self.fault_counter = (self.fault_counter + 1) & 0xF;
                self.last_fault_key = Some(key);
                self.samples_since_fault = 0;
            }
        }
        out
    }
}
