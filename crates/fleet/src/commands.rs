//! The `host-sim fleet …` commands, one options struct each (the command line only parses).

use crate::db::FleetDb;
use crate::ingest::{ingest, IngestOptions};
use crate::scenario::{write, DegradationOptions, Wear};
use crate::status::{lines, status};
use crate::trend::WarningRule;
use anyhow::{bail, Result};
use pbm_io::error::Skipped;
use std::path::PathBuf;

/// `fleet ingest`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IngestRun {
    /// The fleet database (created if absent).
    pub db: PathBuf,
    /// Trace files, data set directories and candump logs.
    pub paths: Vec<PathBuf>,
    /// Replay options.
    pub options: IngestOptions,
}

/// Ingests; prints what was stored (stderr); returns what was skipped.
pub fn run_ingest(a: &IngestRun) -> Result<Skipped> {
    if a.paths.is_empty() {
        bail!("give at least one trace, data set directory or candump log to ingest");
    }
    let mut db = FleetDb::open(&a.db)?;
    let s = ingest(&mut db, &a.paths, &a.options)?;
    for d in s.duplicates.iter().take(10) {
        eprintln!("duplicate, not stored: {d}");
    }
    if s.duplicates.len() > 10 {
        eprintln!("… and {} more duplicates", s.duplicates.len() - 10);
    }
    eprintln!("{s}; {} releases in {}", db.count()?, a.db.display());
    Ok(s.skipped)
}

/// `fleet status`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StatusRun {
    /// The fleet database (must exist).
    pub db: PathBuf,
}

/// Prints one line per locomotive (stdout).
pub fn run_status(a: &StatusRun) -> Result<()> {
    if !a.db.is_file() {
        bail!("{}: no fleet database (create one with `fleet ingest`)", a.db.display());
    }
    for l in status_lines(&a.db)? {
        println!("{l}");
    }
    Ok(())
}

/// The lines `fleet status` prints for the database `db` (which must exist): one per
/// locomotive, or one line saying there are no releases.
pub fn status_lines(db: &std::path::Path) -> Result<Vec<String>> {
    let store = FleetDb::open(db)?;
    let s = status(&store, &WarningRule::default())?;
    if s.is_empty() {
        return Ok(vec![format!("no releases in {}", db.display())]);
    }
    Ok(lines(&s))
}

/// `fleet degrade`: writes the slow-degradation scenario as a data set.
#[derive(Debug, Clone, PartialEq)]
pub struct DegradeRun {
    /// Output directory (empty or absent).
    pub out: PathBuf,
    /// Healthy locomotives, then leaking ones, then clogging ones.
    pub healthy: usize,
    /// Locomotives with a growing leak.
    pub leak: usize,
    /// Locomotives with a clogging release orifice.
    pub clog: usize,
    /// Locomotives with a healthy brake whose transducer fails from the onset on.
    pub sensor: usize,
    /// Seed, releases, onset and end points.
    pub options: DegradationOptions,
}

/// Writes the scenario; says what it wrote (stderr).
pub fn run_degrade(a: &DegradeRun) -> Result<()> {
    let mut wear = vec![Wear::Healthy; a.healthy];
    wear.extend(std::iter::repeat_n(Wear::Leak, a.leak));
    wear.extend(std::iter::repeat_n(Wear::Clog, a.clog));
    wear.extend(std::iter::repeat_n(Wear::Sensor, a.sensor));
    let o = DegradationOptions { wear, ..a.options.clone() };
    let written = write(&o, &a.out)?;
    eprintln!("wrote {} releases of {} locomotives to {}", written.len(), o.wear.len(), a.out.display());
    Ok(())
}

/// `fleet report`: the fleet page.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReportRun {
    /// The fleet database (must exist).
    pub db: PathBuf,
    /// Output directory (`index.html` is written there).
    pub out: PathBuf,
}

/// Writes the page; says where (stderr).
pub fn run_report(a: &ReportRun) -> Result<()> {
    if !a.db.is_file() {
        bail!("{}: no fleet database (create one with `fleet ingest`)", a.db.display());
    }
    let db = FleetDb::open(&a.db)?;
    let path = crate::report::write(&db, &a.out, &WarningRule::default())?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// `fleet export`: the history as a Parquet file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExportRun {
    /// The fleet database (must exist).
    pub db: PathBuf,
    /// The Parquet file to write.
    pub out: PathBuf,
}

/// Writes the Parquet file; says how many rows (stderr).
pub fn run_export(a: &ExportRun) -> Result<()> {
    if !a.db.is_file() {
        bail!("{}: no fleet database (create one with `fleet ingest`)", a.db.display());
    }
    let db = FleetDb::open(&a.db)?;
    let rows = crate::export::export(&db, &a.out)?;
    eprintln!("wrote {rows} releases to {}", a.out.display());
    Ok(())
}
