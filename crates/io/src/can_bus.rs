//! Where frames go and come from: a candump log, a mock bus (tests) or, with the `socketcan`
//! cargo feature on Linux, a SocketCAN interface.
//!
//! For a virtual interface to try it on:
//! ```text
//! sudo ip link add dev vcan0 type vcan
//! sudo ip link set up vcan0
//! ```

use pbm::can::CanFrame;
use std::collections::VecDeque;

/// Something frames can be sent to.
pub trait FrameSink {
    /// Sends one frame, time-stamped `time_us` (a log records it; a bus sends now).
    fn send(&mut self, time_us: u64, frame: &CanFrame) -> std::io::Result<()>;
}

/// Something frames can be received from.
pub trait FrameSource {
    /// The next frame with its time stamp in µs; `Ok(None)` when the source is exhausted.
    fn recv(&mut self) -> std::io::Result<Option<(u64, CanFrame)>>;
}

/// An in-memory bus: frames sent are queued and received in order. Tests use it to play a
/// sender and a receiver, and to drop, repeat, reorder or corrupt frames in between.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MockBus {
    /// Frames in flight, oldest first.
    pub queue: VecDeque<(u64, CanFrame)>,
}

impl MockBus {
    /// An empty bus.
    pub fn new() -> Self {
        Self::default()
    }
}

impl FrameSink for MockBus {
    fn send(&mut self, time_us: u64, frame: &CanFrame) -> std::io::Result<()> {
        self.queue.push_back((time_us, *frame));
        Ok(())
    }
}

impl FrameSource for MockBus {
    fn recv(&mut self) -> std::io::Result<Option<(u64, CanFrame)>> {
        Ok(self.queue.pop_front())
    }
}

impl<S: FrameSink + ?Sized> FrameSink for &mut S {
    fn send(&mut self, time_us: u64, frame: &CanFrame) -> std::io::Result<()> {
        (**self).send(time_us, frame)
    }
}

/// SocketCAN (Linux, `--features socketcan`).
#[cfg(all(feature = "socketcan", target_os = "linux"))]
pub mod socket {
    use super::{FrameSink, FrameSource};
    use pbm::can::CanFrame;
    use socketcan::{CanSocket, EmbeddedFrame, Socket};
    use std::time::{Duration, SystemTime, UNIX_EPOCH};

    /// A raw CAN socket bound to one interface.
    pub struct SocketBus {
        socket: CanSocket,
        /// Stop receiving after this long without a frame (`None`: wait for ever).
        pub idle_timeout: Option<Duration>,
    }

    impl SocketBus {
        /// Opens interface `iface` (e.g. `vcan0`).
        pub fn open(iface: &str) -> std::io::Result<Self> {
            let socket = CanSocket::open(iface)
                .map_err(|e| std::io::Error::new(e.kind(), format!("cannot open CAN interface {iface}: {e}")))?;
            Ok(Self { socket, idle_timeout: None })
        }
    }

    impl FrameSink for SocketBus {
        fn send(&mut self, _time_us: u64, frame: &CanFrame) -> std::io::Result<()> {
            let f = if frame.is_remote_frame() {
                socketcan::CanFrame::new_remote(frame.id(), frame.dlc())
            } else {
                socketcan::CanFrame::new(frame.id(), frame.data())
            }
            .ok_or_else(|| std::io::Error::other("frame not representable by socketcan"))?;
            self.socket.write_frame_insist(&f)
        }
    }

    impl FrameSource for SocketBus {
        fn recv(&mut self) -> std::io::Result<Option<(u64, CanFrame)>> {
            loop {
                let frame = match self.idle_timeout {
                    Some(t) => match self.socket.read_frame_timeout(t) {
                        Ok(f) => f,
                        Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                            return Ok(None)
                        }
                        Err(e) => return Err(e),
                    },
                    None => self.socket.read_frame()?,
                };
                let now = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default();
                let t_us = u64::try_from(now.as_micros()).unwrap_or(u64::MAX);
                // Error frames are bus diagnostics, not data: skip them.
                if let socketcan::CanFrame::Error(_) = frame {
                    continue;
                }
                if let Some(f) = CanFrame::from_frame(&frame) {
                    return Ok(Some((t_us, f)));
                }
            }
        }
    }
}
