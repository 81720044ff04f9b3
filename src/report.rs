//! What the monitor tells the cab: plain data, independent of the CAN bit layout (see `can`).

use crate::fault::FaultClass;
use crate::sensor::SensorFault;

/// Why the monitor declines to name a fault class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NoDiagnosis {
    /// The pressure signal cannot be trusted (out of range, or implausible statistics); the
    /// kind says which check failed.
    SensorFault(SensorFault),
    /// The release ended before enough of it was seen.
    TooShort,
    /// The release is unlike every release the classifier was trained on (its features lie
    /// outside the trained region), so no class it knows can be named with confidence.
    Unfamiliar,
}

/// The monitor's verdict on one release.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Verdict {
    /// A fault class with the classifier's calibrated confidence.
    Class {
        /// Named class.
        class: FaultClass,
        /// Calibrated probability that the class is right, per cent (0..=100; the monitor
        /// sends at most [`crate::classifier::MAX_CONFIDENCE_PCT`]).
        confidence_pct: u8,
    },
    /// No class can be named, with the reason.
    CannotDiagnose(NoDiagnosis),
}

impl core::fmt::Display for NoDiagnosis {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::SensorFault(s) => write!(f, "sensor fault ({s})"),
            Self::TooShort => f.write_str("release too short"),
            Self::Unfamiliar => f.write_str("unfamiliar release"),
        }
    }
}

/// `air_leak 97%` or `cannot diagnose: release too short`: what a display shows.
impl core::fmt::Display for Verdict {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Class { class, confidence_pct } => write!(f, "{class} {confidence_pct}%"),
            Self::CannotDiagnose(why) => write!(f, "cannot diagnose: {why}"),
        }
    }
}

/// Fault report for one release, sent when a diagnosis is made or updated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FaultReport {
    /// The verdict.
    pub verdict: Verdict,
    /// Time since the release command, 10 ms units.
    pub time_since_release_cs: u16,
    /// Estimated supply pressure, mbar g (0 when not estimated yet).
    pub supply_mbar: u16,
    /// Estimated leak, as equivalent orifice diameter in µm (0 = tight or not estimated).
    pub leak_um: u16,
    /// The release has completed (piston at its end stop, pressure settled).
    pub release_completed: bool,
}

/// State of the online estimator, as reported in the status frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum EstimatorState {
    /// No release in progress.
    Idle = 0,
    /// Collecting data; estimates not yet settled.
    Converging = 1,
    /// Estimates settled.
    Settled = 2,
    /// Covariance guard active (no excitation).
    Frozen = 3,
}

/// Periodic status/heartbeat of the monitor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StatusReport {
    /// Sensor health: `None` when the signal is trusted, otherwise the fault the monitor sees.
    pub sensor_fault: Option<SensorFault>,
    /// Estimator state.
    pub estimator: EstimatorState,
    /// Last measured chamber pressure, mbar g (saturated to 0..=65535).
    pub pressure_mbar: u16,
    /// Firmware version (major, minor).
    pub version: (u8, u8),
}
