//! `fleet status`: one line per locomotive — releases, verdict mix, latest estimates,
//! trends and warnings.

use crate::db::{FleetDb, StoredRelease};
use crate::record::{ReleaseRecord, Source};
use crate::trend::{trend, warnings, Parameter, Trend, Warning, WarningRule};
use anyhow::Result;
use pbm::report::Verdict;
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
    /// Early warnings raised.
    pub warnings: Vec<Warning>,
}

/// A stored release as a record again (for the trend functions).
pub fn to_record(s: &StoredRelease) -> ReleaseRecord {
    let class = FaultClass::from_label(&s.verdict);
    let verdict = match (class, s.confidence_pct) {
        (Some(class), Some(c)) => Some(Verdict::Class { class, confidence_pct: u8::try_from(c).unwrap_or(0) }),
        // The trend functions use the estimates only; the reason of a declined diagnosis is kept
        // in the database, not rebuilt here.
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
            warnings: warnings(&records, rule),
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
            let warn = if s.warnings.is_empty() {
                "no warning".to_owned()
            } else {
                let w: Vec<String> = s
                    .warnings
                    .iter()
                    .map(|w| {
                        let eta = s.trends[w.parameter as usize]
                            .and_then(|t| t.releases_to_edge)
                            .map_or_else(String::new, |n| format!(", edge in ≈ {n:.0} releases"));
                        format!(
                            "WARNING {} drifting toward {:.1} {} since release {}{eta}",
                            w.parameter.name(),
                            w.parameter.threshold(),
                            w.parameter.unit(),
                            w.release_no
                        )
                    })
                    .collect();
                w.join("; ")
            };
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
