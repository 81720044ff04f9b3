//! `fleet status`: one line per locomotive — releases, verdict mix, latest estimates,
//! trends and warnings.

use crate::db::{FleetDb, StoredRelease};
use crate::record::{parse_no_diagnosis, ReleaseRecord, Source};
use crate::trend::{episodes, trend, Parameter, Trend, Warning, WarningRule};
use anyhow::Result;
use pbm::report::{NoDiagnosis, Verdict};
use pbm::FaultClass;
use std::collections::BTreeMap;

/// The fleet view of one locomotive.
#[derive(Debug, Clone, PartialEq)]
pub struct LocoStatus {
    /// Locomotive name.
    pub locomotive: String,
    /// Releases followed (those of one source, [`trend_series`]).
    pub releases: usize,
    /// Rows stored for the locomotive (more than `releases` when the same releases came both
    /// as traces and in cab CAN logs).
    pub stored: usize,
    /// Releases followed, per verdict label.
    pub verdicts: BTreeMap<String, usize>,
    /// The latest release's verdict label and confidence.
    pub latest_verdict: Option<(String, Option<i64>)>,
    /// Per parameter ([`Parameter::ALL`] order): its trend, if estimated.
    pub trends: [Option<Trend>; 3],
    /// Early warnings raised now (not cleared).
    pub warnings: Vec<Warning>,
    /// Per parameter, the latest warning that has cleared, when none is raised now.
    pub cleared: Vec<Warning>,
    /// Releases the monitor did not diagnose, per reason (their estimates are not followed).
    pub undiagnosed: Vec<Undiagnosed>,
}

impl LocoStatus {
    /// The sensor fault that puts a brake warning in doubt: one seen on the locomotive from
    /// the warning's onset on (a drifting transducer is flagged only once its error is large,
    /// and the releases before that carry part of its error).
    pub fn sensor_doubt(&self, w: &Warning) -> Option<&Undiagnosed> {
        self.undiagnosed.iter().find(|u| u.sensor && u.last_release_no >= w.onset_release_no)
    }

    /// The brake warning that puts a supply warning in doubt: a leak or orifice warning of the
    /// locomotive that began no later. The supply is estimated from the pressure the chamber
    /// settles at, and a leak holds that below the supply (a blocked orifice keeps the chamber
    /// from reaching it in the window), so a leak or clog lowers the supply estimate while the
    /// supply itself is fine (on the degradation scenario a 0.9 mm leak moved it 0.08 bar).
    pub fn brake_doubt(&self, w: &Warning) -> Option<&Warning> {
        if w.parameter != Parameter::Supply {
            return None;
        }
        self.warnings.iter().find(|o| o.parameter != Parameter::Supply && o.onset_release_no <= w.onset_release_no)
    }

    /// Why a warning cannot be trusted as it reads, if it cannot ([`Self::sensor_doubt`],
    /// [`Self::brake_doubt`]), in words.
    pub fn doubt(&self, w: &Warning) -> Option<String> {
        if let Some(u) = self.sensor_doubt(w) {
            return Some(format!(
                "the transducer is at fault on releases since {} (sensor warning): the shift may be the sensor's, not the \
                 brake's",
                u.first_release_no
            ));
        }
        self.brake_doubt(w).map(|o| {
            format!(
                "the {} warning since release {} lowers the supply estimate (the chamber settles below the supply): the \
                 supply itself may be fine",
                o.parameter.name(),
                o.onset_release_no
            )
        })
    }
}

/// Releases of a locomotive that the monitor did not diagnose, for one reason.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Undiagnosed {
    /// The reason as the core gives it (`sensor fault (implausible level: offset or gain
    /// error)`, `unfamiliar release`, …; `closed without a diagnosis` for a release with none).
    pub reason: String,
    /// `true` for a sensor fault: the transducer, not the brake. A warning of its own.
    pub sensor: bool,
    /// Releases with this reason.
    pub count: usize,
    /// Release number of the first and of the latest of them.
    pub first_release_no: i64,
    /// Release number of the latest of them.
    pub last_release_no: i64,
    /// Releases followed from the first of them on (all reasons and diagnoses).
    pub since: usize,
}

