//! Encoding and stateless decoding of the two frames, with the E2E CRC.
//!
//! E2E scheme (in the style of AUTOSAR E2E profile 11): byte 0 carries a CRC-8 SAE J1850
//! (polynomial 0x1D, initial value 0xFF, final XOR 0xFF) computed over the message's 16-bit
//! data ID (low byte first, not transmitted) followed by data bytes 1..8; the low nibble of
//! byte 1 carries a rolling counter 0..=15. The data ID differs per message, so a frame that
//! shows up under the wrong identifier fails its CRC.

use super::frame::CanFrame;
use super::layout::{self as l, Message, Signal};
use crate::fault::FaultClass;
use crate::report::{EstimatorState, FaultReport, NoDiagnosis, StatusReport, Verdict};
use crate::sensor::SensorFault;
use crc::{Crc, CRC_8_SAE_J1850};

const CRC8: Crc<u8> = Crc::<u8>::new(&CRC_8_SAE_J1850);

/// Why a frame is not a valid report. Small and `Copy` so the firmware and the host can count,
/// log and display it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameError {
    /// The identifier is not one of the monitor's (or is a standard identifier).
    UnknownId {
        /// Raw identifier (11 or 29 bits).
        id: u32,
        /// The identifier is extended.
        extended: bool,
    },
    /// A remote (RTR) frame: the monitor never sends or answers them.
    RemoteFrame {
        /// Raw identifier.
        id: u32,
    },
    /// The data length differs from the DBC.
    WrongLength {
        /// Length the DBC defines.
        expected: u8,
        /// Length received.
        got: u8,
    },
    /// The E2E CRC does not match the payload.
    WrongCrc {
        /// CRC computed over the received payload.
        expected: u8,
        /// CRC received in byte 0.
        got: u8,
    },
    /// The counter equals the previous frame's: a repeated or replayed frame.
    RepeatedCounter {
        /// The counter received.
        counter: u8,
    },
    /// The counter jumped ahead: frames were lost.
    SkippedCounter {
        /// Counter expected.
        expected: u8,
        /// Counter received.
        got: u8,
    },
    /// The counter went backwards: a stale, reordered or replayed frame.
    OutOfOrder {
        /// Counter expected.
        expected: u8,
        /// Counter received.
        got: u8,
    },
    /// CRC and counter are good but a signal holds a value the DBC does not define (or a
    /// reserved bit is set): the sender is broken or speaks another layout version.
    InvalidSignal {
        /// DBC name of the offending signal (`"reserved"` for reserved bits).
        signal: &'static str,
        /// Its raw value.
        raw: u16,
    },
}

impl FrameError {
    /// Short stable label, used in summaries.
    pub const fn label(&self) -> &'static str {
        match self {
            Self::UnknownId { .. } => "unknown_id",
            Self::RemoteFrame { .. } => "remote_frame",
            Self::WrongLength { .. } => "wrong_length",
            Self::WrongCrc { .. } => "wrong_crc",
            Self::RepeatedCounter { .. } => "repeated_counter",
            Self::SkippedCounter { .. } => "skipped_counter",
            Self::OutOfOrder { .. } => "out_of_order",
            Self::InvalidSignal { .. } => "invalid_signal",
        }
    }
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::UnknownId { id, extended: true } => write!(f, "unknown id {id:08X}"),
            Self::UnknownId { id, extended: false } => write!(f, "unknown id {id:03X} (standard)"),
            Self::RemoteFrame { id } => write!(f, "remote frame for id {id:X}"),
            Self::WrongLength { expected, got } => write!(f, "wrong length {got} (expected {expected})"),
            Self::WrongCrc { expected, got } => write!(f, "wrong CRC {got:02X} (expected {expected:02X})"),
            Self::RepeatedCounter { counter } => write!(f, "repeated counter {counter}"),
            Self::SkippedCounter { expected, got } => {
                write!(f, "skipped counter {got} (expected {expected}, {} lost)", got.wrapping_sub(expected) & 0xF)
            }
            Self::OutOfOrder { expected, got } => write!(f, "counter {got} out of order (expected {expected})"),
            Self::InvalidSignal { signal, raw } => write!(f, "invalid value {raw} in signal {signal}"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for FrameError {}

/// A report decoded from a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Report {
    /// A fault report.
    Fault(FaultReport),
    /// A status/heartbeat.
    Status(StatusReport),
}

