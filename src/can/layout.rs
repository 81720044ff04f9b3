//! The bit layout of the monitor's CAN frames: the one copy in code of what
//! `can/brake_monitor.dbc` says. `tests/can_dbc.rs` parses the DBC and checks every message
//! and signal here against it (id, length, start bit, size, byte order, sign, factor, offset,
//! range, value tables), so the two cannot drift apart silently.
//!
//! All signals are unsigned and Intel (little-endian, DBC `@1+`): the 8 data bytes are read as
//! one little-endian `u64` and a signal occupies bits `start_bit .. start_bit + len` of it.

use embedded_can::ExtendedId;

/// One signal of a message, as declared in the DBC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Signal {
    /// DBC signal name.
    pub name: &'static str,
    /// Start bit (LSB) in Intel numbering: bit `i` is bit `i % 8` of byte `i / 8`.
    pub start_bit: u8,
    /// Length in bits (1..=16 here, 32 for the release count).
    pub len: u8,
    /// Physical value = raw · factor + offset.
    pub factor: f64,
    /// Physical value = raw · factor + offset.
    pub offset: f64,
    /// Smallest physical value (DBC `[min|max]`).
    pub min: f64,
    /// Largest physical value (DBC `[min|max]`).
    pub max: f64,
    /// Unit string of the DBC.
    pub unit: &'static str,
}

impl Signal {
    /// Largest raw value the signal can carry.
    pub const fn max_raw(&self) -> u64 {
        (1u64 << self.len) - 1
    }

    /// Raw value of the signal in a payload read as a little-endian `u64`.
    pub const fn get(&self, payload: u64) -> u64 {
        (payload >> self.start_bit) & self.max_raw()
    }

    /// Writes a raw value into a payload, saturating it to the signal's width.
    pub fn put(&self, payload: &mut u64, raw: u64) {
        let raw = if raw > self.max_raw() { self.max_raw() } else { raw };
        *payload &= !(self.max_raw() << self.start_bit);
        *payload |= raw << self.start_bit;
    }

    /// Bit mask of the signal within the payload.
    pub const fn mask(&self) -> u64 {
        self.max_raw() << self.start_bit
    }
}

/// One message (frame) of the DBC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Message {
    /// DBC message name.
    pub name: &'static str,
    /// 29-bit extended CAN identifier (the DBC writes it with bit 31 set).
    pub id: ExtendedId,
    /// Data length in bytes.
    pub dlc: u8,
    /// E2E data ID mixed into the CRC (not transmitted), so a frame under the wrong
    /// identifier fails its CRC: the message's PGN with the layout version in the high nibble
    /// that introduced or last changed the message (layout 2 for the fault report and the
    /// status frame, whose layout 1 used 0xFF50 / 0xFF51; layout 3 for the session frame), so
    /// frames of different layouts cannot be confused.
    pub data_id: u16,
    /// Nominal cycle time in ms (DBC attribute `GenMsgCycleTime`).
    pub cycle_ms: u16,
    /// Every signal of the message; bits not covered are reserved and sent as 0.
    pub signals: &'static [Signal],
}

impl Message {
    /// The raw 29-bit identifier.
    pub fn raw_id(&self) -> u32 {
        self.id.as_raw()
    }

    /// Mask of the bits that no signal covers (reserved, always 0).
    pub fn reserved_mask(&self) -> u64 {
        let used = self.signals.iter().fold(0u64, |m, s| m | s.mask());
        let all = if self.dlc >= 8 { u64::MAX } else { (1u64 << (8 * u32::from(self.dlc))) - 1 };
        all & !used
    }
}

/// An extended identifier checked at compile time (used in `const` items only, where an id
/// above 29 bits fails the build instead of panicking at run time).
const fn ext(id: u32) -> ExtendedId {
    match ExtendedId::new(id) {
        Some(x) => x,
        None => panic!("CAN id above 29 bits"),
    }
}

const fn sig(name: &'static str, start_bit: u8, len: u8, factor: f64, max: f64, unit: &'static str) -> Signal {
    Signal { name, start_bit, len, factor, offset: 0.0, min: 0.0, max, unit }
}

// ---- Fault report ------------------------------------------------------------------------

