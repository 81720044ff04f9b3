//! Encoding and stateless decoding of the two frames, with the E2E CRC.
//!
//! E2E scheme (in the style of AUTOSAR E2E profile 11, with SecOC-style implicit freshness):
//! byte 0 carries a CRC-8 SAE J1850 (polynomial 0x1D, initial value 0xFF, final XOR 0xFF)
//! computed over the message's 16-bit data ID (low byte first, not transmitted), for the fault
//! report then the sender's [`Binding`] (fleet number and release count; not transmitted in the
//! fault report), then data bytes 1..8. Byte 1 starts with the message's counter (4 bits in the
//! fault report, 12 in the status frame). The data ID differs per message, so a frame that
//! shows up under the wrong identifier fails its CRC; the binding in the fault report's CRC ties
//! each report to one locomotive and one release. The session frame (layout 3) carries the full
//! release count and fleet number, of which the status frame's release number and locomotive are
//! the low 6 bits, so a receiver tells a release, and its reports (layout 3.2), from the one 64
//! releases earlier.

use super::frame::CanFrame;
use super::layout::{self as l, Message, Signal};
use crate::fault::FaultClass;
use crate::report::{EstimatorState, FaultReport, NoDiagnosis, StatusReport, Verdict};
use crate::sensor::SensorFault;

/// Who sends and in which release: the locomotive's number and the release number, 6 bits
/// each (higher bits are dropped). Sent in every status frame; the fault report's CRC binds them
/// in full ([`Binding`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Identity {
    /// The locomotive the monitor is fitted to ([`l::LOCOMOTIVE`]).
    pub locomotive: u8,
    /// The release number ([`l::RELEASE_NUMBER`]).
    pub release: u8,
}

impl Identity {
    /// The identity with both numbers cut to their 6 bits.
    pub const fn masked(self) -> Self {
        Self { locomotive: self.locomotive & 0x3F, release: self.release & 0x3F }
    }
}

/// What a fault report's CRC binds besides its payload (layout 3.2; SecOC-style implicit
/// freshness, not transmitted in the report): the locomotive's fleet number and the full release
/// count. Layout 3.1 bound their low 6 bits only (the status frame's [`Identity`]), so a report
/// of the release 64 releases earlier, put in place of the genuine one at the same time since
/// the release, passed its CRC (tenth black-box tester, O1). The status frames carry the low 6
/// bits and the session frames the rest, so a receiver that heard the locomotive's count
/// rebuilds the binding of every release number within 32 of it ([`Self::for_release`]).
///
/// The CRC covers the fleet number's and the count's low bytes where layout 3.1 had the 6-bit
/// numbers, and their higher bytes after them when any is not zero: a unit whose numbers are
/// both below 64 seals exactly as layout 3.1 did (recorded logs of such units stay valid).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Binding {
    /// The locomotive's fleet number (12 bits used; [`l::SESSION_LOCOMOTIVE`] and
    /// [`l::SESSION_LOCOMOTIVE_HIGH`]).
    pub fleet: u16,
    /// The release count ([`l::RELEASE_COUNT`]; its low 6 bits are the release number).
    pub release_count: u32,
}

impl Binding {
    /// The identity the status frames carry for this binding (the low 6 bits of each number).
    pub const fn identity(self) -> Identity {
        Identity { locomotive: (self.fleet & 0x3F) as u8, release: (self.release_count & 0x3F) as u8 }
    }

    /// The binding of release number `release` (6 bits) of the same locomotive: the count within
    /// 32 releases of this one, either way, whose low 6 bits are `release` (how SecOC rebuilds a
    /// freshness value from its transmitted low bits).
    pub const fn for_release(self, release: u8) -> Self {
        let k = ((release.wrapping_sub(self.release_count as u8)) & 0x3F) as i32;
        let release_count = self.release_count.wrapping_add_signed(if k >= 32 { k - 64 } else { k });
        Self { fleet: self.fleet, release_count }
    }

