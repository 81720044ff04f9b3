//! The fleet history: an SQLite file (through `rusqlite`, SQLite compiled in, no server).
//!
//! # Schema
//!
//! `releases` holds one row per release of a locomotive (columns in [`SCHEMA`]); since schema 3
//! `release_curves` (its measured and twin pressure, [`ReleaseCurve::to_blob`]) and
//! `can_reports` (the fault reports the cab decoded) hang off a release's row and are replaced
//! with it. A database of an older schema is migrated when opened (schema 2 → 3 only adds the
//! two tables: its releases have no curve and no reports until ingested again). A release's
//! natural key is (`locomotive`, `source`, `origin`, `release_key`) under a UNIQUE constraint:
//! the same release ingested again (same file, same release in it) updates its row in place
//! (`INSERT … ON CONFLICT … DO UPDATE`) instead of adding one, so re-ingesting is idempotent,
//! and a re-ingest after the monitor changed refreshes the verdicts.
//!
//! # Crashes and concurrency
//!
//! - Each input file is stored in one transaction ([`FleetDb::store_file`]): a crash or a bad
//!   record mid-file leaves none of that file's rows and every earlier file's rows.
//! - The database runs in WAL mode with `synchronous = NORMAL` (a commit survives a process
//!   crash; only an OS crash may lose the last commits, never corrupt the file) and a busy
//!   timeout ([`BUSY_TIMEOUT`]); writers take the write lock when the transaction begins
//!   (`BEGIN IMMEDIATE`), so two ingests at once queue for it instead of failing with a
//!   deadlock on lock upgrade.

use crate::record::{verdict_label, ReleaseCurve, ReleaseRecord, Source};
use anyhow::{Context, Result};
use pbm_io::error::FileError;
use rusqlite::{params, Connection, OpenFlags, OptionalExtension, TransactionBehavior};
use std::path::Path;
use std::time::Duration;

/// How long a writer waits for another's transaction before giving up.
pub const BUSY_TIMEOUT: Duration = Duration::from_secs(60);

/// Version of the schema, kept in `PRAGMA user_version`.
pub const SCHEMA_VERSION: i64 = 3;

/// The tables (idempotent: run on every open).
pub const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS releases (
    id             INTEGER PRIMARY KEY,
    locomotive     TEXT    NOT NULL,
    source         TEXT    NOT NULL CHECK (source IN ('trace', 'can')),
    origin         TEXT    NOT NULL,
    release_key    TEXT    NOT NULL,
    release_no     INTEGER NOT NULL,
    time_s         REAL,
    verdict        TEXT    NOT NULL,
    confidence_pct INTEGER CHECK (confidence_pct BETWEEN 0 AND 100),
    no_diagnosis   TEXT,
    orifice_mm     REAL,
    leak_mm        REAL,
    supply_bar_g   REAL,
    label          TEXT,
    content_hash   TEXT,
    numbered       INTEGER NOT NULL DEFAULT 0,
    ingested_at    TEXT    NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')),
    UNIQUE (locomotive, source, origin, release_key)
);
CREATE INDEX IF NOT EXISTS releases_by_loco ON releases (locomotive, release_no, time_s);
CREATE TABLE IF NOT EXISTS release_curves (
    release_id     INTEGER PRIMARY KEY REFERENCES releases (id),
    step_s         REAL    NOT NULL,
    points         BLOB    NOT NULL
);
CREATE TABLE IF NOT EXISTS can_reports (
    release_id     INTEGER NOT NULL REFERENCES releases (id),
    seq            INTEGER NOT NULL,
    time_s         REAL    NOT NULL,
    can_release    INTEGER NOT NULL,
    verdict        TEXT    NOT NULL,
    confidence_pct INTEGER,
    no_diagnosis   TEXT,
    since_command_s REAL   NOT NULL,
    supply_bar_g   REAL,
    leak_mm        REAL,
    completed      INTEGER NOT NULL,
    current        INTEGER NOT NULL,
    lost_before    INTEGER NOT NULL,
    PRIMARY KEY (release_id, seq)
);
";

/// Schema 1 → 2: the samples' fingerprint and whether the release number is the trace's own.
const MIGRATE_2: &str = "
ALTER TABLE releases ADD COLUMN content_hash TEXT;
ALTER TABLE releases ADD COLUMN numbered INTEGER NOT NULL DEFAULT 0;
";

