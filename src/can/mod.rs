//! CAN reporting to the cab display: frame layout, E2E protection, encoder, stream decoder and
//! transmit schedule. The layout is defined once in `can/brake_monitor.dbc`; [`layout`] is its
//! copy in code, checked against the DBC by `tests/can_dbc.rs`.
//!
//! The monitor only ever transmits the two frames of [`layout::MESSAGES`] (fault report and
//! status, extended identifiers, data frames): no requests, no remote frames, nothing that could
//! command the brake. The decoder flags everything else and yields no report for it.
//!
//! - [`frame`]: a plain frame type implementing [`embedded_can::Frame`].
//! - [`layout`]: identifiers, signals, value codes.
//! - [`codec`]: encoding, E2E CRC, stateless decoding.
//! - [`decoder`]: stream decoder with counter tracking.
//! - [`reporter`]: what to send per monitor sample.

pub mod codec;
pub mod decoder;
pub mod frame;
pub mod layout;
pub mod reporter;

pub use codec::{decode_frame, encode_fault, encode_status, quantize_fault, FrameError, MessageKind, Report};
pub use decoder::Decoder;
pub use frame::CanFrame;
pub use reporter::{CanReporter, Outbox};