    /// The fleet number and release count of a unit whose numbers are both below 64, the only
    /// case in which the 6-bit identity gives them (a receiver that has not heard the
    /// locomotive's session frame yet can check nothing else).
    pub const fn young(identity: Identity) -> Self {
        let id = identity.masked();
        Self { fleet: id.locomotive as u16, release_count: id.release as u32 }
    }
}

/// The largest fleet number a session frame carries (12 bits: [`l::SESSION_LOCOMOTIVE`] and
/// [`l::SESSION_LOCOMOTIVE_HIGH`]).
pub const MAX_FLEET_NUMBER: u16 = 4095;

/// The locomotive number of a locomotive's name as data sets write it (`loco-05` → 5): the low
/// 6 bits (the width of [`l::LOCOMOTIVE`]) of its [`fleet_number`]; `None` where that is `None`.
pub fn locomotive_number(name: &str) -> Option<u8> {
    fleet_number(name).map(|n| (n & 0x3F) as u8)
}

/// The fleet number the session frame carries for a locomotive named `name`: the decimal
/// digits at its end (`loco-71` → 71, `loco-0071` → 71); 0 without digits. `None` when they
/// exceed [`MAX_FLEET_NUMBER`]: the frames cannot carry that number, and wrapping it would make
/// the locomotive indistinguishable from the one 4096 below it, so a caller refuses it.
pub fn fleet_number(name: &str) -> Option<u16> {
    let name = name.trim();
    let digits = name.bytes().rev().take_while(u8::is_ascii_digit).count();
    let mut v: u16 = 0;
    for d in name.bytes().skip(name.len() - digits) {
        v = v.checked_mul(10)?.checked_add(u16::from(d - b'0'))?;
        if v > MAX_FLEET_NUMBER {
            return None;
        }
    }
    Some(v)
}

/// CRC-8 SAE J1850 of one nibble shifted through the register (`T[n]` = CRC step of `n << 4`):
/// a 16-byte table instead of the usual 256 bytes (flash), two lookups a byte.
const CRC8_NIBBLE: [u8; 16] = {
    let mut t = [0u8; 16];
    let mut n = 0;
    while n < 16 {
        let mut c = (n as u8) << 4;
        let mut k = 0;
        while k < 4 {
            c = if c & 0x80 != 0 { (c << 1) ^ 0x1D } else { c << 1 };
            k += 1;
        }
        t[n] = c;
        n += 1;
    }
    t
};

/// Feeds bytes through a CRC-8 SAE J1850 register (polynomial 0x1D, MSB first). Never inlined:
/// one copy of the loop serves every piece the E2E CRC covers (flash).
#[inline(never)]
fn crc8_update(mut crc: u8, bytes: &[u8]) -> u8 {
    for &b in bytes {
        crc ^= b;
        crc = (crc << 4) ^ CRC8_NIBBLE[usize::from(crc >> 4)];
        crc = (crc << 4) ^ CRC8_NIBBLE[usize::from(crc >> 4)];
    }
    crc
}