/// Index of the duplicate checks (created after a migration has added the column).
const INDEX_2: &str = "CREATE INDEX IF NOT EXISTS releases_by_hash ON releases (locomotive, content_hash);";

const UPSERT: &str = "
INSERT INTO releases (locomotive, source, origin, release_key, release_no, time_s, verdict,
                      confidence_pct, no_diagnosis, orifice_mm, leak_mm, supply_bar_g, label,
                      content_hash, numbered)
VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15)
ON CONFLICT (locomotive, source, origin, release_key) DO UPDATE SET
    release_no = excluded.release_no, time_s = excluded.time_s, verdict = excluded.verdict,
    confidence_pct = excluded.confidence_pct, no_diagnosis = excluded.no_diagnosis,
    orifice_mm = excluded.orifice_mm, leak_mm = excluded.leak_mm,
    supply_bar_g = excluded.supply_bar_g, label = excluded.label,
    content_hash = excluded.content_hash, numbered = excluded.numbered,
    ingested_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now')
";

/// An open fleet history.
pub struct FleetDb {
    conn: Connection,
}

/// What storing one file did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Stored {
    /// Releases written (new or updated).
    pub releases: usize,
    /// Of those, releases that were new.
    pub new: usize,
    /// Releases not stored because the locomotive already has them from another file (same
    /// samples, or same `release` number of a numbered trace), as `file: why`.
    pub duplicates: Vec<String>,
}

/// A stored release (a row of `releases`).
#[derive(Debug, Clone, PartialEq)]
pub struct StoredRelease {
    /// Row id (the key of its curve and CAN reports in this database).
    pub id: i64,
    /// Locomotive name.
    pub locomotive: String,
    /// `trace` or `can`.
    pub source: String,
    /// Input file.
    pub origin: String,
    /// Release within the file.
    pub release_key: String,
    /// Position on the locomotive's timeline.
    pub release_no: i64,
    /// Time, s, when known.
    pub time_s: Option<f64>,
    /// Verdict label (a class, `cannot_diagnose` or `none`).
    pub verdict: String,
    /// Confidence of a named class, per cent.
    pub confidence_pct: Option<i64>,
    /// Why no class was named.
    pub no_diagnosis: Option<String>,
    /// Estimated release orifice, mm.
    pub orifice_mm: Option<f64>,
    /// Estimated leak, mm.
    pub leak_mm: Option<f64>,
    /// Estimated supply, bar g.
    pub supply_bar_g: Option<f64>,
    /// Label carried by the input.
    pub label: Option<String>,
    /// Fingerprint of a trace's samples.
    pub content_hash: Option<String>,
    /// The release number is the trace's own `release` metadata.
    pub numbered: bool,
}

/// Where a stored release came from, for messages: its file, and the release within the file
/// when the file holds many (an archive's release id; a trace file's key is `0`).
fn place(origin: &str, release_key: &str) -> String {
    if release_key == "0" {
        origin.to_owned()
    } else {
        format!("{origin} [{release_key}]")
    }
}

