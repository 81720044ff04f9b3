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
        detail: Default::default(),
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
            // Each CAN release keeps its decoded reports: the last one is its verdict.
            let reports = db.can_reports(c.id).unwrap();
            assert_eq!(reports.last().map(|r| r.verdict.as_str()), Some(c.verdict.as_str()));
            assert!(db.curve(c.id).unwrap().is_none(), "CAN carries no pressure curve");
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
fn the_fleet_page_leads_with_the_locomotives_and_links_their_pages() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path(), "a", 41, vec![Wear::Healthy, Wear::Leak]);
    let mut db = FleetDb::open(&dir.path().join("fleet.sqlite")).unwrap();
    ingest(&mut db, &[&set], &opts()).unwrap();
    let out = dir.path().join("report");
    let path = pbm_fleet::report::write(&db, &out, &Default::default()).unwrap();
    let html = std::fs::read_to_string(path).unwrap();
    let found = pbm_report::report_html::check(&html, &["fleet"]).unwrap();
    assert_eq!(found.sections, ["fleet"]);
    // One sparkline per locomotive, one row per locomotive, each linked to its page.
    assert_eq!(found.svgs, 2);
    assert_eq!(found.table_rows, 2);
    assert!(pbm_report::report_html::code_reference(&html).is_none());
    assert!(html.contains("<a href=\"loco-loco01.html\"><strong>loco-01</strong></a>"), "link");
    assert!(html.contains("Calibrated confidence"));
    for (page, _) in [("loco-loco01.html", 0), ("loco-loco02.html", 1)] {
        let loco = std::fs::read_to_string(out.join(page)).unwrap();
        let found = pbm_report::report_html::check(&loco, &pbm_fleet::report::LOCOMOTIVE_SECTIONS).unwrap();
        assert_eq!(found.sections, pbm_fleet::report::LOCOMOTIVE_SECTIONS);
        // Two release curves (the latest and the first), three trends.
        assert_eq!(found.svgs, 2 + 3, "{page}");
        assert!(loco.contains("chamber pressure, bar g") && loco.contains("time since the release command, s"));
        assert!(loco.contains("<a href=\"index.html\">Back to the fleet</a>"));
        // The decoded CAN reports of the latest releases: verdict, confidence, freshness.
        assert!(loco.contains("Decoded fault reports of") && loco.contains("current"), "{page}");
        assert!(pbm_report::report_html::code_reference(&loco).is_none());
        // Plot text at 12 px, no smaller font anywhere in the charts.
        assert!(
            loco.contains("font-size=\"12\"") && !loco.contains("font-size=\"1\"") && !loco.contains("font-size=\"9")
        );
    }
}

#[test]
fn ingest_keeps_each_release_curve_and_the_reports_the_cab_decoded() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path(), "a", 43, vec![Wear::Leak]);
    let mut db = FleetDb::open(&dir.path().join("fleet.sqlite")).unwrap();
    ingest(&mut db, &[&set], &opts()).unwrap();
    for r in db.releases("loco-01").unwrap() {
        let curve = db.curve(r.id).unwrap().expect("a replayed trace has a curve");
        // 60 s at 100 Hz thinned to 5 points a second.
        assert_eq!(curve.twin_bar.len(), 300, "release {}", r.release_no);
        assert!((curve.step_s - pbm_fleet::record::CURVE_STEP_S).abs() < 1e-12);
        let last = curve.measured_bar.last().copied().unwrap();
        assert!((6.5..8.5).contains(&last), "settles near the supply: {last}");
        assert!(curve.twin_bar.iter().all(|v| v.is_finite()));
        let reports = db.can_reports(r.id).unwrap();
        assert!(!reports.is_empty(), "release {}: the controller sent fault reports", r.release_no);
        let final_report = reports.last().unwrap();
        // The cab's last report of the release is the diagnosis the replay closed.
        assert_eq!(final_report.verdict, r.verdict, "release {}", r.release_no);
        assert_eq!(final_report.confidence_pct, r.confidence_pct);
        assert!(reports.iter().all(|c| c.current && c.lost_before == 0), "a clean replay: all current");
        assert!(reports.windows(2).all(|w| w[0].since_command_s <= w[1].since_command_s));
    }
    // Re-ingesting replaces the curve and the reports instead of adding to them.
    let before: Vec<usize> =
        db.releases("loco-01").unwrap().iter().map(|r| db.can_reports(r.id).unwrap().len()).collect();
    ingest(&mut db, &[&set], &opts()).unwrap();
    let after: Vec<usize> =
        db.releases("loco-01").unwrap().iter().map(|r| db.can_reports(r.id).unwrap().len()).collect();
    assert_eq!(before, after);
}

