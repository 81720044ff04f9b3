//! Fleet archives from the command line: `archive pack` / `archive unpack` give back the
//! generator's traces byte for byte; `replay` of an archive prints the same table and writes
//! the same outputs and CAN log as the replay of the data set in the archive's order;
//! `--results-parquet` holds the table's rows; `fleet ingest` takes an archive; bad input is
//! named and skipped (exit 3) or refused (exit 1).

use parquet::file::reader::{FileReader, SerializedFileReader};
use parquet::record::Field;
use pbm_io::archive::{ArchiveWriter, ArchivedRelease};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::Duration;

mod common;
use common::os;

/// Runs `host-sim args…`, killing it after 120 s.
fn host_sim(args: &[&OsStr]) -> Output {
    common::host_sim_within(Duration::from_secs(120), args)
}

fn ok(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "stderr: {stderr}\nstdout: {}", String::from_utf8_lossy(&out.stdout));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A small generated data set: 3 locomotives, 5 classes, 3 releases per class.
fn generate(dir: &Path) -> PathBuf {
    let d = dir.join("gen");
    ok(&host_sim(&[
        os("generate"),
        os("--out"),
        d.as_os_str(),
        os("--per-class"),
        os("2"),
        os("--test-per-class"),
        os("1"),
        os("--locomotives"),
        os("3"),
        os("--test-locomotives"),
        os("1"),
        os("--seed"),
        os("11"),
    ]));
    d
}

/// The files under `dir`, relative, sorted.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_owned()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().to_owned());
            }
        }
    }
    out.sort();
    out
}