impl FleetDb {
    /// Opens (creating if needed) the fleet history at `path`.
    pub fn open(path: &Path) -> Result<Self> {
        let conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_WRITE | OpenFlags::SQLITE_OPEN_CREATE | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .with_context(|| format!("cannot open the fleet database {}", path.display()))?;
        // The busy timeout comes first: switching to WAL itself needs a lock another process
        // may hold.
        conn.busy_timeout(BUSY_TIMEOUT)?;
        // Two first opens of a new file race for the lock that switching to WAL takes, and
        // SQLite answers the loser with "busy" at once, without calling the busy handler (its
        // deadlock avoidance): wait and retry here, within the same timeout (a CI run found
        // two threads' first opens failing).
        let deadline = std::time::Instant::now() + BUSY_TIMEOUT;
        let mode: String = loop {
            match conn.query_row("PRAGMA journal_mode = WAL", [], |r| r.get(0)) {
                Ok(mode) => break mode,
                Err(rusqlite::Error::SqliteFailure(e, _))
                    if e.code == rusqlite::ErrorCode::DatabaseBusy && std::time::Instant::now() < deadline =>
                {
                    std::thread::sleep(std::time::Duration::from_millis(20));
                }
                Err(e) => {
                    return Err(e)
                        .with_context(|| format!("{}: not a fleet database (cannot set WAL mode)", path.display()))
                }
            }
        };
        if !mode.eq_ignore_ascii_case("wal") {
            anyhow::bail!("{}: the database refused WAL mode (journal mode {mode})", path.display());
        }
        conn.pragma_update(None, "synchronous", "NORMAL")?;
        let version: i64 = conn.query_row("PRAGMA user_version", [], |r| r.get(0))?;
        if version > SCHEMA_VERSION {
            anyhow::bail!(
                "{}: fleet database schema {version} is newer than this tool's ({SCHEMA_VERSION})",
                path.display()
            );
        }
        // Creating the schema is one immediate transaction, so two first opens do not race.
        let tx = Self::begin(&conn)?;
        tx.execute_batch(SCHEMA).with_context(|| format!("{}: not a fleet database", path.display()))?;
        let has_hash: bool =
            tx.query_row("SELECT count(*) FROM pragma_table_info('releases') WHERE name = 'content_hash'", [], |r| {
                r.get::<_, i64>(0)
            })? > 0;
        if !has_hash {
            tx.execute_batch(MIGRATE_2)
                .with_context(|| format!("{}: cannot migrate the fleet database", path.display()))?;
        }
        tx.execute_batch(INDEX_2)?;
        tx.pragma_update(None, "user_version", SCHEMA_VERSION)?;
        tx.commit()?;
        Ok(Self { conn })
    }