/// CRC-8 SAE J1850 (initial value 0xFF, final XOR 0xFF; check value 0x4B for "123456789").
pub fn crc8_sae_j1850(bytes: &[u8]) -> u8 {
    crc8_update(0xFF, bytes) ^ 0xFF
}

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
    /// Not newer than what was accepted from that message: a repetition, a replay, or the late
    /// frame of a reordered pair.
    Stale {
        /// Counter of the last accepted frame (fault report: its time since release, 0.1 s).
        last: u16,
        /// Counter received (fault report: its time since release, 0.1 s).
        got: u16,
    },
    /// Its freshness does not match the time it arrived (more than the receive tolerance): a
    /// delayed frame, or a replay or insertion at the wrong moment.
    Untimely {
        /// How much later (positive) or earlier (negative) it arrived than its freshness says, ms.
        off_ms: i32,
    },
    /// Sooner after the previous frame of that message than the sender ever sends (status: 1 s;
    /// fault report: 100 ms, 0.75 s for an unchanged one in sequence): a flood or an inserted frame.
    RateExceeded {
        /// Time since the previous accepted frame of that message, ms.
        gap_ms: u32,
    },
    /// A status frame of another locomotive (another monitor on the bus, or frames of another
    /// recording) while one is being followed.
    ForeignSender {
        /// The locomotive number it carries (a session frame's: the 12-bit fleet number).
        locomotive: u16,
    },
    /// A release number that went backwards (an earlier release's frame).
    WrongRelease {
        /// Release number of the session.
        expected: u8,
        /// Release number received.
        got: u8,
    },
    /// A session frame whose release count does not follow what the receiver knows of the
    /// locomotive: behind the newest count seen (a recording of an old session), further ahead
    /// than one release a second since allows, or not the count of the session it belongs to.
    WrongReleaseCount {
        /// The count the receiver knows (the newest seen from the locomotive, or the session's).
        known: u32,
        /// The count received.
        got: u32,
    },
    /// A fault report with the counter of the report held, of its release and on time, but
    /// other content: the sender never sends two reports with one counter, so one of the two is
    /// another sender's whose CRC happens to fit, or a corruption that kept it. The held one is
    /// withdrawn ([`super::Reception::withdrawn`]) and neither is current.
    Conflicting {
        /// The counter both carry.
        counter: u8,
    },
    /// A fault report with no live heartbeat to attribute it to (before the first status frame
    /// or after the heartbeat was lost): its locomotive and release cannot be checked.
    NoHeartbeat,
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
            Self::Stale { .. } => "stale",
            Self::Untimely { .. } => "untimely",
            Self::RateExceeded { .. } => "rate_exceeded",
            Self::ForeignSender { .. } => "foreign_sender",
            Self::WrongRelease { .. } => "wrong_release",
            Self::WrongReleaseCount { .. } => "wrong_release_count",
            Self::Conflicting { .. } => "conflicting",
            Self::NoHeartbeat => "no_heartbeat",
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
            Self::Stale { last, got } => {
                write!(f, "stale: {got} not newer than {last} (repeated, replayed or reordered)")
            }
            Self::Untimely { off_ms } if off_ms >= 0 => write!(f, "untimely: {off_ms} ms late for its freshness"),
            Self::Untimely { off_ms } => write!(f, "untimely: {} ms early for its freshness", -i64::from(off_ms)),
            Self::RateExceeded { gap_ms } => write!(f, "rate exceeded: {gap_ms} ms after the previous frame"),
            Self::ForeignSender { locomotive } => write!(f, "foreign sender: locomotive {locomotive}"),
            Self::WrongRelease { expected, got } => write!(f, "release {got} went backwards (expected {expected})"),
            // Serial-number order (the count wraps at 2³²): behind when more than 2³¹ ahead.
            Self::WrongReleaseCount { known, got } if got.wrapping_sub(known) >= 1 << 31 => {
                write!(f, "release count {got} is behind {known}, seen before from this locomotive (an old recording)")
            }
            Self::WrongReleaseCount { known, got } => {
                write!(f, "release count {got} does not follow {known} (further on than the time allows, or not this session's)")
            }
            Self::Conflicting { counter } => write!(
                f,
                "conflicting: another report with counter {counter} of this release said otherwise (one of the two is \
                 another sender's whose CRC fits; neither is shown)"
            ),
            Self::NoHeartbeat => write!(f, "no heartbeat to attribute it to"),
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
    /// A session frame: the sender's full release count.
    Session(SessionLink),
}

/// Which of the monitor's messages a frame is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MessageKind {
    /// [`l::FAULT_REPORT`].
    Fault = 0,
    /// [`l::STATUS`].
    Status = 1,
    /// [`l::SESSION`].
    Session = 2,
}

impl MessageKind {
    /// Its layout.
    pub const fn layout(self) -> &'static Message {
        match self {
            Self::Fault => &l::FAULT_REPORT,
            Self::Status => &l::STATUS,
            Self::Session => &l::SESSION,
        }
    }

    /// The message a frame identifier belongs to.
    pub fn of(frame: &impl embedded_can::Frame) -> Result<Self, FrameError> {
        let id = super::frame::raw_id(frame.id());
        let extended = frame.is_extended();
        match (extended, id) {
            (true, x) if x == l::FAULT_REPORT.raw_id() => Ok(Self::Fault),
            (true, x) if x == l::STATUS.raw_id() => Ok(Self::Status),
            (true, x) if x == l::SESSION.raw_id() => Ok(Self::Session),
            _ => Err(FrameError::UnknownId { id, extended }),
        }
    }
}