/// Which of the monitor's messages a frame is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MessageKind {
    /// [`l::FAULT_REPORT`].
    Fault = 0,
    /// [`l::STATUS`].
    Status = 1,
}

impl MessageKind {
    /// Its layout.
    pub const fn layout(self) -> &'static Message {
        match self {
            Self::Fault => &l::FAULT_REPORT,
            Self::Status => &l::STATUS,
        }
    }

    /// The message a frame identifier belongs to.
    pub fn of(frame: &impl embedded_can::Frame) -> Result<Self, FrameError> {
        let id = super::frame::raw_id(frame.id());
        let extended = frame.is_extended();
        match (extended, id) {
            (true, x) if x == l::FAULT_REPORT.raw_id() => Ok(Self::Fault),
            (true, x) if x == l::STATUS.raw_id() => Ok(Self::Status),
            _ => Err(FrameError::UnknownId { id, extended }),
        }
    }
}

/// The E2E CRC of an 8-byte payload for a data ID (byte 0 of the payload is not included).
pub fn e2e_crc(data_id: u16, payload: &[u8; 8]) -> u8 {
    let mut d = CRC8.digest();
    d.update(&data_id.to_le_bytes());
    d.update(payload.get(1..).unwrap_or(&[]));
    d.finalize()
}

fn seal(msg: &Message, counter_sig: &Signal, crc_sig: &Signal, mut bits: u64, counter: u8) -> CanFrame {
    counter_sig.put(&mut bits, u64::from(counter & 0xF));
    let mut payload = bits.to_le_bytes();
    let crc = e2e_crc(msg.data_id, &payload);
    crc_sig.put(&mut bits, u64::from(crc));
    payload = bits.to_le_bytes();
    CanFrame::from_extended(msg.id, payload)
}

/// Rounded division of a `u16` by a small constant, as a raw signal value. In `u32`: a 64-bit
/// division would link the Cortex-M's software `u64` divide (≈ 0.9 KiB of flash).
fn quant(v: u16, per_lsb: u16) -> u64 {
    u64::from((u32::from(v) + u32::from(per_lsb / 2)) / u32::from(per_lsb.max(1)))
}

/// Encodes a fault report with the given rolling counter (only its low 4 bits are used).
///
/// Quantisation (see [`quantize_fault`]): time to 0.1 s, supply to 5 mbar, leak to 1 µm, each
/// rounded to nearest and saturated to its signal's range.
pub fn encode_fault(r: &FaultReport, counter: u8) -> CanFrame {
    let mut bits = 0u64;
    let (diag, conf, reason) = match r.verdict {
        Verdict::Class { class, confidence_pct } => (class as u8, confidence_pct, l::reason::NONE),
        Verdict::CannotDiagnose(why) => (l::DIAGNOSIS_CANNOT_DIAGNOSE, 0, reason_code(why)),
    };
    l::DIAGNOSIS.put(&mut bits, u64::from(diag));
    l::CONFIDENCE.put(&mut bits, u64::from(conf));
    l::NO_DIAGNOSIS_REASON.put(&mut bits, u64::from(reason));
    l::RELEASE_COMPLETED.put(&mut bits, u64::from(r.release_completed));
    l::TIME_SINCE_RELEASE.put(&mut bits, quant(r.time_since_release_cs, l::TIME_CS_PER_LSB));
    l::SUPPLY_PRESSURE.put(&mut bits, quant(r.supply_mbar, l::SUPPLY_MBAR_PER_LSB));
    l::LEAK_DIAMETER.put(&mut bits, quant(r.leak_um, l::LEAK_UM_PER_LSB));
    seal(&l::FAULT_REPORT, &l::FAULT_COUNTER, &l::FAULT_CRC, bits, counter)
}

