//! One release as the fleet history keeps it: who, which release, what the monitor said, and
//! the estimates it closed the release with.
//!
//! Everything here is read off the core's own output (the replayed pipeline's closed
//! [`FaultReport`] and last [`Estimates`](pbm::estimator::Estimates), or a decoded CAN fault
//! report); nothing is recomputed.

use pbm::report::{FaultReport, Verdict};

/// Where a release came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Source {
    /// A recorded trace replayed through the monitor pipeline on the host.
    Trace,
    /// A fault report decoded from a cab CAN log (candump format).
    Can,
}

impl Source {
    /// The stable name stored in the database.
    pub const fn label(self) -> &'static str {
        match self {
            Self::Trace => "trace",
            Self::Can => "can",
        }
    }
}

/// One release of one locomotive.
#[derive(Debug, Clone, PartialEq)]
pub struct ReleaseRecord {
    /// Locomotive name (`loco-05`; a CAN report's 6-bit number is written the same way).
    pub locomotive: String,
    /// What kind of input the release came from.
    pub source: Source,
    /// The input file it came from (canonical path), part of the natural key.
    pub origin: String,
    /// Which release of that file it is (a trace file holds one; a CAN log many), part of the
    /// natural key.
    pub release_key: String,
    /// Position on the locomotive's timeline: the trace's `release` metadata, else its rank
    /// among the locomotive's traces in the data set; the CAN release number for a CAN report.
    pub release_no: i64,
    /// Time of the release, s (CAN log time stamp; trace metadata `time_s`), when known.
    pub time_s: Option<f64>,
    /// The monitor's verdict (`None`: the release closed without a diagnosis).
    pub verdict: Option<Verdict>,
    /// Estimated release orifice, mm (not carried on CAN).
    pub orifice_mm: Option<f64>,
    /// Estimated leak as an equivalent orifice, mm.
    pub leak_mm: Option<f64>,
    /// Estimated supply pressure, bar g.
    pub supply_bar_g: Option<f64>,
    /// The label the input carries (ground truth of a generated trace), if any.
    pub label: Option<String>,
}

impl ReleaseRecord {
    /// The verdict as stored: the class label, `cannot_diagnose`, or `none`.
    pub fn verdict_label(&self) -> String {
        verdict_label(self.verdict.as_ref())
    }

    /// Calibrated confidence of a named class, per cent.
    pub fn confidence_pct(&self) -> Option<u8> {
        match self.verdict {
            Some(Verdict::Class { confidence_pct, .. }) => Some(confidence_pct),
            _ => None,
        }
    }

    /// Why no class was named (`sensor fault (…)`, …), when none was.
    pub fn no_diagnosis(&self) -> Option<String> {
        match self.verdict {
            Some(Verdict::CannotDiagnose(why)) => Some(why.to_string()),
            _ => None,
        }
    }
}

/// The stored verdict label of a verdict.
pub fn verdict_label(v: Option<&Verdict>) -> String {
    match v {
        Some(Verdict::Class { class, .. }) => class.label().to_owned(),
        Some(Verdict::CannotDiagnose(_)) => CANNOT_DIAGNOSE.to_owned(),
        None => NO_VERDICT.to_owned(),
    }
}

/// Stored verdict of a release where the monitor declined to name a class.
pub const CANNOT_DIAGNOSE: &str = "cannot_diagnose";
/// Stored verdict of a release that closed without any diagnosis.
pub const NO_VERDICT: &str = "none";

/// Supply and leak as a CAN fault report carries them (0 means "not estimated yet" for the
/// supply, "tight or not estimated" for the leak: [`FaultReport`]).
pub fn can_estimates(r: &FaultReport) -> (Option<f64>, Option<f64>) {
    let supply = (r.supply_mbar != 0).then(|| f64::from(r.supply_mbar) / 1000.0);
    let leak = Some(f64::from(r.leak_um) / 1000.0);
    (supply, leak)
}

/// The name of CAN locomotive number `n`, written as the data sets write names, so that a
/// locomotive's CAN reports and its recorded traces land on one row (`5` → `loco-05`; the
/// inverse of [`pbm::can::codec::locomotive_number`] for those names).
pub fn can_locomotive_name(n: u8) -> String {
    format!("loco-{n:02}")
}
