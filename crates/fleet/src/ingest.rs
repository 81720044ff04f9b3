//! `fleet ingest`: releases from traces, data sets and cab CAN logs into the fleet history.
//!
//! - A **trace file** or every trace of a **data set directory** is replayed through the core's
//!   `Pipeline` ([`pbm_lab::replay::replay_item`], the host's one replay loop); a release's
//!   verdict is the diagnosis the pipeline closed and its estimates are the estimator's at the
//!   end of the release. Each trace is one input file: one transaction.
//! - A **fleet archive** ([`pbm_io::archive`]) is replayed release by release like a data
//!   set; a release's natural key is the archive and its release id, its fingerprint that of
//!   the trace it unpacks to, so a release stored before from its trace file is not stored
//!   again. Each release is one transaction.
//! - A **candump log** (`.log`, or a file whose first line is a candump line) is decoded by the
//!   core's CAN [`Decoder`] as the cab display decodes it; the fault reports of one locomotive
//!   and release number form one release, and the last report of it (the final diagnosis) is
//!   stored. CAN carries no orifice estimate. The whole log is one transaction.
//!
//! Bad input follows the project's policy: a trace that cannot be read is skipped whole with
//! its file and line (nothing of it stored), a log line that is not a frame is skipped with its
//! line and the rest of the log is stored; the run goes on and its [`Skipped`] makes the tool
//! exit with status 3.

use crate::db::{FleetDb, Stored};
use crate::record::{
    can_estimates, can_locomotive_name, samples_hash, CanReport, ReleaseCurve, ReleaseDetail, ReleaseRecord, Source,
    CURVE_STEP_S,
};
use anyhow::{bail, Result};
use pbm::can::{Decoder, Report};
use pbm_io::archive::{is_archive, ArchiveReader, ArchivedRelease};
use pbm_io::dataset::TraceItem;
use pbm_io::error::{FileError, Skipped};
use pbm_io::trace::TraceReader;
use pbm_lab::replay::{
    replay_archived_observing, replay_item_observing, ReplayError, ReplayOptions, ReplaySample, TimedFrame, TraceReplay,
};
use rayon::prelude::*;
use std::collections::HashMap;
use std::io::BufRead;
use std::path::Path;
use std::time::{Duration, Instant};

/// What an ingest run did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IngestSummary {
    /// Input files stored (each in its own transaction).
    pub files: usize,
    /// Releases written (new or updated).
    pub releases: usize,
    /// Of those, releases not in the database before.
    pub new: usize,
    /// Releases not stored because the locomotive already has them under another file name
    /// (same samples, or same `release` number), each as `file: why`.
    pub duplicates: Vec<String>,
    /// Inputs (or lines of CAN logs) skipped, each with file and line.
    pub skipped: Skipped,
    /// Wall-clock time.
    pub elapsed: Duration,
}

impl IngestSummary {
    fn add(&mut self, s: Stored) {
        self.files += 1;
        self.releases += s.releases;
        self.new += s.new;
        self.duplicates.extend(s.duplicates);
    }
}

impl std::fmt::Display for IngestSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let secs = self.elapsed.as_secs_f64();
        write!(
            f,
            "stored {} releases ({} new) from {} files in {:.2} s ({:.0} releases/s)",
            self.releases,
            self.new,
            self.files,
            secs,
            if secs > 0.0 { self.releases as f64 / secs } else { 0.0 }
        )?;
        if !self.duplicates.is_empty() {
            write!(f, "; {} duplicates not stored (already stored under another file name)", self.duplicates.len())?;
        }
        if !self.skipped.is_empty() {
            write!(f, "; {} skipped", self.skipped.len())?;
        }
        Ok(())
    }
}

/// Options of an ingest.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct IngestOptions {
    /// Worker threads for replaying traces (0 = all cores).
    pub threads: usize,
}

/// A path's canonical form when it has one (so that the same file ingested from another working
/// directory has the same natural key), else the path as given.
fn origin_of(path: &Path) -> String {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_owned()).display().to_string()
}

/// `true` when `path` looks like a candump log: a `.log` file, or one whose first non-blank,
/// non-comment line starts with `(`.
pub fn is_can_log(path: &Path) -> bool {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("log")) {
        return true;
    }
    let Ok(f) = std::fs::File::open(path) else { return false };
    let reader = std::io::BufReader::new(f);
    for line in reader.lines().take(64) {
        let Ok(line) = line else { return false };
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        return t.starts_with('(');
    }
    false
}