/// Encodes a status report with the given rolling counter (only its low 4 bits are used).
/// Lossless.
pub fn encode_status(s: &StatusReport, counter: u8) -> CanFrame {
    let mut bits = 0u64;
    let health = s.sensor_fault.map_or(l::sensor_health::OK, SensorFault::code);
    l::SENSOR_HEALTH.put(&mut bits, u64::from(health));
    l::ESTIMATOR_STATE.put(&mut bits, s.estimator as u64);
    l::CHAMBER_PRESSURE.put(&mut bits, u64::from(s.pressure_mbar));
    l::FIRMWARE_MAJOR.put(&mut bits, u64::from(s.version.0));
    l::FIRMWARE_MINOR.put(&mut bits, u64::from(s.version.1));
    seal(&l::STATUS, &l::STATUS_COUNTER, &l::STATUS_CRC, bits, counter)
}

/// The report a receiver decodes from [`encode_fault`]'s frame: fields rounded to the signal
/// resolutions and saturated. Idempotent.
pub fn quantize_fault(r: &FaultReport) -> FaultReport {
    let back = |v: u16, per: u16, sig: &Signal| -> u16 {
        let raw = quant(v, per).min(sig.max_raw());
        (raw as u16).saturating_mul(per)
    };
    FaultReport {
        verdict: r.verdict,
        time_since_release_cs: back(r.time_since_release_cs, l::TIME_CS_PER_LSB, &l::TIME_SINCE_RELEASE),
        supply_mbar: back(r.supply_mbar, l::SUPPLY_MBAR_PER_LSB, &l::SUPPLY_PRESSURE),
        leak_um: back(r.leak_um, l::LEAK_UM_PER_LSB, &l::LEAK_DIAMETER),
        release_completed: r.release_completed,
    }
}

/// `NoDiagnosisReason` code of a reason.
pub fn reason_code(why: NoDiagnosis) -> u8 {
    match why {
        NoDiagnosis::SensorFault(f) => f.code(),
        NoDiagnosis::TooShort => l::reason::TOO_SHORT,
        NoDiagnosis::Unfamiliar => l::reason::UNFAMILIAR,
    }
}

fn invalid(sig: &Signal, raw: u64) -> FrameError {
    FrameError::InvalidSignal { signal: sig.name, raw: raw.min(u64::from(u16::MAX)) as u16 }
}

/// First stage of decoding: which message, right length, right CRC. Returns the message kind,
/// the payload as a little-endian `u64` and the rolling counter.
pub fn check_frame(frame: &impl embedded_can::Frame) -> Result<(MessageKind, u64, u8), FrameError> {
    if frame.is_remote_frame() {
        return Err(FrameError::RemoteFrame { id: super::frame::raw_id(frame.id()) });
    }
    let kind = MessageKind::of(frame)?;
    let msg = kind.layout();
    let data = frame.data();
    let payload: [u8; 8] = match data.try_into() {
        Ok(p) if data.len() == usize::from(msg.dlc) => p,
        _ => return Err(FrameError::WrongLength { expected: msg.dlc, got: data.len().min(255) as u8 }),
    };
    let bits = u64::from_le_bytes(payload);
    let (crc_sig, counter_sig) = match kind {
        MessageKind::Fault => (&l::FAULT_CRC, &l::FAULT_COUNTER),
        MessageKind::Status => (&l::STATUS_CRC, &l::STATUS_COUNTER),
    };
    let expected = e2e_crc(msg.data_id, &payload);
    let got = crc_sig.get(bits) as u8;
    if expected != got {
        return Err(FrameError::WrongCrc { expected, got });
    }
    Ok((kind, bits, counter_sig.get(bits) as u8))
}