/// The E2E CRC of an 8-byte payload for a data ID (byte 0 of the payload is not included);
/// `binding` (the fault report's) goes into the CRC after the data ID, not on the bus: the low
/// bytes of the fleet number and release count, then, when any of them is not zero, their high
/// bytes ([`Binding`]).
pub fn e2e_crc(data_id: u16, binding: Option<Binding>, payload: &[u8; 8]) -> u8 {
    // The register is fed piece by piece through one out-of-line loop (`crc8_update`): smaller
    // in the image than a buffer laid out first (flash: the extended twin's images are within a
    // hundred bytes of the 32 KiB budget).
    let mut crc = crc8_update(0xFF, &data_id.to_le_bytes());
    if let Some(b) = binding {
        let (f, c) = (b.fleet & 0xFFF, b.release_count);
        let bound = [f as u8, c as u8, (f >> 8) as u8, (c >> 8) as u8, (c >> 16) as u8, (c >> 24) as u8];
        let n = if (u32::from(f) | c) >> 8 == 0 { 2 } else { 6 };
        crc = crc8_update(crc, bound.get(..n).unwrap_or(&bound));
    }
    crc8_update(crc, payload.get(1..).unwrap_or(&[])) ^ 0xFF
}

fn seal(msg: &Message, binding: Option<Binding>, bits: u64) -> CanFrame {
    let mut payload = bits.to_le_bytes();
    payload[0] = e2e_crc(msg.data_id, binding, &payload);
    CanFrame::from_extended(msg.id, payload)
}

/// Rounded division of a `u16` by a small constant, as a raw signal value. In `u32`: a 64-bit
/// division would link the Cortex-M's software `u64` divide (≈ 0.9 KiB of flash).
fn quant(v: u16, per_lsb: u16) -> u64 {
    u64::from((u32::from(v) + u32::from(per_lsb / 2)) / u32::from(per_lsb.max(1)))
}

/// Encodes a fault report with the given rolling counter (only its low 4 bits are used) for a
/// sender's fleet number and release count (bound into the CRC).
///
/// Quantisation (see [`quantize_fault`]): time to 0.1 s, supply to 5 mbar, leak to 1 µm, each
/// rounded to nearest and saturated to its signal's range.
pub fn encode_fault(r: &FaultReport, counter: u8, binding: Binding) -> CanFrame {
    seal_fault(fault_content_bits(r), r.time_since_release_cs, counter, binding)
}

/// The payload bits of a fault report's content: everything but the CRC, the counter and the
/// time since release (the verdict, completed flag, supply and leak at CAN resolution). Two
/// reports with the same content bits say the same on the bus.
pub fn fault_content_bits(r: &FaultReport) -> u64 {
    let mut bits = 0u64;
    let (diag, conf, reason) = match r.verdict {
        Verdict::Class { class, confidence_pct } => (class as u8, confidence_pct, l::reason::NONE),
        Verdict::CannotDiagnose(why) => (l::DIAGNOSIS_CANNOT_DIAGNOSE, 0, reason_code(why)),
    };
    l::DIAGNOSIS.put(&mut bits, u64::from(diag));
    l::CONFIDENCE.put(&mut bits, u64::from(conf));
    l::NO_DIAGNOSIS_REASON.put(&mut bits, u64::from(reason));
    l::RELEASE_COMPLETED.put(&mut bits, u64::from(r.release_completed));
    l::SUPPLY_PRESSURE.put(&mut bits, quant(r.supply_mbar, l::SUPPLY_MBAR_PER_LSB));
    l::LEAK_DIAMETER.put(&mut bits, quant(r.leak_um, l::LEAK_UM_PER_LSB));
    bits
}

