//! The fleet history: idempotent re-ingest, concurrent ingests, a crash mid-ingest, bad input,
//! CAN logs.

use pbm_fleet::db::FleetDb;
use pbm_fleet::ingest::{can_records, ingest, IngestOptions};
use pbm_fleet::record::{ReleaseRecord, Source};
use pbm_fleet::scenario::{write, DegradationOptions, Wear};
use std::path::{Path, PathBuf};

/// A small degradation data set: `locos` locomotives × 8 releases.
fn small_set(dir: &Path, name: &str, seed: u64, wear: Vec<Wear>) -> PathBuf {
    let out = dir.join(name);
    let o = DegradationOptions { releases: 8, onset: 2, ..DegradationOptions::new(seed, wear) };
    write(&o, &out).expect("write the scenario");
    out
}

fn opts() -> IngestOptions {
    IngestOptions { threads: 1 }
}

#[test]
fn reingest_is_idempotent_and_status_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path(), "a", 5, vec![Wear::Healthy, Wear::Leak]);
    let db_path = dir.path().join("fleet.sqlite");
    let mut db = FleetDb::open(&db_path).unwrap();
    let first = ingest(&mut db, &[&set], &opts()).unwrap();
    assert_eq!((first.releases, first.new, first.files), (16, 16, 16));
    assert!(first.skipped.is_empty(), "{}", first.skipped);
    let second = ingest(&mut db, &[&set], &opts()).unwrap();
    assert_eq!((second.releases, second.new), (16, 0));
    // The same files named through another path are the same releases.
    let other = dir.path().join(".").join("a").join("..").join("a");
    let third = ingest(&mut db, &[&other], &opts()).unwrap();
    assert_eq!(third.new, 0);
    assert_eq!(db.count().unwrap(), 16);
    assert_eq!(db.duplicate_keys().unwrap(), 0);
    assert_eq!(db.locomotives().unwrap(), ["loco-01", "loco-02"]);
    let r = db.releases("loco-02").unwrap();
    assert_eq!(r.iter().map(|r| r.release_no).collect::<Vec<_>>(), (0..8).collect::<Vec<_>>());
    assert!(r.iter().all(|r| r.orifice_mm.is_some() && r.supply_bar_g.is_some() && r.verdict != "none"));
    let s = pbm_fleet::status::status(&db, &Default::default()).unwrap();
    let lines = pbm_fleet::status::lines(&s);
    assert_eq!(lines.len(), 2);
    assert!(lines[0].starts_with("loco-01  releases 8  latest normal"), "{}", lines[0]);
}

#[test]
fn two_threads_ingesting_at_once_give_the_union_without_duplicates() {
    let dir = tempfile::tempdir().unwrap();
    let a = small_set(dir.path(), "a", 11, vec![Wear::Healthy, Wear::Clog]);
    let b = small_set(dir.path(), "b", 12, vec![Wear::Leak, Wear::Healthy, Wear::Healthy]);
    let db_path = dir.path().join("fleet.sqlite");
    // Both threads ingest both sets (in opposite orders), each through its own connection.
    let handles: Vec<_> = [vec![a.clone(), b.clone()], vec![b.clone(), a.clone()]]
        .into_iter()
        .map(|paths| {
            let db_path = db_path.clone();
            std::thread::spawn(move || {
                let mut db = FleetDb::open(&db_path).unwrap();
                ingest(&mut db, &paths, &opts()).unwrap()
            })
        })
        .collect();
    let sums: Vec<_> = handles.into_iter().map(|h| h.join().unwrap()).collect();
    let db = FleetDb::open(&db_path).unwrap();
    // Both sets name their locomotives loco-01… and number their releases 0…7: set b's loco-01
    // and loco-02 releases are (locomotive, release number) pairs set a already has, so they
    // are duplicates, not new releases (16 of a + loco-03's 8 of b).
    assert_eq!(db.count().unwrap(), 16 + 8);
    assert_eq!(sums.iter().map(|s| s.new).sum::<usize>(), 24, "each release is new exactly once");
    assert_eq!(
        sums.iter().map(|s| s.duplicates.len()).sum::<usize>(),
        16 + 16,
        "the other names' copies, in both runs"
    );
    assert_eq!(db.duplicate_keys().unwrap(), 0);
    assert_eq!(db.integrity_check().unwrap(), "ok");
}