impl Undiagnosed {
    /// In words: the sensor warning, or the note of undiagnosed releases.
    pub fn describe(&self) -> String {
        let span = format!(
            "on {} of the {} releases since release {} (latest {})",
            self.count, self.since, self.first_release_no, self.last_release_no
        );
        if self.sensor {
            let kind =
                self.reason.strip_prefix("sensor fault (").and_then(|r| r.strip_suffix(')')).unwrap_or(&self.reason);
            format!("sensor: {kind} {span} — the transducer, not the brake; their estimates are not followed")
        } else {
            format!("not diagnosed: {} {span}; their estimates are not followed", self.reason)
        }
    }
}

/// The releases of `stored` (one source, timeline order) not diagnosed, grouped by reason,
/// sensor faults first.
pub fn undiagnosed(stored: &[&StoredRelease]) -> Vec<Undiagnosed> {
    let mut out: Vec<Undiagnosed> = Vec::new();
    for (pos, r) in stored.iter().enumerate() {
        if FaultClass::from_label(&r.verdict).is_some() {
            continue;
        }
        let reason = match (&r.no_diagnosis, r.verdict.as_str()) {
            (Some(why), _) => why.clone(),
            (None, crate::record::CANNOT_DIAGNOSE) => "no diagnosis (reason not recorded)".to_owned(),
            (None, _) => "closed without a diagnosis".to_owned(),
        };
        match out.iter_mut().find(|u| u.reason == reason) {
            Some(u) => {
                u.count += 1;
                u.last_release_no = r.release_no;
            }
            None => out.push(Undiagnosed {
                sensor: reason.starts_with("sensor fault"),
                reason,
                count: 1,
                first_release_no: r.release_no,
                last_release_no: r.release_no,
                since: stored.len() - pos,
            }),
        }
    }
    out.sort_by_key(|u| (!u.sensor, u.first_release_no));
    out
}

/// A stored release as a record again (for the trend functions).
pub fn to_record(s: &StoredRelease) -> ReleaseRecord {
    let class = FaultClass::from_label(&s.verdict);
    let verdict = match (class, s.confidence_pct) {
        (Some(class), Some(c)) => Some(Verdict::Class { class, confidence_pct: u8::try_from(c).unwrap_or(0) }),
        // A declined diagnosis keeps its reason (the trends leave its estimates out and the
        // status names the reason); an unknown stored reason still counts as declined.
        _ if s.verdict == crate::record::CANNOT_DIAGNOSE => Some(Verdict::CannotDiagnose(
            s.no_diagnosis.as_deref().and_then(parse_no_diagnosis).unwrap_or(NoDiagnosis::Unfamiliar),
        )),
        _ => None,
    };
    ReleaseRecord {
        locomotive: s.locomotive.clone(),
        source: crate::db::source_of(&s.source).unwrap_or(Source::Trace),
        origin: s.origin.clone(),
        release_key: s.release_key.clone(),
        release_no: s.release_no,
        time_s: s.time_s,
        verdict,
        orifice_mm: s.orifice_mm,
        leak_mm: s.leak_mm,
        supply_bar_g: s.supply_bar_g,
        label: s.label.clone(),
        content_hash: s.content_hash.clone(),
        numbered: s.numbered,
        // The trends need no curve or reports; the pages read them by the row id.
        detail: Default::default(),
    }
}

/// The releases a locomotive's trends and warnings follow: those of one source, the one with
/// the most releases (recorded traces on a tie, as they also carry the orifice estimate). A
/// release seen both as a trace and in a cab CAN log is the same release twice; mixing both
/// would count it twice and let the CUSUM alarm twice as fast.
pub fn trend_series(stored: &[StoredRelease]) -> Vec<ReleaseRecord> {
    followed(stored).map(to_record).collect()
}