/// Last stage of decoding: the signals of a payload that passed [`check_frame`].
pub fn decode_signals(kind: MessageKind, bits: u64) -> Result<Report, FrameError> {
    let reserved = bits & kind.layout().reserved_mask();
    if reserved != 0 {
        return Err(FrameError::InvalidSignal {
            signal: "reserved",
            raw: (reserved >> reserved.trailing_zeros()) as u16,
        });
    }
    match kind {
        MessageKind::Fault => decode_fault_signals(bits).map(Report::Fault),
        MessageKind::Status => decode_status_signals(bits).map(Report::Status),
    }
}

fn decode_fault_signals(bits: u64) -> Result<FaultReport, FrameError> {
    let diag = l::DIAGNOSIS.get(bits);
    let conf = l::CONFIDENCE.get(bits);
    let reason = l::NO_DIAGNOSIS_REASON.get(bits);
    let verdict = if diag == u64::from(l::DIAGNOSIS_CANNOT_DIAGNOSE) {
        let why = match reason as u8 {
            l::reason::TOO_SHORT => NoDiagnosis::TooShort,
            l::reason::UNFAMILIAR => NoDiagnosis::Unfamiliar,
            code => match SensorFault::from_code(code) {
                Some(f) => NoDiagnosis::SensorFault(f),
                None => return Err(invalid(&l::NO_DIAGNOSIS_REASON, reason)),
            },
        };
        if conf != 0 {
            return Err(invalid(&l::CONFIDENCE, conf));
        }
        Verdict::CannotDiagnose(why)
    } else {
        let class = FaultClass::from_code(diag as u8).ok_or(invalid(&l::DIAGNOSIS, diag))?;
        if reason != u64::from(l::reason::NONE) {
            return Err(invalid(&l::NO_DIAGNOSIS_REASON, reason));
        }
        if conf > u64::from(l::CONFIDENCE_MAX_PCT) {
            return Err(invalid(&l::CONFIDENCE, conf));
        }
        Verdict::Class { class, confidence_pct: conf as u8 }
    };
    // Each raw value is at most 12 bits, so the products fit a u16 (4095 · 10 = 40950).
    Ok(FaultReport {
        verdict,
        time_since_release_cs: (l::TIME_SINCE_RELEASE.get(bits) as u16).saturating_mul(l::TIME_CS_PER_LSB),
        supply_mbar: (l::SUPPLY_PRESSURE.get(bits) as u16).saturating_mul(l::SUPPLY_MBAR_PER_LSB),
        leak_um: (l::LEAK_DIAMETER.get(bits) as u16).saturating_mul(l::LEAK_UM_PER_LSB),
        release_completed: l::RELEASE_COMPLETED.get(bits) == 1,
    })
}

fn decode_status_signals(bits: u64) -> Result<StatusReport, FrameError> {
    let health = l::SENSOR_HEALTH.get(bits);
    let sensor_fault = match health as u8 {
        l::sensor_health::OK => None,
        code => Some(SensorFault::from_code(code).ok_or(invalid(&l::SENSOR_HEALTH, health))?),
    };
    let estimator = match l::ESTIMATOR_STATE.get(bits) {
        0 => EstimatorState::Idle,
        1 => EstimatorState::Converging,
        2 => EstimatorState::Settled,
        _ => EstimatorState::Frozen,
    };
    Ok(StatusReport {
        sensor_fault,
        estimator,
        pressure_mbar: l::CHAMBER_PRESSURE.get(bits) as u16,
        version: (l::FIRMWARE_MAJOR.get(bits) as u8, l::FIRMWARE_MINOR.get(bits) as u8),
    })
}

/// Stateless decode of one frame (no counter check): identifier, length, CRC and signals.
/// Returns the report and its rolling counter. Use [`super::Decoder`] for a stream.
pub fn decode_frame(frame: &impl embedded_can::Frame) -> Result<(Report, u8), FrameError> {
    let (kind, bits, counter) = check_frame(frame)?;
    decode_signals(kind, bits).map(|r| (r, counter))
}