/// A release record of file `origin` (no replay needed for the crash test).
fn fake(origin: &str, k: i64) -> ReleaseRecord {
    ReleaseRecord {
        locomotive: "loco-09".into(),
        source: Source::Trace,
        origin: origin.into(),
        release_key: k.to_string(),
        release_no: k,
        time_s: None,
        verdict: None,
        orifice_mm: Some(1.25),
        leak_mm: Some(0.0),
        supply_bar_g: Some(7.7),
        label: None,
        content_hash: None,
        numbered: false,
    }
}

const CHILD_DB: &str = "PBM_FLEET_TEST_CHILD_DB";
const CHILD_MODE: &str = "PBM_FLEET_TEST_CHILD_MODE";

/// Runs this test binary's `child` test in a child process with `mode`.
fn spawn_child(db: &Path, mode: &str) -> std::process::Child {
    std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "child", "--nocapture", "--test-threads=1"])
        .env(CHILD_DB, db)
        .env(CHILD_MODE, mode)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap()
}

/// The child process's side of the process tests (does nothing when run as a normal test).
#[test]
fn child() {
    let (Some(db), Ok(mode)) = (std::env::var_os(CHILD_DB), std::env::var(CHILD_MODE)) else { return };
    let mut db = FleetDb::open(Path::new(&db)).unwrap();
    match mode.as_str() {
        "crash" => {
            db.store_file((0..50).map(|k| Ok(fake("committed.csv", k)))).unwrap().unwrap();
            // The process dies in the middle of the second file's transaction.
            let dying = (0..50).map(|k| {
                if k == 25 {
                    std::process::abort();
                }
                Ok(fake("torn.csv", k))
            });
            let _ = db.store_file(dying);
            unreachable!("the child aborts");
        }
        writer => {
            // Concurrent writer processes: 40 files of 5 releases each, every file shared by both.
            for f in 0..40 {
                let origin = format!("shared-{f}.csv");
                db.store_file((0..5).map(|k| Ok(fake(&origin, k)))).unwrap().unwrap();
            }
            let own = format!("{writer}.csv");
            db.store_file((0..5).map(|k| Ok(fake(&own, k)))).unwrap().unwrap();
        }
    }
}

#[test]
fn a_process_killed_mid_ingest_loses_only_its_open_file() {
    let dir = tempfile::tempdir().unwrap();
    let db_path = dir.path().join("fleet.sqlite");
    let status = spawn_child(&db_path, "crash").wait().unwrap();
    assert!(!status.success(), "the child must have died");
    let db = FleetDb::open(&db_path).unwrap();
    assert_eq!(db.integrity_check().unwrap(), "ok");
    assert_eq!(db.count().unwrap(), 50, "the committed file is whole, the torn one absent");
    let origins: std::collections::BTreeSet<String> =
        db.releases("loco-09").unwrap().into_iter().map(|r| r.origin).collect();
    assert_eq!(origins.into_iter().collect::<Vec<_>>(), ["committed.csv"]);
}

#[test]
fn two_processes_writing_at_once_do_not_corrupt_the_database() {
    let dir = tempfile::tempdir().unwrap();
    let db_path = dir.path().join("fleet.sqlite");
    let children = [spawn_child(&db_path, "w1"), spawn_child(&db_path, "w2")];
    for mut c in children {
        assert!(c.wait().unwrap().success());
    }
    let db = FleetDb::open(&db_path).unwrap();
    assert_eq!(db.integrity_check().unwrap(), "ok");
    assert_eq!(db.count().unwrap(), 40 * 5 + 2 * 5);
    assert_eq!(db.duplicate_keys().unwrap(), 0);
}