    fn begin(conn: &Connection) -> Result<rusqlite::Transaction<'_>> {
        // `Transaction::new_unchecked` would allow nesting; a fresh immediate one is what we want.
        rusqlite::Transaction::new_unchecked(conn, TransactionBehavior::Immediate)
            .context("cannot start a database transaction")
    }

    /// Stores the releases of one input file in one transaction. The releases come as the
    /// input is read: when one is an input error, nothing of this file is stored (the
    /// transaction rolls back) and the error comes back as `Ok(Err(…))`; `Err` is a database
    /// failure.
    pub fn store_file(
        &mut self,
        releases: impl IntoIterator<Item = Result<ReleaseRecord, FileError>>,
    ) -> Result<Result<Stored, FileError>> {
        let tx = Self::begin(&self.conn)?;
        let mut stored = Stored::default();
        {
            let mut exists = tx.prepare_cached(
                "SELECT 1 FROM releases WHERE locomotive = ?1 AND source = ?2 AND origin = ?3 AND release_key = ?4",
            )?;
            let mut upsert = tx.prepare_cached(UPSERT)?;
            let mut id_of = tx.prepare_cached(
                "SELECT id FROM releases WHERE locomotive = ?1 AND source = ?2 AND origin = ?3 AND release_key = ?4",
            )?;
            let mut drop_curve = tx.prepare_cached("DELETE FROM release_curves WHERE release_id = ?1")?;
            let mut drop_reports = tx.prepare_cached("DELETE FROM can_reports WHERE release_id = ?1")?;
            let mut put_curve =
                tx.prepare_cached("INSERT INTO release_curves (release_id, step_s, points) VALUES (?1, ?2, ?3)")?;
            let mut put_report = tx.prepare_cached(
                "INSERT INTO can_reports (release_id, seq, time_s, can_release, verdict, confidence_pct, no_diagnosis,
                                          since_command_s, supply_bar_g, leak_mm, completed, current, lost_before)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13)",
            )?;
            let mut same_samples = tx.prepare_cached(
                "SELECT origin, release_key FROM releases WHERE locomotive = ?1 AND content_hash = ?2 LIMIT 1",
            )?;
            let mut same_number = tx.prepare_cached(
                "SELECT origin FROM releases WHERE locomotive = ?1 AND source = ?2 AND release_no = ?3 AND numbered = 1 LIMIT 1",
            )?;
            for r in releases {
                let r = match r {
                    Ok(r) => r,
                    // Dropping the transaction rolls it back.
                    Err(e) => return Ok(Err(e)),
                };
                let key = params![r.locomotive, r.source.label(), r.origin, r.release_key];
                let known = exists.query_row(key, |_| Ok(())).optional()?.is_some();
                if !known {
                    let same: Option<String> = match &r.content_hash {
                        Some(h) => same_samples
                            .query_row(params![r.locomotive, h], |row| {
                                Ok(place(&row.get::<_, String>(0)?, &row.get::<_, String>(1)?))
                            })
                            .optional()?,
                        None => None,
                    };
                    let why = match same {
                        Some(o) => Some(format!("same samples as {o}")),
                        None if r.numbered => same_number
                            .query_row(params![r.locomotive, r.source.label(), r.release_no], |row| {
                                row.get::<_, String>(0)
                            })
                            .optional()?
                            .map(|o| {
                                format!("release {} of {} is already stored from {o}", r.release_no, r.locomotive)
                            }),
                        None => None,
                    };
                    if let Some(why) = why {
                        stored.duplicates.push(format!("{}: {why}", place(&r.origin, &r.release_key)));
                        continue;
                    }
                }
                upsert.execute(params![
                    r.locomotive,
                    r.source.label(),
                    r.origin,
                    r.release_key,
                    r.release_no,
                    r.time_s,
                    r.verdict_label(),
                    r.confidence_pct(),
                    r.no_diagnosis(),
                    r.orifice_mm,
                    r.leak_mm,
                    r.supply_bar_g,
                    r.label,
                    r.content_hash,
                    r.numbered,
                ])?;
                let id: i64 = id_of.query_row(key, |row| row.get(0))?;
                drop_curve.execute([id])?;
                drop_reports.execute([id])?;
                if let Some(c) = &r.detail.curve {
                    put_curve.execute(params![id, c.step_s, c.to_blob()])?;
                }
                for (seq, c) in r.detail.can_reports.iter().enumerate() {
                    put_report.execute(params![
                        id,
                        seq as i64,
                        c.time_s,
                        c.can_release,
                        verdict_label(Some(&c.report.verdict)),
                        crate::record::confidence_of(&c.report.verdict),
                        crate::record::no_diagnosis_of(&c.report.verdict),
                        f64::from(c.report.time_since_release_cs) / 100.0,
                        crate::record::can_estimates(&c.report).0,
                        crate::record::can_estimates(&c.report).1,
                        c.report.release_completed,
                        c.current,
                        c.lost_before,
                    ])?;
                }
                stored.releases += 1;
                stored.new += usize::from(!known);
            }
        }
        tx.commit().context("cannot commit to the fleet database")?;
        Ok(Ok(stored))
    }

    /// Number of stored releases.
    pub fn count(&self) -> Result<i64> {
        Ok(self.conn.query_row("SELECT count(*) FROM releases", [], |r| r.get(0))?)
    }

    /// The locomotives, sorted by name.
    pub fn locomotives(&self) -> Result<Vec<String>> {
        let mut s = self.conn.prepare("SELECT DISTINCT locomotive FROM releases ORDER BY locomotive")?;
        let rows = s.query_map([], |r| r.get(0))?;
        Ok(rows.collect::<rusqlite::Result<_>>()?)
    }

    /// The releases of one locomotive in timeline order (release number, then time, then
    /// source and origin so the order is total and stable).
    pub fn releases(&self, locomotive: &str) -> Result<Vec<StoredRelease>> {
        let mut s = self.conn.prepare_cached(
            "SELECT locomotive, source, origin, release_key, release_no, time_s, verdict, confidence_pct,
                    no_diagnosis, orifice_mm, leak_mm, supply_bar_g, label, content_hash, numbered, id
             FROM releases WHERE locomotive = ?1
             ORDER BY release_no, time_s, source, origin, release_key",
        )?;
        let rows = s.query_map([locomotive], |r| {
            Ok(StoredRelease {
                locomotive: r.get(0)?,
                source: r.get(1)?,
                origin: r.get(2)?,
                release_key: r.get(3)?,
                release_no: r.get(4)?,
                time_s: r.get(5)?,
                verdict: r.get(6)?,
                confidence_pct: r.get(7)?,
                no_diagnosis: r.get(8)?,
                orifice_mm: r.get(9)?,
                leak_mm: r.get(10)?,
                supply_bar_g: r.get(11)?,
                label: r.get(12)?,
                content_hash: r.get(13)?,
                numbered: r.get(14)?,
                id: r.get(15)?,
            })
        })?;
        Ok(rows.collect::<rusqlite::Result<_>>()?)
    }

    /// The stored release curve of a release ([`StoredRelease::id`]), if it has one.
    pub fn curve(&self, release_id: i64) -> Result<Option<ReleaseCurve>> {
        let mut s = self.conn.prepare_cached("SELECT step_s, points FROM release_curves WHERE release_id = ?1")?;
        let row: Option<(f64, Vec<u8>)> = s.query_row([release_id], |r| Ok((r.get(0)?, r.get(1)?))).optional()?;
        Ok(row.and_then(|(step, blob)| ReleaseCurve::from_blob(step, &blob)))
    }

    /// The decoded CAN fault reports of a release ([`StoredRelease::id`]), in order.
    pub fn can_reports(&self, release_id: i64) -> Result<Vec<StoredCanReport>> {
        let mut s = self.conn.prepare_cached(
            "SELECT time_s, can_release, verdict, confidence_pct, no_diagnosis, since_command_s, supply_bar_g,
                    leak_mm, completed, current, lost_before
             FROM can_reports WHERE release_id = ?1 ORDER BY seq",
        )?;
        let rows = s.query_map([release_id], |r| {
            Ok(StoredCanReport {
                time_s: r.get(0)?,
                can_release: r.get(1)?,
                verdict: r.get(2)?,
                confidence_pct: r.get(3)?,
                no_diagnosis: r.get(4)?,
                since_command_s: r.get(5)?,
                supply_bar_g: r.get(6)?,
                leak_mm: r.get(7)?,
                completed: r.get(8)?,
                current: r.get(9)?,
                lost_before: r.get(10)?,
            })
        })?;
        Ok(rows.collect::<rusqlite::Result<_>>()?)
    }

    /// The schema version of the open database (`PRAGMA user_version`).
    pub fn schema_version(&self) -> Result<i64> {
        Ok(self.conn.query_row("PRAGMA user_version", [], |r| r.get(0))?)
    }

    /// SQLite's own consistency check (`PRAGMA integrity_check`): `ok` or what is wrong.
    pub fn integrity_check(&self) -> Result<String> {
        Ok(self.conn.query_row("PRAGMA integrity_check", [], |r| r.get(0))?)
    }

    /// Rows whose natural key appears more than once (0 unless the UNIQUE constraint is gone).
    pub fn duplicate_keys(&self) -> Result<i64> {
        Ok(self.conn.query_row(
            "SELECT count(*) FROM (SELECT 1 FROM releases GROUP BY locomotive, source, origin, release_key
                                   HAVING count(*) > 1)",
            [],
            |r| r.get(0),
        )?)
    }

    /// Moves the write-ahead log into the main file (for a size measurement or a copy).
    pub fn checkpoint(&self) -> Result<()> {
        self.conn.query_row("PRAGMA wal_checkpoint(TRUNCATE)", [], |_| Ok(()))?;
        Ok(())
    }
}

/// A decoded CAN fault report as stored (a row of `can_reports`).
#[derive(Debug, Clone, PartialEq)]
pub struct StoredCanReport {
    /// Time of the frame, s (since the release's start for a replayed trace; the log's clock for
    /// a CAN log).
    pub time_s: f64,
    /// The 6-bit release number the frame carries.
    pub can_release: i64,
    /// Verdict label (a class, `cannot_diagnose`).
    pub verdict: String,
    /// Calibrated confidence of a named class, per cent.
    pub confidence_pct: Option<i64>,
    /// Why no class was named.
    pub no_diagnosis: Option<String>,
    /// Time since the release command, s.
    pub since_command_s: f64,
    /// Supply estimate, bar g (none before it is estimated).
    pub supply_bar_g: Option<f64>,
    /// Leak estimate, mm.
    pub leak_mm: Option<f64>,
    /// The release had completed.
    pub completed: bool,
    /// A heartbeat vouched for the report (else the display shows it as stale).
    pub current: bool,
    /// Reports sent before it that the display never received.
    pub lost_before: i64,
}

/// Whether `s` names a source the database stores.
pub fn source_of(s: &str) -> Option<Source> {
    [Source::Trace, Source::Can].into_iter().find(|x| x.label() == s)
}