#[test]
fn pack_unpack_replay_and_ingest_agree_with_the_data_set() {
    let tmp = tempfile::tempdir().unwrap();
    let data = generate(tmp.path());
    let archive = tmp.path().join("fleet.parquet");
    let out = host_sim(&[os("archive"), os("pack"), data.as_os_str(), os("--out"), archive.as_os_str()]);
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stderr).contains("packed 15 releases of 3 locomotives"), "{out:?}");

    // Unpack: every trace the generator wrote comes back byte for byte.
    let back = tmp.path().join("back");
    ok(&host_sim(&[os("archive"), os("unpack"), archive.as_os_str(), os("--out"), back.as_os_str()]));
    let manifest = std::fs::read_to_string(data.join("manifest.csv")).unwrap();
    let traces: Vec<&str> = manifest.lines().skip(1).map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(traces.len(), 15);
    for t in &traces {
        assert!(std::fs::read(data.join(t)).unwrap() == std::fs::read(back.join(t)).unwrap(), "{t} differs");
    }

    // Replay of the archive = replay of the unpacked data set (the archive's order): the same
    // table, per-trace results, summary and CAN log, byte for byte.
    let replay = |input: &Path, tag: &str| {
        let res = tmp.path().join(format!("res-{tag}"));
        let log = tmp.path().join(format!("{tag}.log"));
        let pq = tmp.path().join(format!("{tag}.parquet"));
        let out = host_sim(&[
            os("replay"),
            input.as_os_str(),
            os("--out"),
            res.as_os_str(),
            os("--can-log"),
            log.as_os_str(),
            os("--results-parquet"),
            pq.as_os_str(),
        ]);
        (ok(&out), res, log, pq)
    };
    let (table_a, res_a, log_a, pq_a) = replay(&archive, "archive");
    let (table_u, res_u, log_u, _) = replay(&back, "unpacked");
    assert_eq!(table_a, table_u);
    assert!(std::fs::read(&log_a).unwrap() == std::fs::read(&log_u).unwrap(), "CAN logs differ");
    assert!(std::fs::metadata(&log_a).unwrap().len() > 0);
    assert_eq!(files(&res_a), files(&res_u));
    for f in files(&res_a) {
        assert!(std::fs::read(res_a.join(&f)).unwrap() == std::fs::read(res_u.join(&f)).unwrap(), "{f:?} differs");
    }
    // And the original data set (manifest in class order) gives the same rows in its order.
    let (table_d, ..) = replay(&data, "data");
    let sorted = |t: &str| {
        let mut l: Vec<String> = t.lines().map(str::to_owned).collect();
        l.sort();
        l
    };
    assert_eq!(sorted(&table_a), sorted(&table_d));

    // The results Parquet: one row per release, the table's fields.
    let reader = SerializedFileReader::new(std::fs::File::open(&pq_a).unwrap()).unwrap();
    let names: Vec<String> =
        reader.metadata().file_metadata().schema_descr().columns().iter().map(|c| c.name().to_owned()).collect();
    assert_eq!(names, pbm_io::archive::results::COLUMNS);
    let rows: Vec<parquet::record::Row> = reader.get_row_iter(None).unwrap().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 15);
    let lines: Vec<&str> = table_a.lines().skip(1).collect();
    for (row, line) in rows.iter().zip(&lines) {
        let field = |name: &str| row.get_column_iter().find(|(n, _)| *n == name).map(|(_, f)| f.clone()).unwrap();
        let Field::Str(release) = field("release") else { panic!("release") };
        let Field::Str(diagnosis) = field("diagnosis") else { panic!("diagnosis") };
        assert!(line.starts_with(&release) && line.ends_with(&diagnosis), "{line} vs {release} / {diagnosis}");
        assert!(matches!(field("error"), Field::Null));
        assert!(matches!(field("samples"), Field::Long(6000)), "{:?}", field("samples"));
        match field("verdict") {
            Field::Str(v) if diagnosis.starts_with("cannot diagnose") => assert_eq!(v, "cannot_diagnose"),
            Field::Str(v) => {
                assert!(diagnosis.starts_with(&v), "{v} / {diagnosis}");
                assert!(matches!(field("confidence_pct"), Field::Int(c) if (0..=100).contains(&c)));
            }
            other => panic!("verdict {other:?}"),
        }
    }

    // Fleet ingest of the archive, then of the data set: the same releases, recognised.
    let db = tmp.path().join("fleet.sqlite");
    let out = host_sim(&[os("fleet"), os("ingest"), os("--db"), db.as_os_str(), archive.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    ok(&out);
    assert!(stderr.contains("stored 15 releases (15 new)"), "{stderr}");
    let out = host_sim(&[os("fleet"), os("ingest"), os("--db"), db.as_os_str(), data.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    ok(&out);
    assert!(stderr.contains("stored 0 releases (0 new)") && stderr.contains("15 duplicates not stored"), "{stderr}");
    assert!(
        stderr.contains(&format!("same samples as {} [traces/", archive.canonicalize().unwrap().display())),
        "{stderr}"
    );
}

/// A release at 100 Hz whose samples are `adc`.
fn release(loco: &str, name: &str, t_s: Vec<f64>, adc: Vec<u16>) -> ArchivedRelease {
    ArchivedRelease {
        locomotive: loco.into(),
        release: name.into(),
        label: Some("normal".into()),
        split: Some("test".into()),
        metadata: Vec::new(),
        t_s,
        adc,
    }
}

#[test]
fn a_bad_release_is_skipped_with_its_name_and_the_rest_replayed() {
    let tmp = tempfile::tempdir().unwrap();
    // A real release, and one sampled at 50 Hz (the monitor's clock is 100 Hz).
    let good = pbm_io::trace::read_trace(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/small/traces/test/air_leak_0000.csv"),
    )
    .unwrap();
    let archive = tmp.path().join("a.parquet");
    let mut w = ArchiveWriter::create(&archive).unwrap();
    w.add(&ArchivedRelease::from_trace("loco-01".into(), "good.csv".into(), None, None, good).unwrap()).unwrap();
    w.add(&release("loco-02", "slow.csv", (0..100).map(|i| f64::from(i) * 0.02).collect(), vec![410; 100])).unwrap();
    w.finish().unwrap();
    let pq = tmp.path().join("r.parquet");
    let out = host_sim(&[os("replay"), archive.as_os_str(), os("--results-parquet"), pq.as_os_str()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stdout.contains("good.csv") && stdout.contains("air_leak"), "{stdout}");
    let want = format!(
        "{}: release slow.csv of loco-02: sample 1: sample interval 0.020000 s, expected 0.01 s",
        archive.display()
    );
    assert!(stdout.contains(&format!("slow.csv  SKIPPED: {want}")), "{stdout}");
    assert!(stderr.contains(&want) && stderr.contains("1 input(s) skipped"), "{stderr}");
    let reader = SerializedFileReader::new(std::fs::File::open(&pq).unwrap()).unwrap();
    let rows: Vec<parquet::record::Row> = reader.get_row_iter(None).unwrap().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 2);
    let error = rows[1].get_column_iter().find(|(n, _)| *n == "error").map(|(_, f)| f.clone()).unwrap();
    assert!(matches!(&error, Field::Str(e) if e.contains("sample interval")), "{error:?}");

    // Only one locomotive's releases: `--split` keeps the archive's split.
    let out = host_sim(&[os("replay"), archive.as_os_str(), os("--split"), os("train")]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("no trace could be replayed"), "{out:?}");
}

#[test]
fn a_file_that_is_not_an_archive_is_refused_by_unpack() {
    let tmp = tempfile::tempdir().unwrap();
    let not = tmp.path().join("x.parquet");
    std::fs::write(&not, "PAR1 but not really").unwrap();
    let out = host_sim(&[os("archive"), os("unpack"), not.as_os_str(), os("--out"), tmp.path().join("o").as_os_str()]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(&format!("{}: not a Parquet file", not.display())), "{stderr}");
    // Replay takes a file starting with the Parquet magic for an archive and says why not.
    let out = host_sim(&[os("replay"), not.as_os_str()]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a Parquet file"), "{out:?}");
}