#[test]
fn a_bad_trace_is_skipped_with_its_line_and_the_rest_is_stored() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path(), "a", 21, vec![Wear::Healthy]);
    // Break a line in the middle of the fourth trace.
    let bad = set.join("traces/loco-01_0003.csv");
    let text = std::fs::read_to_string(&bad).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    let mid = lines.len() / 2;
    lines[mid] = "12.34,not-a-number";
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let mut db = FleetDb::open(&dir.path().join("fleet.sqlite")).unwrap();
    let s = ingest(&mut db, &[&set], &opts()).unwrap();
    assert_eq!(s.releases, 7);
    assert_eq!(s.skipped.len(), 1);
    let e = &s.skipped.errors()[0];
    assert!(e.file.ends_with("loco-01_0003.csv") && e.line == mid + 1, "{e}");
    assert!(db.releases("loco-01").unwrap().iter().all(|r| r.release_no != 3));
    // A path that is neither a trace nor a data set is skipped too; nothing at all is an error.
    let s = ingest(&mut db, &[dir.path().join("missing.csv")], &opts());
    assert!(s.is_err());
}

#[test]
fn cab_can_logs_are_ingested_per_locomotive_and_release() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path(), "a", 31, vec![Wear::Healthy, Wear::Clog]);
    let log = dir.path().join("cab.log");
    let (items, _) = pbm_lab::replay::items(&set, None).unwrap();
    let (frames, skipped) = pbm_lab::replay::replay_to_can_log(&log, &items).unwrap();
    assert!(frames > 0 && skipped.is_empty());
    let mut db = FleetDb::open(&dir.path().join("fleet.sqlite")).unwrap();
    let from_traces = ingest(&mut db, &[&set], &opts()).unwrap();
    // Insert a bad line in the middle of the log: skipped with its line, the rest stored.
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    lines.insert(lines.len() / 2, "(garbage");
    std::fs::write(&log, lines.join("\n")).unwrap();
    let s = ingest(&mut db, &[&log], &opts()).unwrap();
    assert_eq!(s.files, 1);
    assert_eq!(s.skipped.len(), 1, "{}", s.skipped);
    assert_eq!(s.releases, from_traces.releases, "one CAN release per trace");
    let again = ingest(&mut db, &[&log], &opts()).unwrap();
    assert_eq!(again.new, 0);
    for loco in ["loco-01", "loco-02"] {
        let all = db.releases(loco).unwrap();
        let (can, traces): (Vec<_>, Vec<_>) = all.iter().partition(|r| r.source == "can");
        assert_eq!(can.len(), traces.len());
        // The cab saw the verdict the replay closed, release by release.
        for (c, t) in can.iter().zip(&traces) {
            assert_eq!(c.verdict, t.verdict, "{loco} release {}", t.release_no);
            assert!(c.orifice_mm.is_none(), "CAN carries no orifice estimate");
        }
    }
    // Directly: a log of nothing but junk gives errors with lines and no release.
    let (records, errors) = can_records("x.log", "x.log", "(1.0) can0 zz#00\n\nfoo\n".as_bytes());
    assert!(records.is_empty());
    assert_eq!(errors.iter().map(|e| e.line).collect::<Vec<_>>(), [1, 3]);
}

#[test]
fn trends_follow_one_source_per_locomotive() {
    let dir = tempfile::tempdir().unwrap();
    let mut db = FleetDb::open(&dir.path().join("fleet.sqlite")).unwrap();
    let can = |origin: &str, k: i64| {
        let mut r = fake(origin, k);
        r.source = Source::Can;
        r.orifice_mm = None;
        r
    };
    db.store_file((0..30).map(|k| Ok(fake("t.csv", k)))).unwrap().unwrap();
    db.store_file((0..30).map(|k| Ok(can("cab.log", k)))).unwrap().unwrap();
    let stored = db.releases("loco-09").unwrap();
    assert_eq!(stored.len(), 60);
    let series = pbm_fleet::status::trend_series(&stored);
    assert_eq!(series.len(), 30);
    assert!(series.iter().all(|r| r.source == Source::Trace));
}

