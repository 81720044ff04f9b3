//! One release as the fleet history keeps it: who, which release, what the monitor said, and
//! the estimates it closed the release with.
//!
//! Everything here is read off the core's own output (the replayed pipeline's closed
//! [`FaultReport`] and last [`Estimates`](pbm::estimator::Estimates), or a decoded CAN fault
//! report); nothing is recomputed.

use pbm::report::{FaultReport, NoDiagnosis, Verdict};
use pbm::sensor::SensorFault;

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
    /// Fingerprint of a trace's samples ([`samples_hash`]): the same release stored again under
    /// another file name is recognised by it. `None` for a CAN report.
    pub content_hash: Option<String>,
    /// `true` when the release number is the trace's own `release` metadata (not its rank in a
    /// data set): then (locomotive, release number) names the release.
    pub numbered: bool,
    /// The release curve and the decoded CAN reports, when the input gave them.
    pub detail: ReleaseDetail,
}

/// What a locomotive page shows of one release besides its verdict and estimates: the
/// measured pressure against the twin's, and the fault reports the cab received.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReleaseDetail {
    /// Measured and twin pressure over the release (a replayed trace only; a CAN log carries no
    /// pressure curve).
    pub curve: Option<ReleaseCurve>,
    /// The fault reports of the release as the cab display decodes them, in order.
    pub can_reports: Vec<CanReport>,
}

/// Measured and twin chamber pressure of one release, thinned to [`CURVE_STEP_S`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReleaseCurve {
    /// Time between points, s.
    pub step_s: f64,
    /// Measured pressure, bar g (`NaN` where the monitor found the sample faulty).
    pub measured_bar: Vec<f32>,
    /// The nominal twin's pressure for the same valve command, bar g.
    pub twin_bar: Vec<f32>,
}

/// Time between the stored points of a release curve, s (5 points a second: a 60 s release is
/// 300 points, 1.2 kB in the database, and the curve's shape on a page-wide plot is intact).
pub const CURVE_STEP_S: f64 = 0.2;

impl ReleaseCurve {
    /// Both series as one blob: per point two little-endian `i16` of mbar, measured then twin;
    /// `i16::MIN` marks a missing (faulty) measured sample.
    pub fn to_blob(&self) -> Vec<u8> {
        let code = |v: f32| {
            if v.is_finite() {
                (f64::from(v) * 1000.0).round().clamp(-32_767.0, 32_767.0) as i16
            } else {
                i16::MIN
            }
        };
        let mut out = Vec::with_capacity(self.measured_bar.len() * 4);
        for (&m, &t) in self.measured_bar.iter().zip(&self.twin_bar) {
            out.extend_from_slice(&code(m).to_le_bytes());
            out.extend_from_slice(&code(t).to_le_bytes());
        }
        out
    }

    /// The inverse of [`Self::to_blob`]; `None` for a blob that is not whole points.
    pub fn from_blob(step_s: f64, blob: &[u8]) -> Option<Self> {
        if blob.len() % 4 != 0 || !(step_s.is_finite() && step_s > 0.0) {
            return None;
        }
        let value = |b: &[u8]| {
            let v = i16::from_le_bytes([b[0], b[1]]);
            if v == i16::MIN {
                f32::NAN
            } else {
                f32::from(v) / 1000.0
            }
        };
        let (measured_bar, twin_bar) = blob.chunks_exact(4).map(|p| (value(&p[..2]), value(&p[2..]))).unzip();
        Some(Self { step_s, measured_bar, twin_bar })
    }
}

/// One fault report as the cab display decoded it.
#[derive(Debug, Clone, PartialEq)]
pub struct CanReport {
    /// Time of the frame, s since the start of the release (replayed trace) or on the log's
    /// clock (CAN log).
    pub time_s: f64,
    /// The 6-bit release number the frame carries.
    pub can_release: u8,
    /// The report.
    pub report: FaultReport,
    /// `false` when the report came while no heartbeat vouched for the sender (the display
    /// shows it as stale).
    pub current: bool,
    /// Fault reports the sender sent before this one that the display never received.
    pub lost_before: u8,
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

    /// `true` when the monitor named a class for this release: only then do its estimates
    /// describe the brake. A release it declined (sensor fault, unfamiliar, too short) or
    /// closed without a diagnosis is not evidence about the brake, and the trends and
    /// warnings do not follow its estimates.
    pub fn diagnosed(&self) -> bool {
        matches!(self.verdict, Some(Verdict::Class { .. }))
    }

    /// Why the monitor declined to name a class, when it declined.
    pub fn declined(&self) -> Option<NoDiagnosis> {
        match self.verdict {
            Some(Verdict::CannotDiagnose(why)) => Some(why),
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

/// Calibrated confidence of a verdict that names a class, per cent.
pub fn confidence_of(v: &Verdict) -> Option<u8> {
    match v {
        Verdict::Class { confidence_pct, .. } => Some(*confidence_pct),
        Verdict::CannotDiagnose(_) => None,
    }
}

/// Why a verdict names no class, in the core's words.
pub fn no_diagnosis_of(v: &Verdict) -> Option<String> {
    match v {
        Verdict::CannotDiagnose(why) => Some(why.to_string()),
        Verdict::Class { .. } => None,
    }
}

/// The stored verdict label of a verdict (the one mapping, shared with the replay's results
/// file).
pub use pbm_io::archive::results::verdict_label;

/// The reason of a declined diagnosis from its stored text (the core's own `Display` of
/// [`NoDiagnosis`], as [`ReleaseRecord::no_diagnosis`] stores it); `None` for an unknown text.
pub fn parse_no_diagnosis(text: &str) -> Option<NoDiagnosis> {
    SensorFault::ALL
        .into_iter()
        .map(NoDiagnosis::SensorFault)
        .chain([NoDiagnosis::TooShort, NoDiagnosis::Unfamiliar])
        .find(|n| n.to_string() == text)
}

/// The fingerprint of a trace's samples: FNV-1a (64 bit, stable across builds and platforms)
/// of its data lines — every line that is neither blank nor a `#` metadata line, trimmed — so
/// that a copy of a trace under another name, or with other metadata, has the same one.
pub fn samples_hash(text: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut lines = 0u64;
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('#')) {
        for b in line.bytes().chain([b'\n']) {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
        lines += 1;
    }
    format!("{h:016x}-{lines}")
}

/// Stored verdict of a release where the monitor declined to name a class, and of one that
/// closed without any diagnosis.
pub use pbm_io::archive::results::{CANNOT_DIAGNOSE, NO_VERDICT};

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