/// The stored releases of the source [`trend_series`] follows.
pub fn followed(stored: &[StoredRelease]) -> impl Iterator<Item = &StoredRelease> {
    let traces = stored.iter().filter(|s| s.source == Source::Trace.label()).count();
    let can = stored.len() - traces;
    let source = if traces >= can { Source::Trace } else { Source::Can };
    stored.iter().filter(move |s| s.source == source.label())
}

/// The status of every locomotive in the database.
pub fn status(db: &FleetDb, rule: &WarningRule) -> Result<Vec<LocoStatus>> {
    let mut out = Vec::new();
    for loco in db.locomotives()? {
        let stored = db.releases(&loco)?;
        let records = trend_series(&stored);
        let all = episodes(&records, rule);
        let mut verdicts = BTreeMap::new();
        for r in followed(&stored) {
            *verdicts.entry(r.verdict.clone()).or_insert(0) += 1;
        }
        out.push(LocoStatus {
            locomotive: loco,
            releases: records.len(),
            stored: stored.len(),
            verdicts,
            latest_verdict: followed(&stored).last().map(|r| (r.verdict.clone(), r.confidence_pct)),
            trends: Parameter::ALL.map(|p| trend(&records, p)),
            warnings: all.iter().filter(|w| w.cleared_release_no.is_none()).cloned().collect(),
            cleared: Parameter::ALL
                .into_iter()
                .filter(|&p| !all.iter().any(|w| w.parameter == p && w.cleared_release_no.is_none()))
                .filter_map(|p| all.iter().rev().find(|w| w.parameter == p).cloned())
                .collect(),
            undiagnosed: undiagnosed(&followed(&stored).collect::<Vec<_>>()),
        });
    }
    Ok(out)
}

fn estimate_text(t: &Option<Trend>, p: Parameter) -> String {
    match t {
        None => format!("{} n/a", p.name()),
        Some(t) => {
            let se = if t.slope_se.is_finite() { format!("±{:.4}", t.slope_se) } else { String::new() };
            format!("{} {:.3} {} ({:+.4}{se}/release)", p.name(), t.latest, p.unit(), t.slope)
        }
    }
}

/// The status as text lines, one per locomotive.
pub fn lines(statuses: &[LocoStatus]) -> Vec<String> {
    statuses
        .iter()
        .map(|s| {
            let mix: Vec<String> = s.verdicts.iter().map(|(v, n)| format!("{v} {n}")).collect();
            let latest = match &s.latest_verdict {
                Some((v, Some(c))) => format!("{v} {c}%"),
                Some((v, None)) => v.clone(),
                None => "-".to_owned(),
            };
            let est: Vec<String> = Parameter::ALL.iter().zip(&s.trends).map(|(&p, t)| estimate_text(t, p)).collect();
            let mut warn: Vec<String> = Vec::new();
            for u in s.undiagnosed.iter().filter(|u| u.sensor) {
                warn.push(format!("SENSOR WARNING {}", u.describe()));
            }
            for w in &s.warnings {
                if let Some(why) = s.doubt(w) {
                    warn.push(format!("CANNOT TELL {} — {why}", w.describe()));
                    continue;
                }
                let eta = s.trends[w.parameter as usize]
                    .and_then(|t| t.releases_to_edge)
                    .map_or_else(String::new, |n| format!(", edge in ≈ {n:.0} releases"));
                warn.push(format!("WARNING {}{eta}", w.describe()));
            }
            if warn.is_empty() {
                warn.push("no warning".to_owned());
            }
            for w in &s.cleared {
                warn.push(format!("(earlier: {})", w.describe()));
            }
            for u in s.undiagnosed.iter().filter(|u| !u.sensor) {
                warn.push(u.describe());
            }
            let warn = warn.join("; ");
            let stored = if s.stored > s.releases {
                format!(" ({} stored from traces and cab logs)", s.stored)
            } else {
                String::new()
            };
            format!(
                "{}  releases {}{stored}  latest {}  mix [{}]  {}  {}",
                s.locomotive,
                s.releases,
                latest,
                mix.join(", "),
                est.join("  "),
                warn
            )
        })
        .collect()
}