/// Replays one trace into its release record. `rank` is the trace's rank among its
/// locomotive's traces, the release number when the trace has no `release` metadata.
pub fn trace_record(item: &TraceItem, rank: usize) -> Result<Result<ReleaseRecord, FileError>> {
    let meta = match TraceReader::open(&item.path) {
        Ok(r) => r,
        Err(e) => return Ok(Err(e.into())),
    };
    let name = item.path.display().to_string();
    let (release_no, time_s) = match release_meta(|k| meta.meta(k)) {
        Ok(x) => x,
        Err(m) => return Ok(Err(FileError::new(&name, 0, m))),
    };
    let numbered = release_no.is_some();
    let release_no = release_no.unwrap_or(rank as i64);
    drop(meta);
    let content_hash = match std::fs::read(&item.path) {
        Ok(bytes) => Some(samples_hash(&String::from_utf8_lossy(&bytes))),
        Err(e) => return Ok(Err(FileError::new(&name, 0, format!("cannot read: {e}")))),
    };
    // The release curve, thinned to the stored step, is kept as the samples go by; the frames
    // the controller sent are kept and decoded as the cab display would.
    let mut curve_keeper = CurveKeeper::new();
    let replay = match replay_item_observing(item, &ReplayOptions::default(), 0, true, |s| curve_keeper.push(s)) {
        Ok(r) => r,
        Err(ReplayError::Input(e)) => return Ok(Err(e)),
        Err(ReplayError::Output(e)) => return Err(e),
    };
    let detail = curve_keeper.detail(&replay);
    Ok(Ok(record_of(
        &replay,
        origin_of(&item.path),
        "0".to_owned(),
        release_no,
        time_s,
        content_hash,
        numbered,
        detail,
    )))
}

/// The release curve, thinned to the stored step as the samples go by.
struct CurveKeeper {
    stride: usize,
    index: usize,
    curve: ReleaseCurve,
}

impl CurveKeeper {
    fn new() -> Self {
        let stride = (CURVE_STEP_S / pbm::twin::SAMPLE_PERIOD_S).round().max(1.0) as usize;
        Self { stride, index: 0, curve: ReleaseCurve { step_s: CURVE_STEP_S, ..ReleaseCurve::default() } }
    }

    fn push(&mut self, s: &ReplaySample) {
        if self.index % self.stride == 0 {
            self.curve.measured_bar.push(s.measured_bar() as f32);
            self.curve.twin_bar.push(s.twin_bar() as f32);
        }
        self.index += 1;
    }

    /// The stored detail of a replay: this curve and the fault reports the controller's frames
    /// carry, decoded as the cab display would.
    fn detail(self, replay: &TraceReplay) -> ReleaseDetail {
        let curve = self.curve;
        ReleaseDetail {
            curve: (!curve.twin_bar.is_empty()).then_some(curve),
            can_reports: decode_frames(&replay.replayed.frames),
        }
    }
}

/// The record of a replayed trace.
#[allow(clippy::too_many_arguments)]
fn record_of(
    replay: &TraceReplay,
    origin: String,
    release_key: String,
    release_no: i64,
    time_s: Option<f64>,
    content_hash: Option<String>,
    numbered: bool,
    detail: ReleaseDetail,
) -> ReleaseRecord {
    let s = &replay.summary;
    let est = s.last.map(|l| l.estimates);
    let f = |v: Option<f32>| v.map(f64::from).filter(|x| x.is_finite());
    let label = (s.label != "-").then(|| s.label.clone());
    ReleaseRecord {
        locomotive: s.locomotive.clone(),
        source: Source::Trace,
        origin,
        release_key,
        release_no,
        time_s,
        verdict: s.diagnosis.map(|d| d.verdict),
        orifice_mm: f(est.and_then(|e| e.orifice_mm)),
        leak_mm: f(est.and_then(|e| e.leak_mm)),
        supply_bar_g: f(est.and_then(|e| e.supply_bar_g)),
        label,
        content_hash,
        numbered,
        detail,
    }
}

/// Reads the metadata `release` (an integer) and `time_s` (a finite number) of a trace.
fn release_meta<'a>(meta: impl Fn(&str) -> Option<&'a str>) -> Result<(Option<i64>, Option<f64>), String> {
    let release_no = match meta("release") {
        Some(v) => Some(v.parse::<i64>().map_err(|_| format!("metadata `release: {v}` is not an integer"))?),
        None => None,
    };
    let time_s = match meta("time_s") {
        Some(v) => match v.parse::<f64>() {
            Ok(t) if t.is_finite() => Some(t),
            _ => return Err(format!("metadata `time_s: {v}` is not a finite number")),
        },
        None => None,
    };
    Ok((release_no, time_s))
}

