//! CAN reporting to the cab display: frame layout, E2E protection, encoder, stream decoder and
//! transmit schedule. The layout is defined once in `can/brake_monitor.dbc`; [`layout`] is its
//! copy in code, checked against the DBC by `tests/can_dbc.rs`.
//!
//! # The monitor never commands the brake
//!
//! The monitor only ever transmits the three frames of [`layout::MESSAGES`] (fault report,
//! status and session, extended identifiers, 8-byte data frames): no requests, no remote frames, nothing
//! that could command the brake or any other device. Nothing in this crate acts on a received
//! frame: the monitor's only inputs are the ADC reading and the valve command, passed as
//! arguments ([`crate::monitor::Monitor::update`], [`crate::pipeline::Pipeline::step`]); no
//! function takes a frame and changes the monitor's state or drives an output. The [`decoder`]
//! is for receivers (the cab display, the host tools); it flags everything that is not one of
//! the three messages and yields no report for it. `tests/can_codec.rs` checks that the pipeline
//! emits nothing but these three identifiers, whatever its inputs.
//!
//! - [`frame`]: a plain frame type implementing [`embedded_can::Frame`].
//! - [`layout`]: identifiers, signals, value codes.
//! - [`codec`]: encoding, E2E CRC, stateless decoding.
//! - [`decoder`]: stream decoder with freshness checks (counters, release, receive time, rate).
//! - [`reporter`]: what to send per monitor sample.
//! - [`candump`]: candump log lines of frames (the firmware's CAN stand-in in QEMU and the
//!   host's logs write the same bytes).

pub mod candump;
pub mod codec;
pub mod decoder;
pub mod frame;
pub mod layout;
pub mod reporter;

pub use codec::{
    decode_frame, encode_fault, encode_session, encode_status, quantize_fault, Binding, FrameError, Identity,
    MessageKind, Report, SessionLink, StatusLink,
};
pub use decoder::{Decoder, Reception, HEARTBEAT_TIMEOUT_US, MAX_LATENCY_STEP_US, MAX_RELOCK_US, RELOCK_RUN};
pub use frame::CanFrame;
pub use reporter::{CanReporter, Outbox, PowerUp};