/// E2E CRC-8 (SAE J1850) over the data ID and bytes 1..8 of the fault report.
pub const FAULT_CRC: Signal = sig("FaultCrc", 0, 8, 1.0, 255.0, "");
/// E2E rolling counter of the fault report (0..=15, wraps).
pub const FAULT_COUNTER: Signal = sig("FaultCounter", 8, 4, 1.0, 15.0, "");
/// Diagnosis: `FaultClass as u8` (0..=5) or [`DIAGNOSIS_CANNOT_DIAGNOSE`].
pub const DIAGNOSIS: Signal = sig("Diagnosis", 12, 4, 1.0, 15.0, "");
/// Calibrated classifier confidence, 1 % per LSB (0..=100, a clean percentage: the DBC range is
/// `[0|100]` although 7 bits could carry 127; the monitor sends at most
/// [`crate::classifier::MAX_CONFIDENCE_PCT`]).
pub const CONFIDENCE: Signal = sig("Confidence", 16, 7, 1.0, 100.0, "%");
/// Why no class is named ([`reason`] codes; 0 when a class is named).
pub const NO_DIAGNOSIS_REASON: Signal = sig("NoDiagnosisReason", 23, 4, 1.0, 15.0, "");
/// Release completed (piston at its end stop, pressure settled).
pub const RELEASE_COMPLETED: Signal = sig("ReleaseCompleted", 27, 1, 1.0, 1.0, "");
/// Time since the release command, 0.1 s per LSB (saturates at 409.5 s).
pub const TIME_SINCE_RELEASE: Signal = sig("TimeSinceRelease", 28, 12, 0.1, 409.5, "s");
/// Estimated supply pressure, 5 mbar per LSB (0 = not estimated; saturates at 20.475 bar g).
pub const SUPPLY_PRESSURE: Signal = sig("SupplyPressure", 40, 12, 0.005, 20.475, "bar");
/// Estimated leak as an equivalent orifice diameter, 1 µm per LSB (saturates at 4.095 mm).
pub const LEAK_DIAMETER: Signal = sig("LeakDiameter", 52, 12, 0.001, 4.095, "mm");

/// Raw value of [`DIAGNOSIS`] meaning "cannot diagnose" (the reason is in [`NO_DIAGNOSIS_REASON`]).
pub const DIAGNOSIS_CANNOT_DIAGNOSE: u8 = 15;
/// Largest raw value of [`CONFIDENCE`] that means something (100 %).
pub const CONFIDENCE_MAX_PCT: u8 = 100;
/// Report time units (10 ms) per raw LSB of [`TIME_SINCE_RELEASE`].
pub const TIME_CS_PER_LSB: u16 = 10;
/// Millibar per raw LSB of [`SUPPLY_PRESSURE`].
pub const SUPPLY_MBAR_PER_LSB: u16 = 5;
/// Micrometres per raw LSB of [`LEAK_DIAMETER`].
pub const LEAK_UM_PER_LSB: u16 = 1;

/// Codes of [`NO_DIAGNOSIS_REASON`]. A sensor fault is sent with its own code,
/// [`SensorFault::code`](crate::sensor::SensorFault::code) (1, 2 and 5..=13), the same number
/// `BPM_Status.SensorHealth` carries.
pub mod reason {
    /// A class is named (no reason).
    pub const NONE: u8 = 0;
    /// The release ended before enough of it was seen.
    pub const TOO_SHORT: u8 = 3;
    /// The release is unlike every release the classifier was trained on.
    pub const UNFAMILIAR: u8 = 4;
    /// Labels as in the DBC `VAL_` table, indexed by code (`""`: code not used).
    pub const LABELS: [&str; 14] = [
        "none",
        "sensor_open_circuit",
        "sensor_short_circuit",
        "too_short",
        "unfamiliar_release",
        "sensor_frozen",
        "sensor_dead",
        "sensor_noisy",
        "sensor_spikes",
        "sensor_dropouts",
        "sensor_lost_resolution",
        "sensor_clipped",
        "sensor_impossible_rate",
        "sensor_implausible_level",
    ];
}

/// The fault report frame.
pub const FAULT_REPORT: Message = Message {
    name: "BPM_FaultReport",
    id: ext(0x18FF_5080),
    dlc: 8,
    data_id: 0x2F50,
    cycle_ms: 1000,
    signals: &[
        FAULT_CRC,
        FAULT_COUNTER,
        DIAGNOSIS,
        CONFIDENCE,
        NO_DIAGNOSIS_REASON,
        RELEASE_COMPLETED,
        TIME_SINCE_RELEASE,
        SUPPLY_PRESSURE,
        LEAK_DIAMETER,
    ],
};