/// The schema of a version-2 database, as the tool wrote it before curves and CAN reports
/// were kept (copied from that version).
const SCHEMA_2: &str = "
CREATE TABLE releases (
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
CREATE INDEX releases_by_loco ON releases (locomotive, release_no, time_s);
CREATE INDEX releases_by_hash ON releases (locomotive, content_hash);
INSERT INTO releases (locomotive, source, origin, release_key, release_no, verdict, confidence_pct, orifice_mm,
                      leak_mm, supply_bar_g, numbered)
VALUES ('loco-07', 'trace', '/old/loco-07_0000.csv', '0', 0, 'air_leak', 93, 1.24, 0.71, 7.69, 1);
PRAGMA user_version = 2;
";

#[test]
fn a_schema_2_database_still_opens_and_reads() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v2.sqlite");
    {
        let conn = rusqlite::Connection::open(&path).unwrap();
        conn.execute_batch(SCHEMA_2).unwrap();
    }
    let mut db = FleetDb::open(&path).unwrap();
    assert_eq!(db.schema_version().unwrap(), pbm_fleet::db::SCHEMA_VERSION);
    let old = db.releases("loco-07").unwrap();
    assert_eq!(old.len(), 1);
    assert_eq!((old[0].verdict.as_str(), old[0].confidence_pct, old[0].leak_mm), ("air_leak", Some(93), Some(0.71)));
    // Stored before curves and reports were kept: none, and the pages say so.
    assert!(db.curve(old[0].id).unwrap().is_none());
    assert!(db.can_reports(old[0].id).unwrap().is_empty());
    let out = dir.path().join("report");
    pbm_fleet::report::write(&db, &out, &Default::default()).unwrap();
    let page = std::fs::read_to_string(out.join("loco-loco07.html")).unwrap();
    assert!(page.contains("No pressure curve is stored") && page.contains("No decoded fault reports are stored"));
    // New releases go in next to the old one.
    db.store_file((0..3).map(|k| Ok(fake("new.csv", k)))).unwrap().unwrap();
    assert_eq!(db.count().unwrap(), 4);
    assert_eq!(db.integrity_check().unwrap(), "ok");
}

#[test]
fn the_fleet_table_says_when_the_recent_releases_disagree() {
    use pbm::report::Verdict;
    use pbm::FaultClass;
    let dir = tempfile::tempdir().unwrap();
    let mut db = FleetDb::open(&dir.path().join("fleet.sqlite")).unwrap();
    let with = |k: i64, class: FaultClass, c: u8| {
        let mut r = fake("t.csv", k);
        r.verdict = Some(Verdict::Class { class, confidence_pct: c });
        r
    };
    // Twenty settled healthy releases, then ten that flip between healthy and a leak.
    let mut rs: Vec<ReleaseRecord> = (0..20).map(|k| with(k, FaultClass::Normal, 97)).collect();
    rs.extend((20..30).map(|k| with(k, if k % 2 == 0 { FaultClass::AirLeak } else { FaultClass::Normal }, 71)));
    db.store_file(rs.into_iter().map(Ok)).unwrap().unwrap();
    let stored = db.releases("loco-09").unwrap();
    let recent = pbm_fleet::report::RecentVerdicts::of(&stored);
    assert_eq!((recent.releases, recent.diagnosed, recent.agree), (10, 10, 5));
    assert!(recent.disagree());
    let s = pbm_fleet::status::status(&db, &Default::default()).unwrap();
    let cell = pbm_fleet::report::confidence_cell(&s[0], &recent);
    assert!(cell.text.starts_with("releases disagree: air leak 5, healthy 5 of the last 10"), "{}", cell.text);
    // Settled: the calibrated confidence the monitor sent, and how many agree.
    let settled = pbm_fleet::report::RecentVerdicts::of(&stored[..20]);
    assert!(!settled.disagree());
    let mut s0 = s[0].clone();
    s0.latest_verdict = Some(("normal".into(), Some(97)));
    let cell = pbm_fleet::report::confidence_cell(&s0, &settled);
    assert_eq!(cell.text, "97 % healthy; 10 of the last 10 agree");
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

#[test]
fn a_failing_transducer_locomotive_is_a_sensor_warning_not_a_brake_fault() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path(), "a", 47, vec![Wear::Healthy, Wear::Sensor]);
    let mut db = FleetDb::open(&dir.path().join("fleet.sqlite")).unwrap();
    ingest(&mut db, &[&set], &opts()).unwrap();
    let s = pbm_fleet::status::status(&db, &Default::default()).unwrap();
    assert!(s[0].undiagnosed.is_empty(), "{:?}", s[0].undiagnosed);
    // From the onset (release 2 of 8) on, every release is declined as a sensor fault.
    let sensor: Vec<_> = s[1].undiagnosed.iter().filter(|u| u.sensor).collect();
    assert_eq!(sensor.len(), 1, "{:?}", s[1].undiagnosed);
    assert_eq!((sensor[0].count, sensor[0].first_release_no), (6, 2), "{:?}", sensor[0]);
    assert!(s[1].warnings.is_empty(), "no brake warning from a failing transducer");
    let lines = pbm_fleet::status::lines(&s);
    assert!(lines[1].contains("SENSOR WARNING"), "{}", lines[1]);
}