/// A fault report frame of the given content bits ([`fault_content_bits`]), time since release
/// (10 ms units), counter and binding.
pub fn seal_fault(content: u64, time_since_release_cs: u16, counter: u8, binding: Binding) -> CanFrame {
    let mut bits = content;
    l::FAULT_COUNTER.put(&mut bits, u64::from(counter & 0xF));
    l::TIME_SINCE_RELEASE.put(&mut bits, quant(time_since_release_cs, l::TIME_CS_PER_LSB));
    seal(&l::FAULT_REPORT, Some(binding), bits)
}

/// What a status frame says about the link besides the [`StatusReport`]: its heartbeat
/// counter, the sender's identity and how many fault reports it has sent.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct StatusLink {
    /// Heartbeat counter (12 bits used).
    pub counter: u16,
    /// Locomotive and release number.
    pub identity: Identity,
    /// Fault reports sent so far, modulo 16 (4 bits used).
    pub fault_count: u8,
}

/// Encodes a status report with its link fields. Lossless for every pressure the transducer
/// can read (below 16.383 bar) and versions up to 15.15; larger values saturate.
pub fn encode_status(s: &StatusReport, link: StatusLink) -> CanFrame {
    let mut bits = 0u64;
    let id = link.identity.masked();
    l::STATUS_COUNTER.put(&mut bits, u64::from(link.counter & 0xFFF));
    l::LOCOMOTIVE.put(&mut bits, u64::from(id.locomotive));
    l::RELEASE_NUMBER.put(&mut bits, u64::from(id.release));
    l::FAULT_REPORT_COUNT.put(&mut bits, u64::from(link.fault_count & 0xF));
    let health = s.sensor_fault.map_or(l::sensor_health::OK, SensorFault::code);
    l::SENSOR_HEALTH.put(&mut bits, u64::from(health));
    l::ESTIMATOR_STATE.put(&mut bits, s.estimator as u64);
    l::CHAMBER_PRESSURE.put(&mut bits, u64::from(s.pressure_mbar));
    l::FIRMWARE_MAJOR.put(&mut bits, u64::from(s.version.0));
    l::FIRMWARE_MINOR.put(&mut bits, u64::from(s.version.1));
    seal(&l::STATUS, None, bits)
}

/// What a session frame says: the heartbeat counter of the status frame it follows, the
/// locomotive and the full release count (whose low 6 bits are the status frame's release
/// number).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct SessionLink {
    /// Heartbeat counter of the status frame sent in the same tick (12 bits used).
    pub counter: u16,
    /// The locomotive's fleet number (12 bits used: the low 6 are the status frame's
    /// locomotive).
    pub locomotive: u16,
    /// Release commands and power-ups since the controller was new (non-volatile; it wraps at
    /// 2³², and receivers compare counts in serial-number order).
    pub release_count: u32,
}

impl SessionLink {
    /// The locomotive as the status frames and fault reports carry it (6 bits).
    pub const fn locomotive_slot(&self) -> u8 {
        (self.locomotive & 0x3F) as u8
    }

    /// The release number (6 bits) the status frames carry for this count.
    pub const fn release(&self) -> u8 {
        (self.release_count & 0x3F) as u8
    }
}

/// Encodes a session frame.
pub fn encode_session(link: SessionLink) -> CanFrame {
    let mut bits = 0u64;
    l::SESSION_STATUS_COUNTER.put(&mut bits, u64::from(link.counter & 0xFFF));
    l::SESSION_LOCOMOTIVE.put(&mut bits, u64::from(link.locomotive & 0x3F));
    l::SESSION_LOCOMOTIVE_HIGH.put(&mut bits, u64::from((link.locomotive >> 6) & 0x3F));
    l::RELEASE_COUNT.put(&mut bits, u64::from(link.release_count));
    seal(&l::SESSION, None, bits)
}