// ---- Status / heartbeat ------------------------------------------------------------------

/// E2E CRC-8 (SAE J1850) over the data ID and bytes 1..8 of the status frame.
pub const STATUS_CRC: Signal = sig("StatusCrc", 0, 8, 1.0, 255.0, "");
/// Heartbeat counter: status frames sent since the monitor started, modulo 4096 (+1 per frame;
/// 12 bits, so it wraps only after 68 minutes and a replayed heartbeat is told from the live one
/// at any lag up to that, and by the receive time beyond).
pub const STATUS_COUNTER: Signal = sig("StatusCounter", 8, 12, 1.0, 4095.0, "");
/// Estimator state: `EstimatorState as u8`.
pub const ESTIMATOR_STATE: Signal = sig("EstimatorState", 20, 2, 1.0, 3.0, "");
/// Sensor health: 0 = ok, otherwise the [`SensorFault::code`](crate::sensor::SensorFault::code)
/// of the fault the monitor sees now ([`sensor_health`] labels).
pub const SENSOR_HEALTH: Signal = sig("SensorHealth", 22, 4, 1.0, 15.0, "");
/// Last measured chamber pressure, 1 mbar per LSB (14 bits: 0..16.383 bar g, above the
/// transducer's full scale of 11.25 bar g, so every reading is sent exactly).
pub const CHAMBER_PRESSURE: Signal = sig("ChamberPressure", 26, 14, 0.001, 16.383, "bar");
/// Firmware major version (0..=15).
pub const FIRMWARE_MAJOR: Signal = sig("FirmwareMajor", 40, 4, 1.0, 15.0, "");
/// Firmware minor version (0..=15).
pub const FIRMWARE_MINOR: Signal = sig("FirmwareMinor", 44, 4, 1.0, 15.0, "");
/// The locomotive the monitor is fitted to (its number in the fleet configuration, modulo 64).
/// Also bound into every fault report's CRC.
pub const LOCOMOTIVE: Signal = sig("Locomotive", 48, 6, 1.0, 63.0, "");
/// Release number: release commands and power-ups the monitor has seen (a counter a
/// controller keeps across power cycles), modulo 64. Each release, and each power cycle, has
/// its own number: the release the fault reports of this moment belong to, and what tells a
/// restarted sender from a replay. Also bound into every fault report's CRC.
pub const RELEASE_NUMBER: Signal = sig("ReleaseNumber", 54, 6, 1.0, 63.0, "");
/// Fault reports sent so far, modulo 16: the `FaultCounter` the next fault report will carry.
/// A receiver that got fewer knows within a second that a fault report was lost.
pub const FAULT_REPORT_COUNT: Signal = sig("FaultReportCount", 60, 4, 1.0, 15.0, "");

/// Codes of [`SENSOR_HEALTH`].
pub mod sensor_health {
    /// No sensor fault.
    pub const OK: u8 = 0;
    /// Labels as in the DBC `VAL_` table, indexed by code (`""`: code not used).
    pub const LABELS: [&str; 14] = [
        "ok",
        "open_circuit",
        "short_circuit",
        "",
        "",
        "frozen",
        "dead",
        "noisy",
        "spikes",
        "dropouts",
        "lost_resolution",
        "clipped",
        "impossible_rate",
        "implausible_level",
    ];
}

/// Labels of [`ESTIMATOR_STATE`] as in the DBC `VAL_` table, indexed by `EstimatorState as u8`.
pub const ESTIMATOR_STATE_LABELS: [&str; 4] = ["idle", "converging", "settled", "frozen"];

/// The status/heartbeat frame.
pub const STATUS: Message = Message {
    name: "BPM_Status",
    id: ext(0x18FF_5180),
    dlc: 8,
    data_id: 0x2F51,
    cycle_ms: 1000,
    signals: &[
        STATUS_CRC,
        STATUS_COUNTER,
        ESTIMATOR_STATE,
        SENSOR_HEALTH,
        CHAMBER_PRESSURE,
        FIRMWARE_MAJOR,
        FIRMWARE_MINOR,
        LOCOMOTIVE,
        RELEASE_NUMBER,
        FAULT_REPORT_COUNT,
    ],
};

// ---- Session (release count) ---------------------------------------------------------------