#[test]
fn the_fleet_page_leads_with_the_locomotives_and_names_no_code() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path(), "a", 41, vec![Wear::Healthy, Wear::Leak]);
    let mut db = FleetDb::open(&dir.path().join("fleet.sqlite")).unwrap();
    ingest(&mut db, &[&set], &opts()).unwrap();
    let out = dir.path().join("report");
    let path = pbm_fleet::report::write(&db, &out, &Default::default()).unwrap();
    let html = std::fs::read_to_string(path).unwrap();
    let found = pbm_report::report_html::check(&html, &["fleet", "loco-loco01", "loco-loco02"]).unwrap();
    assert_eq!(found.sections[0], "fleet", "the fleet table comes first");
    // Two sparklines and three trend charts per locomotive.
    assert_eq!(found.svgs, 2 + 2 * 3);
    assert_eq!(found.table_rows, 2);
    assert!(pbm_report::report_html::code_reference(&html).is_none());
    // Plot text at 12 px, no smaller font anywhere in the charts.
    assert!(html.contains("font-size=\"12\""));
    assert!(!html.contains("SPARKLINE-"));
}

#[test]
fn a_file_that_is_not_a_fleet_database_is_refused_with_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("notes.sqlite");
    std::fs::write(&p, "this is not a database, just a long enough line of text to fill a header.\n".repeat(20))
        .unwrap();
    let e = FleetDb::open(&p).err().expect("refused");
    assert!(format!("{e:#}").contains("notes.sqlite"), "{e:#}");
}

#[test]
fn the_parquet_export_holds_every_release_with_its_nulls() {
    use parquet::file::reader::{FileReader, SerializedFileReader};
    use parquet::record::RowAccessor;
    let dir = tempfile::tempdir().unwrap();
    let mut db = FleetDb::open(&dir.path().join("fleet.sqlite")).unwrap();
    db.store_file((0..4).map(|k| Ok(fake("t.csv", k)))).unwrap().unwrap();
    let mut r = fake("cab.log", 9);
    r.source = Source::Can;
    r.orifice_mm = None;
    r.time_s = Some(12.5);
    db.store_file([Ok(r)]).unwrap().unwrap();
    let path = dir.path().join("fleet.parquet");
    assert_eq!(pbm_fleet::export::export(&db, &path).unwrap(), 5);
    let reader = SerializedFileReader::try_from(std::fs::File::open(&path).unwrap()).unwrap();
    assert_eq!(reader.metadata().file_metadata().num_rows(), 5);
    let rows: Vec<_> = reader.get_row_iter(None).unwrap().map(|r| r.unwrap()).collect();
    let can = rows.iter().find(|r| r.get_string(1).unwrap() == "can").unwrap();
    assert_eq!(can.get_string(0).unwrap(), "loco-09");
    assert_eq!(can.get_double(5).unwrap(), 12.5);
    assert!(can.get_double(9).is_err(), "no orifice estimate on CAN: null");
    assert_eq!(can.get_double(11).unwrap(), 7.7);
    let trace = rows.iter().find(|r| r.get_string(1).unwrap() == "trace").unwrap();
    assert_eq!(trace.get_double(9).unwrap(), 1.25);
    assert_eq!(trace.get_string(6).unwrap(), "none");
}

/// Several first opens of a new database at once all succeed: switching a new file to WAL
/// takes a lock, and SQLite answers the losers "busy" without waiting (a CI run found two
/// threads' first opens failing).
#[test]
fn many_first_opens_of_a_new_database_at_once_all_succeed() {
    for round in 0..20 {
        let dir = tempfile::tempdir().unwrap();
        let db_path = dir.path().join("fleet.sqlite");
        let handles: Vec<_> = (0..8)
            .map(|_| {
                let db_path = db_path.clone();
                std::thread::spawn(move || FleetDb::open(&db_path).map(|_| ()))
            })
            .collect();
        for h in handles {
            let opened = h.join().expect("no panic");
            assert!(opened.is_ok(), "round {round}: {opened:?}");
        }
    }
}