/// The fields of a session payload.
pub fn session_link(bits: u64) -> SessionLink {
    SessionLink {
        counter: l::SESSION_STATUS_COUNTER.get(bits) as u16,
        locomotive: (l::SESSION_LOCOMOTIVE.get(bits) | l::SESSION_LOCOMOTIVE_HIGH.get(bits) << 6) as u16,
        release_count: l::RELEASE_COUNT.get(bits) as u32,
    }
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

/// First stage of decoding: which message, right length. Returns the message kind and the
/// payload as a little-endian `u64`.
pub fn frame_payload(frame: &impl embedded_can::Frame) -> Result<(MessageKind, u64), FrameError> {
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
    Ok((kind, u64::from_le_bytes(payload)))
}

/// The CRC check of a payload: `binding` is the fault report's (ignored for the status and
/// session frames).
pub fn check_crc(kind: MessageKind, bits: u64, binding: Binding) -> Result<(), FrameError> {
    let id = match kind {
        MessageKind::Fault => Some(binding),
        MessageKind::Status | MessageKind::Session => None,
    };
    let expected = e2e_crc(kind.layout().data_id, id, &bits.to_le_bytes());
    let got = l::FAULT_CRC.get(bits) as u8;
    if expected == got {
        Ok(())
    } else {
        Err(FrameError::WrongCrc { expected, got })
    }
}

/// The counter of a payload (fault report: 4 bits; status: 12 bits; session: the 12-bit
/// heartbeat counter of the status frame it follows).
pub fn counter_of(kind: MessageKind, bits: u64) -> u16 {
    match kind {
        MessageKind::Fault => l::FAULT_COUNTER.get(bits) as u16,
        MessageKind::Status => l::STATUS_COUNTER.get(bits) as u16,
        MessageKind::Session => l::SESSION_STATUS_COUNTER.get(bits) as u16,
    }
}

/// The link fields of a status payload.
pub fn status_link(bits: u64) -> StatusLink {
    StatusLink {
        counter: l::STATUS_COUNTER.get(bits) as u16,
        identity: Identity { locomotive: l::LOCOMOTIVE.get(bits) as u8, release: l::RELEASE_NUMBER.get(bits) as u8 },
        fault_count: l::FAULT_REPORT_COUNT.get(bits) as u8,
    }
}

/// Which message, right length, right CRC (for `binding`, when a fault report). Returns the
/// message kind, the payload as a little-endian `u64` and the counter.
pub fn check_frame(frame: &impl embedded_can::Frame, binding: Binding) -> Result<(MessageKind, u64, u16), FrameError> {
    let (kind, bits) = frame_payload(frame)?;
    check_crc(kind, bits, binding)?;
    Ok((kind, bits, counter_of(kind, bits)))
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
        MessageKind::Session => Ok(Report::Session(session_link(bits))),
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

/// Stateless decode of one frame (no freshness check): identifier, length, CRC (a fault report
/// against the given sender's `binding`) and signals. Returns the report and its counter. Use
/// [`super::Decoder`] for a stream.
pub fn decode_frame(frame: &impl embedded_can::Frame, binding: Binding) -> Result<(Report, u16), FrameError> {
    let (kind, bits, counter) = check_frame(frame, binding)?;
    decode_signals(kind, bits).map(|r| (r, counter))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nibble_crc_is_crc_8_sae_j1850() {
        assert_eq!(crc8_sae_j1850(b"123456789"), 0x4B);
        assert_eq!(crc8_sae_j1850(b""), 0x00);
        // Bitwise reference over every single byte and a few strings.
        let bitwise = |bytes: &[u8]| {
            let mut c = 0xFFu8;
            for &b in bytes {
                c ^= b;
                for _ in 0..8 {
                    c = if c & 0x80 != 0 { (c << 1) ^ 0x1D } else { c << 1 };
                }
            }
            c ^ 0xFF
        };
        for b in 0..=255u8 {
            assert_eq!(crc8_sae_j1850(&[b]), bitwise(&[b]));
            assert_eq!(crc8_sae_j1850(&[b, 0x5A, b ^ 0xFF]), bitwise(&[b, 0x5A, b ^ 0xFF]));
        }
    }
}