/// E2E CRC-8 (SAE J1850) over the data ID and bytes 1..8 of the session frame.
pub const SESSION_CRC: Signal = sig("SessionCrc", 0, 8, 1.0, 255.0, "");
/// The heartbeat counter of the status frame this session frame follows (sent in the same
/// transmit tick, right after it): what ties the release count to one moment of one session.
pub const SESSION_STATUS_COUNTER: Signal = sig("SessionStatusCounter", 8, 12, 1.0, 4095.0, "");
/// The locomotive, as in [`LOCOMOTIVE`]: the low 6 bits of its fleet number.
pub const SESSION_LOCOMOTIVE: Signal = sig("SessionLocomotive", 20, 6, 1.0, 63.0, "");
/// Bits 6..12 of the locomotive's fleet number (layout 3.1, in bits that layout 3.0 reserved
/// as 0): with [`SESSION_LOCOMOTIVE`], 12 bits (0–4095). The status frames and fault reports
/// carry 6; a unit of another locomotive whose number is the same modulo 64 (a spare or swapped
/// controller, or its recording) is told apart by its session frames (eighth black-box attacker,
/// F2: such a recording played after the monitor stopped had been taken as its restart).
pub const SESSION_LOCOMOTIVE_HIGH: Signal = sig("SessionLocomotiveHigh", 26, 6, 1.0, 63.0, "");
/// Release count: release commands and power-ups since the controller was new, the counter it
/// keeps in non-volatile memory, in full (32 bits; [`RELEASE_NUMBER`] is its low 6 bits). The
/// 6-bit release number repeats every 64 releases; this count repeats only after 2³² (136
/// years at one release a second from 0; a receiver compares counts in serial-number order, so
/// a count that started at an erased 0xFFFF_FFFF is followed across its wrap), so a receiver
/// that saw it once tells a restart of the monitor from a recording of an old session of the
/// same locomotive.
pub const RELEASE_COUNT: Signal = sig("ReleaseCount", 32, 32, 1.0, 4_294_967_295.0, "");

/// Status frames between two periodic session frames (10 s): a display that joins late
/// learns the release count within this time. A session frame is also sent after the first
/// status frame of a power-up and after the first status frame of each new release number.
pub const SESSION_EVERY_STATUS_FRAMES: u16 = 10;

/// The session frame: the full release count, sent right after a status frame (power-up, a new
/// release number, and every [`SESSION_EVERY_STATUS_FRAMES`] status frames). Layout 3 added it;
/// the two frames of layout 2 are unchanged.
pub const SESSION: Message = Message {
    name: "BPM_Session",
    id: ext(0x18FF_5280),
    dlc: 8,
    data_id: 0x3F52,
    cycle_ms: 10_000,
    signals: &[SESSION_CRC, SESSION_STATUS_COUNTER, SESSION_LOCOMOTIVE, SESSION_LOCOMOTIVE_HIGH, RELEASE_COUNT],
};

/// Every message the monitor transmits. Nothing else is ever sent.
pub const MESSAGES: [Message; 3] = [FAULT_REPORT, STATUS, SESSION];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signals_do_not_overlap_and_fit_the_frame() {
        for m in MESSAGES {
            let mut used = 0u64;
            for s in m.signals {
                assert!(s.len >= 1 && u32::from(s.start_bit) + u32::from(s.len) <= 8 * u32::from(m.dlc), "{}", s.name);
                assert_eq!(used & s.mask(), 0, "{} overlaps", s.name);
                used |= s.mask();
            }
            assert_eq!(m.signals[0].start_bit, 0, "CRC in byte 0");
            assert_eq!(m.signals[0].len, 8);
            assert_eq!(m.signals[1].start_bit, 8, "counter from the low nibble of byte 1");
        }
        assert_eq!(FAULT_REPORT.reserved_mask(), 0);
        assert_eq!(STATUS.reserved_mask(), 0);
        assert_eq!(SESSION.reserved_mask(), 0, "layout 3.1 uses the bits 3.0 reserved");
    }

    #[test]
    fn put_get_saturate() {
        let mut p = u64::MAX;
        TIME_SINCE_RELEASE.put(&mut p, 5000);
        assert_eq!(TIME_SINCE_RELEASE.get(p), 4095);
        TIME_SINCE_RELEASE.put(&mut p, 7);
        assert_eq!(TIME_SINCE_RELEASE.get(p), 7);
        assert_eq!(p | TIME_SINCE_RELEASE.mask(), u64::MAX, "neighbours untouched");
    }
}
