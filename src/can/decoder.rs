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

use super::codec::{check_frame, decode_signals, FrameError, MessageKind, Report};

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

/// Stream decoder of the monitor's frames, one counter tracker per message.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Decoder {
    trackers: [CounterTracker; 2],
}

impl Decoder {
    /// A decoder that has seen nothing yet.
    pub const fn new() -> Self {
        Self { trackers: [CounterTracker { last: None, out_of_order_run: 0 }; 2] }
    }

    /// Forgets the counter history (for example after a bus-off or a long gap).
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
