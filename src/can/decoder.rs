//! Receiver side: a stream decoder with per-message rolling-counter tracking.
//!
//! Checks, in order: remote frame, identifier, length, CRC, counter, signal values. A frame
//! that fails any check is flagged with a [`FrameError`] and yields no report; the decoder
//! never panics on any input.
//!
//! Counter rule (per message; `d = (received − last accepted) mod 16`):
//! - first frame after construction or [`Decoder::reset`]: accepted (nothing to compare with);
//! - `d = 1`: in sequence, accepted;
//! - `d = 0`: [`FrameError::RepeatedCounter`] (repeated or replayed frame);
//! - `d = 2..=8`: [`FrameError::SkippedCounter`] (`d − 1` frames lost); the frame is flagged
//!   and the tracker resynchronises to it, so the next in-sequence frame is accepted;
//! - `d = 9..=15`: [`FrameError::OutOfOrder`] (stale, reordered or replayed); no resync, so a
//!   late frame cannot disturb the live sequence. After [`RESYNC_AFTER`] consecutive
//!   out-of-order frames the tracker resynchronises to the newest one (the sender restarted).
//!
//! Heartbeat rule ([`Decoder::receive`], which knows the receive time): the status frame is the
//! monitor's heartbeat (1 Hz). When a status frame with a valid CRC was seen before but none in
//! the last [`HEARTBEAT_TIMEOUT_US`], the monitor was lost (power cycle, bus-off, a gap between
//! two recordings in a log). The decoder then forgets its counter history for both messages,
//! so the restarted sender's sequence (counters from 0 again) is accepted at once instead of
//! being flagged as repeated or skipped, and tells the caller, who shows the loss. The price is
//! that a frame replayed right after such a silence is not recognised as a replay; for a
//! report-only display message that is acceptable (see can/README.md).

use super::codec::{check_frame, decode_signals, FrameError, MessageKind, Report};
use super::layout::STATUS;

/// Consecutive out-of-order frames after which the counter tracker accepts the new sequence.
pub const RESYNC_AFTER: u8 = 3;

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct CounterTracker {
    last: Option<u8>,
    out_of_order_run: u8,
}

impl CounterTracker {
    fn check(&mut self, counter: u8) -> Result<(), FrameError> {
        let counter = counter & 0xF;
        let Some(last) = self.last else {
            self.last = Some(counter);
            return Ok(());
        };
        let expected = last.wrapping_add(1) & 0xF;
        match counter.wrapping_sub(last) & 0xF {
            1 => {
                self.last = Some(counter);
                self.out_of_order_run = 0;
                Ok(())
            }
            0 => {
                self.out_of_order_run = 0;
                Err(FrameError::RepeatedCounter { counter })
            }
            2..=8 => {
                self.last = Some(counter);
                self.out_of_order_run = 0;
                Err(FrameError::SkippedCounter { expected, got: counter })
            }
            _ => {
                self.out_of_order_run = self.out_of_order_run.saturating_add(1);
                if self.out_of_order_run >= RESYNC_AFTER {
                    self.last = Some(counter);
                    self.out_of_order_run = 0;
                }
                Err(FrameError::OutOfOrder { expected, got: counter })
            }
        }
    }
}

/// Silence of the heartbeat (no status frame with a valid CRC) after which the monitor counts
/// as lost: three status cycles (3 s).
pub const HEARTBEAT_TIMEOUT_US: u64 = 3 * STATUS.cycle_ms as u64 * 1000;

/// What [`Decoder::receive`] made of one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reception {
    /// The report, or why the frame was flagged and skipped.
    pub result: Result<Report, FrameError>,
    /// `Some(silence in µs)` when this frame came after the heartbeat had been silent for longer
    /// than [`HEARTBEAT_TIMEOUT_US`]: the monitor was lost and counter tracking restarted
    /// before this frame was checked.
    pub heartbeat_lost_us: Option<u64>,
}

/// Stream decoder of the monitor's frames, one counter tracker per message.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Decoder {
    trackers: [CounterTracker; 2],
    /// Receive time of the last status frame with a valid CRC ([`Decoder::receive`] only).
    last_heartbeat_us: Option<u64>,
}

impl Decoder {
    /// A decoder that has seen nothing yet.
    pub const fn new() -> Self {
        Self { trackers: [CounterTracker { last: None, out_of_order_run: 0 }; 2], last_heartbeat_us: None }
    }

    /// Decodes one frame received at `now_us` (µs of a monotonic receive clock, e.g. a log's
    /// time stamps): the heartbeat rule of the module doc, then [`Decoder::decode`]. A clock
    /// that goes backwards counts as no silence.
    pub fn receive(&mut self, now_us: u64, frame: &impl embedded_can::Frame) -> Reception {
        let mut heartbeat_lost_us = None;
        if let Some(last) = self.last_heartbeat_us {
            let silence = now_us.saturating_sub(last);
            if silence > HEARTBEAT_TIMEOUT_US {
                self.reset();
                heartbeat_lost_us = Some(silence);
            }
        }
        let result = self.decode(frame);
        let heartbeat = match result {
            Ok(Report::Status(_)) => true,
            // A CRC-valid status frame flagged only for its counter or a signal value still
            // shows that the monitor is alive.
            Err(
                FrameError::RepeatedCounter { .. }
                | FrameError::SkippedCounter { .. }
                | FrameError::OutOfOrder { .. }
                | FrameError::InvalidSignal { .. },
            ) => matches!(MessageKind::of(frame), Ok(MessageKind::Status)),
            _ => false,
        };
        if heartbeat {
            self.last_heartbeat_us = Some(now_us);
        }
        Reception { result, heartbeat_lost_us }
    }

    /// Forgets the counter and heartbeat history (for example after a bus-off).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Decodes one received frame. Frames that are not the monitor's (other identifiers,
    /// remote frames) come back as errors too, so the caller can count or ignore them.
    pub fn decode(&mut self, frame: &impl embedded_can::Frame) -> Result<Report, FrameError> {
        let (kind, bits, counter) = check_frame(frame)?;
        let tracker = match kind {
            MessageKind::Fault => &mut self.trackers[0],
            MessageKind::Status => &mut self.trackers[1],
        };
        tracker.check(counter)?;
        decode_signals(kind, bits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(seq: &[u8]) -> [Option<&'static str>; 16] {
        let mut t = CounterTracker::default();
        let mut out = [None; 16];
        for (o, &c) in out.iter_mut().zip(seq) {
            *o = t.check(c).err().map(|e| e.label());
        }
        out
    }

    #[test]
    fn counter_rules() {
        let r = run(&[0, 1, 2, 3]);
        assert_eq!(r[..4], [None; 4]);
        // Reordered 2 and 1: 2 skips one, 1 is late; 3 then continues the sequence.
        let r = run(&[0, 2, 1, 3]);
        assert_eq!(r[..4], [None, Some("skipped_counter"), Some("out_of_order"), None]);
        // Dropped frame.
        let r = run(&[14, 15, 1, 2]);
        assert_eq!(r[..4], [None, None, Some("skipped_counter"), None]);
        // Replayed frame.
        let r = run(&[5, 6, 6, 7]);
        assert_eq!(r[..4], [None, None, Some("repeated_counter"), None]);
        // Sender restart: three out-of-order frames, then resync.
        let r = run(&[2, 3, 0, 1, 2, 3]);
        assert_eq!(r[..6], [None, None, Some("out_of_order"), Some("out_of_order"), Some("out_of_order"), None]);
    }
}