/// The record of one archived release: replayed as a trace; its natural key is the archive
/// (canonical path) and the release id, its fingerprint that of the trace CSV it unpacks to
/// (so a release already stored from its trace file is recognised).
fn archive_record(
    name: &str,
    origin: &str,
    r: &ArchivedRelease,
    rank: usize,
) -> Result<Result<ReleaseRecord, FileError>> {
    let (release_no, time_s) = match release_meta(|k| r.meta(k)) {
        Ok(x) => x,
        Err(m) => return Ok(Err(FileError::new(name, 0, format!("release {} of {}: {m}", r.release, r.locomotive)))),
    };
    let mut csv = Vec::new();
    r.write_csv(&mut csv)?;
    let content_hash = Some(samples_hash(&String::from_utf8_lossy(&csv)));
    let mut curve_keeper = CurveKeeper::new();
    let replay = match replay_archived_observing(name, r, &ReplayOptions::default(), 0, true, |s| curve_keeper.push(s))
    {
        Ok(t) => t,
        Err(ReplayError::Input(e)) => return Ok(Err(e)),
        Err(ReplayError::Output(e)) => return Err(e),
    };
    let numbered = release_no.is_some();
    let release_no = release_no.unwrap_or(rank as i64);
    let detail = curve_keeper.detail(&replay);
    Ok(Ok(record_of(&replay, origin.to_owned(), r.release.clone(), release_no, time_s, content_hash, numbered, detail)))
}

/// Ingests the releases of the fleet archive `path`: each release is one transaction, as a
/// trace file is; read and replayed 256 at a time in parallel (memory: one chunk of releases).
fn ingest_archive(
    db: &mut FleetDb,
    path: &Path,
    pool: &rayon::ThreadPool,
    summary: &mut IngestSummary,
) -> Result<usize> {
    let reader = match ArchiveReader::open(path) {
        Ok(r) => r,
        Err(e) => {
            summary.skipped.push(e);
            return Ok(1);
        }
    };
    let name = reader.name().to_owned();
    let origin = origin_of(path);
    let groups = reader.selected();
    let mut seen: HashMap<String, usize> = HashMap::new();
    for chunk in groups.chunks(256) {
        let read: Vec<Result<ArchivedRelease, FileError>> =
            pool.install(|| chunk.par_iter().map(|&i| reader.read(i)).collect());
        let ranked: Vec<Result<(ArchivedRelease, usize), FileError>> = read
            .into_iter()
            .map(|r| {
                r.map(|r| {
                    let n = seen.entry(r.locomotive.clone()).or_insert(0);
                    *n += 1;
                    (r, *n - 1)
                })
            })
            .collect();
        let records: Vec<Result<Result<ReleaseRecord, FileError>>> = pool.install(|| {
            ranked
                .par_iter()
                .map(|r| match r {
                    Ok((r, rank)) => archive_record(&name, &origin, r, *rank),
                    Err(e) => Ok(Err(e.clone())),
                })
                .collect()
        });
        for r in records {
            match db.store_file([r?])? {
                Ok(s) => summary.add(s),
                Err(e) => summary.skipped.push(e),
            }
        }
    }
    Ok(groups.len())
}

/// The fault reports among a replayed release's frames, decoded by the core's decoder as the
/// cab display decodes a log of them (times from the release's start).
pub fn decode_frames(frames: &[TimedFrame]) -> Vec<CanReport> {
    let mut decoder = Decoder::new();
    let mut out = Vec::new();
    for f in frames {
        let reception = decoder.receive(pbm::can::candump::LOG_EPOCH_US + f.time_us, &f.frame);
        if let (Ok(Report::Fault(report)), Some(id)) = (reception.result, reception.identity) {
            out.push(CanReport {
                time_s: f.time_us as f64 / 1e6,
                can_release: id.release,
                report,
                current: !reception.stale,
                lost_before: reception.lost_fault_reports,
            });
        }
    }
    out
}

/// The releases of a candump log: one per (locomotive, release number) run of fault reports,
/// holding its last report; the log lines that are not frames come back as errors (file and
/// line) to be reported as skipped.
pub fn can_records(name: &str, origin: &str, reader: impl BufRead) -> (Vec<ReleaseRecord>, Vec<FileError>) {
    let mut decoder = Decoder::new();
    let mut records: Vec<ReleaseRecord> = Vec::new();
    // Per locomotive number: (release number, index into `records`) of the open release, and
    // how many releases of it the log has shown so far.
    let mut open: HashMap<u8, (u8, usize)> = HashMap::new();
    let mut count: HashMap<u8, i64> = HashMap::new();
    let mut errors = Vec::new();
    let mut anonymous = 0usize;
    for item in pbm_io::can_log::read_log(reader) {
        let rec = match item {
            Ok(r) => r,
            Err(e) => {
                errors.push(FileError::new(name, e.line, e.reason));
                continue;
            }
        };
        // Flagged frames (bad CRC, counter, freshness) are the decoder's to refuse, as on the
        // cab display; only accepted fault reports become releases.
        let reception = decoder.receive(rec.time_us, &rec.frame);
        let Ok(Report::Fault(report)) = reception.result else { continue };
        let Some(id) = reception.identity else {
            anonymous += 1;
            continue;
        };
        let (supply, leak) = can_estimates(&report);
        let decoded = CanReport {
            time_s: rec.time_us as f64 / 1e6,
            can_release: id.release,
            report,
            current: !reception.stale,
            lost_before: reception.lost_fault_reports,
        };
        let fill = |r: &mut ReleaseRecord| {
            r.verdict = Some(report.verdict);
            r.supply_bar_g = supply;
            r.leak_mm = leak;
            r.detail.can_reports.push(decoded);
        };
        match open.get(&id.locomotive) {
            Some(&(release, index)) if release == id.release => fill(&mut records[index]),
            _ => {
                let n = count.entry(id.locomotive).or_insert(0);
                let mut r = ReleaseRecord {
                    locomotive: can_locomotive_name(id.locomotive),
                    source: Source::Can,
                    origin: origin.to_owned(),
                    // The release number wraps (6 bits): the time of its first report makes
                    // the key unique within the log.
                    release_key: format!("{}@{}", id.release, rec.time_us),
                    release_no: *n,
                    time_s: Some(rec.time_us as f64 / 1e6),
                    verdict: None,
                    orifice_mm: None,
                    leak_mm: None,
                    supply_bar_g: None,
                    label: None,
                    content_hash: None,
                    numbered: false,
                    detail: ReleaseDetail::default(),
                };
                *n += 1;
                fill(&mut r);
                open.insert(id.locomotive, (id.release, records.len()));
                records.push(r);
            }
        }
    }
    if anonymous > 0 {
        errors.push(FileError::new(
            name,
            0,
            format!("{anonymous} fault reports without a locomotive identity ignored"),
        ));
    }
    (records, errors)
}

/// Ingests every path (trace files, data set directories, candump logs) into `db`; returns
/// what was stored and skipped. Fails only on a database error, or when nothing at all could
/// be read.
pub fn ingest(db: &mut FleetDb, paths: &[impl AsRef<Path>], opts: &IngestOptions) -> Result<IngestSummary> {
    let start = Instant::now();
    let mut summary = IngestSummary::default();
    let mut attempted = 0usize;
    for path in paths {
        let path = path.as_ref();
        if path.is_file() && is_can_log(path) {
            attempted += 1;
            let name = path.display().to_string();
            let file = match pbm_io::files::open_regular(path) {
                Ok(f) => f,
                Err(e) => {
                    summary.skipped.push(FileError::new(&name, 0, format!("{e:#}")));
                    continue;
                }
            };
            let (records, errors) = can_records(&name, &origin_of(path), std::io::BufReader::new(file));
            for e in errors {
                summary.skipped.push(e);
            }
            match db.store_file(records.into_iter().map(Ok))? {
                Ok(s) => summary.add(s),
                Err(e) => summary.skipped.push(e),
            }
            continue;
        }
        if path.is_file() && is_archive(path) {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(opts.threads).build()?;
            attempted += ingest_archive(db, path, &pool, &mut summary)?;
            continue;
        }
        let (items, skipped) = match pbm_lab::replay::items(path, None) {
            Ok(x) => x,
            Err(e) => {
                summary.skipped.push(FileError::new(path.display(), 0, format!("{e:#}")));
                continue;
            }
        };
        summary.skipped.extend(skipped);
        attempted += items.len();
        // Rank of each trace among its locomotive's, in manifest order.
        let mut seen: HashMap<&str, usize> = HashMap::new();
        let ranks: Vec<usize> = items
            .iter()
            .map(|i| {
                let n = seen.entry(i.locomotive.as_deref().unwrap_or("-")).or_insert(0);
                *n += 1;
                *n - 1
            })
            .collect();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(opts.threads).build()?;
        // Replays run in parallel, in chunks so that memory stays bounded and each finished
        // chunk is committed (file by file) before the next is replayed.
        for (chunk, ranks) in items.chunks(256).zip(ranks.chunks(256)) {
            let records: Vec<Result<Result<ReleaseRecord, FileError>>> =
                pool.install(|| chunk.par_iter().zip(ranks).map(|(item, &rank)| trace_record(item, rank)).collect());
            for r in records {
                match db.store_file([r?])? {
                    Ok(s) => summary.add(s),
                    Err(e) => summary.skipped.push(e),
                }
            }
        }
    }
    summary.elapsed = start.elapsed();
    if attempted > 0 && summary.files == 0 {
        bail!("nothing could be ingested\n{}", summary.skipped);
    }
    if attempted == 0 && !summary.skipped.is_empty() {
        bail!("nothing to ingest\n{}", summary.skipped);
    }
    Ok(summary)
}
