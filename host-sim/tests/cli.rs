//! The command line as a user meets it: exit codes, what is reported on stderr, and that bad
//! inputs are skipped (or refused) without losing the rest of the run or hanging.

mod common;

use common::os;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

fn small() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/small")
}

/// Runs `host-sim args…`, killing it after 60 s.
fn host_sim(args: &[&OsStr]) -> Output {
    common::host_sim_within(Duration::from_secs(60), args)
}

/// A data set dir with `good.csv` (a real trace) and whatever else `extra` writes.
fn data_set(root: &Path, manifest_rows: &str) -> PathBuf {
    let dir = root.join("set");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(small().join("traces/test/air_leak_0000.csv"), dir.join("good.csv")).unwrap();
    std::fs::write(dir.join("manifest.csv"), format!("file,label,locomotive,split\n{manifest_rows}")).unwrap();
    dir
}

#[test]
fn replay_skips_a_bad_trace_writes_everything_else_and_exits_3() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = data_set(tmp.path(), "bad.csv,normal,x,test\ngood.csv,air_leak,y,test\n");
    std::fs::write(dir.join("bad.csv"), "t_s,adc\n0.00,410\n0.01,5000\n").unwrap();
    let res = tmp.path().join("res");
    let log = tmp.path().join("all.log");
    let out =
        host_sim(&[os("replay"), dir.as_os_str(), os("--out"), res.as_os_str(), os("--can-log"), log.as_os_str()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stdout.contains("good.csv") && stdout.contains("air_leak"), "{stdout}");
    assert!(stdout.contains("bad.csv") && stdout.contains("SKIPPED"), "{stdout}");
    assert!(stderr.contains("bad.csv:3: adc value 5000 outside 0..=4095"), "{stderr}");
    assert!(stderr.contains("1 input(s) skipped"), "{stderr}");
    let summary = std::fs::read_to_string(res.join("summary.csv")).unwrap();
    assert_eq!(summary.lines().count(), 3, "{summary}");
    assert!(res.join("good.csv").is_file() && !res.join("bad.csv").exists());
    // The CAN log holds the good trace's reports to the end (a closed diagnosis).
    let decoded = host_sim(&[os("can"), os("decode"), log.as_os_str()]);
    let text = String::from_utf8_lossy(&decoded.stdout);
    assert!(decoded.status.success(), "{text}");
    assert!(text.contains("air_leak") && text.contains("completed"), "{text}");
}

#[cfg(unix)]
#[test]
fn a_fifo_in_a_manifest_is_refused_without_hanging() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = data_set(tmp.path(), "pipe.csv,normal,x,test\ngood.csv,air_leak,y,test\n");
    let fifo = dir.join("pipe.csv");
    let status = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(status.success());
    let out = host_sim(&[os("replay"), dir.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("pipe.csv") && stderr.contains("not a regular file"), "{stderr}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("good.csv"));
    // A FIFO given directly is refused too; with nothing replayed the run failed (exit 1).
    let out = host_sim(&[os("replay"), fifo.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("not a regular file") && stderr.contains("no trace could be replayed"), "{stderr}");
    // A manifest that is a FIFO is refused as such (not read as a missing manifest, not read).
    let other = tmp.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    assert!(Command::new("mkfifo").arg(other.join("manifest.csv")).status().unwrap().success());
    let out = host_sim(&[os("replay"), other.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("manifest.csv: not a regular file"), "{stderr}");
}

#[cfg(unix)]
#[test]
fn a_symlink_leaving_the_data_set_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let outside = tmp.path().join("outside.csv");
    std::fs::copy(small().join("traces/test/normal_0000.csv"), &outside).unwrap();
    let dir = data_set(tmp.path(), "link.csv,normal,x,test\nsub/inner.csv,air_leak,y,test\ngood.csv,air_leak,y,test\n");
    std::os::unix::fs::symlink(&outside, dir.join("link.csv")).unwrap();
    // A link that stays inside the data set is fine.
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    std::os::unix::fs::symlink(dir.join("good.csv"), dir.join("sub/inner.csv")).unwrap();
    let out = host_sim(&[os("replay"), dir.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("link.csv") && stderr.contains("outside the data set"), "{stderr}");
    assert!(stdout.contains("sub/inner.csv") && !stdout.contains("inner.csv  SKIPPED"), "{stdout}");
}

#[test]
fn path_traversal_in_a_manifest_is_refused_with_its_line_and_the_rest_replays() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = data_set(tmp.path(), "good.csv,air_leak,y,test\n../good.csv,normal,x,test\n/etc/passwd,normal,x,test\n");
    let out = host_sim(&[os("replay"), dir.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("manifest.csv:3: file `../good.csv` must be a relative path"), "{stderr}");
    assert!(stderr.contains("manifest.csv:4: file `/etc/passwd` must be a relative path"), "{stderr}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("good.csv"));
}

#[test]
fn outputs_never_overwrite_inputs() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = data_set(tmp.path(), "good.csv,air_leak,y,test\n");
    let before = std::fs::read(dir.join("good.csv")).unwrap();
    let manifest = std::fs::read(dir.join("manifest.csv")).unwrap();
    // Results into the data set itself: `DIR/good.csv` is the input trace.
    let out = host_sim(&[os("replay"), dir.as_os_str(), os("--out"), dir.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("would overwrite the input"), "{stderr}");
    // The CAN log over the manifest; one trace given directly with --out next to it.
    let out = host_sim(&[os("replay"), dir.as_os_str(), os("--can-log"), dir.join("manifest.csv").as_os_str()]);
    assert_eq!(out.status.code(), Some(1), "{}", String::from_utf8_lossy(&out.stderr));
    let out = host_sim(&[os("replay"), dir.join("good.csv").as_os_str(), os("--out"), dir.as_os_str()]);
    assert_eq!(out.status.code(), Some(1), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read(dir.join("good.csv")).unwrap(), before, "the input trace is untouched");
    assert_eq!(std::fs::read(dir.join("manifest.csv")).unwrap(), manifest, "the manifest is untouched");
}

#[test]
fn endless_lines_and_special_files_are_refused_in_bounded_memory() {
    let tmp = tempfile::tempdir().unwrap();
    // 8 MB without a line break, listed in a data set: skipped, the rest replays.
    let dir = data_set(tmp.path(), "endless.csv,normal,x,test\ngood.csv,air_leak,y,test\n");
    std::fs::write(dir.join("endless.csv"), vec![b'7'; 8 << 20]).unwrap();
    let out = host_sim(&[os("replay"), dir.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("endless.csv:1: line longer than"), "{stderr}");
    // A CAN log that is a directory or a device is refused, not decoded.
    for path in [tmp.path().as_os_str(), os("/dev/zero")] {
        let out = host_sim(&[os("can"), os("decode"), path]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{path:?}: {stderr}");
        assert!(stderr.contains("refused"), "{stderr}");
    }
}

#[cfg(unix)]
#[test]
fn a_fifo_model_file_is_refused_without_hanging() {
    let tmp = tempfile::tempdir().unwrap();
    let models = tmp.path().join("models");
    std::fs::create_dir_all(&models).unwrap();
    for f in ["paper_raw.mlp", "paper_residual.mlp", "paper_theta.mlp", "ours_f64.mlp", "ours_int8.txt"] {
        assert!(Command::new("mkfifo").arg(models.join(f)).status().unwrap().success());
    }
    let out = host_sim(&[os("evaluate"), small().as_os_str(), os("--models"), models.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("not a regular file"), "{stderr}");
}

#[test]
fn usage_errors_exit_2_and_help_has_no_code_references() {
    let out = host_sim(&[os("replay"), os("--no-such-flag")]);
    assert_eq!(out.status.code(), Some(2));
    let mut commands = vec![vec!["--help"]];
    for c in [
        "simulate",
        "generate",
        "audit",
        "audit-sweep",
        "audit-metro",
        "bench",
        "replay",
        "fit",
        "estimate",
        "train",
        "evaluate",
        "demo",
    ] {
        commands.push(vec![c, "--help"]);
    }
    for c in ["decode", "send", "demo-log"] {
        commands.push(vec!["can", c, "--help"]);
    }
    for args in commands {
        let out = host_sim(&args.iter().map(os).collect::<Vec<_>>());
        let help = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{args:?}");
        for code in ["host_sim", "pbm_", "::", "issue ", "SPEC §", "Pipeline", "fn "] {
            assert!(!help.contains(code), "`{}` help mentions `{code}`:\n{help}", args.join(" "));
        }
    }
}

#[test]
fn effect_help_lists_every_mechanism_with_its_unit() {
    let out = host_sim(&[os("generate"), os("--help")]);
    let help = String::from_utf8_lossy(&out.stdout);
    for d in pbm::mechanism::MECHANISMS {
        assert!(help.contains(d.name), "{} missing:\n{help}", d.name);
    }
    let out = host_sim(&[os("generate"), os("--out"), os("x"), os("--effect"), os("warp_drive=1")]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("warp_drive"));
}

/// A data set of the small set's `normal` releases (one per locomotive), the first with an
/// unknown metadata key, plus whatever `extra` adds as `(file, text)`.
fn normal_set(root: &Path, extra: &[(&str, String)]) -> PathBuf {
    let dir = root.join("normal");
    std::fs::create_dir_all(&dir).unwrap();
    let mut manifest = "file,label,locomotive,split\n".to_owned();
    for (k, src) in ["traces/train/normal_0000.csv", "traces/train/normal_0001.csv"].into_iter().enumerate() {
        let text = std::fs::read_to_string(small().join(src)).unwrap();
        let text = if k == 0 { format!("# sensor_supply_v: 5\n{text}") } else { text };
        std::fs::write(dir.join(format!("n{k}.csv")), text).unwrap();
        manifest.push_str(&format!("n{k}.csv,normal,loco-01,train\n"));
    }
    for (name, text) in extra {
        std::fs::write(dir.join(name), text).unwrap();
        manifest.push_str(&format!("{name},normal,loco-01,train\n"));
    }
    std::fs::write(dir.join("manifest.csv"), manifest).unwrap();
    dir
}

#[test]
fn audit_refuses_what_is_no_release_and_warns_about_unknown_metadata() {
    let tmp = tempfile::tempdir().unwrap();
    // White noise around 0 bar, a dead channel: nothing to audit, exit 1 with the reasons.
    let only_bad = tmp.path().join("bad");
    std::fs::create_dir_all(&only_bad).unwrap();
    let noise: String = (0..1500).map(|i| format!("{:.2},{}\n", f64::from(i) * 0.01, 410 + (i * 7919) % 5)).collect();
    std::fs::write(only_bad.join("noise.csv"), format!("t_s,adc\n{noise}")).unwrap();
    let dead: String = (0..1500).map(|i| format!("{:.2},2000\n", f64::from(i) * 0.01)).collect();
    std::fs::write(only_bad.join("dead.csv"), format!("t_s,adc\n{dead}")).unwrap();
    std::fs::write(
        only_bad.join("manifest.csv"),
        "file,label,locomotive,split\nnoise.csv,normal,l,train\ndead.csv,normal,l,train\n",
    )
    .unwrap();
    let out = host_sim(&[os("audit"), only_bad.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("no usable release to audit"), "{stderr}");
    assert!(stderr.contains("noise.csv") && stderr.contains("no release to audit: the pressure rises"), "{stderr}");
    assert!(stderr.contains("dead.csv") && stderr.contains("sensor fault `dead`"), "{stderr}");
    assert!(!String::from_utf8_lossy(&out.stdout).contains("cause:"));

    // Real releases, one with `# sensor_supply_v: 5`, and an all-zero ADC trace: the audit runs,
    // warns on stderr and in the JSON, skips the zero trace (exit 3).
    let zero: String = (0..1500).map(|i| format!("{:.2},0\n", f64::from(i) * 0.01)).collect();
    let dir = normal_set(tmp.path(), &[("zero.csv", format!("t_s,adc\n{zero}"))]);
    let json = tmp.path().join("audit.json");
    let out = host_sim(&[os("audit"), dir.as_os_str(), os("--json"), json.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("warning: n0.csv: metadata key `sensor_supply_v` is not a configuration key"), "{stderr}");
    assert!(stderr.contains("zero.csv") && stderr.contains("sensor fault `open_circuit`"), "{stderr}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("cause:") && !stdout.contains("NaN") && !stdout.contains("inf"), "{stdout}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let warnings = v["warnings"].as_array().expect("warnings array");
    assert_eq!(warnings.len(), 2, "{v}");
    assert!(warnings[0].as_str().unwrap().contains("sensor_supply_v"));
    // The skipped trace is in the JSON as well (an independent tester found it only on stderr).
    assert!(
        warnings[1].as_str().unwrap().starts_with("skipped: ") && warnings[1].as_str().unwrap().contains("zero.csv")
    );
}

#[test]
fn fit_refuses_a_trace_too_short_to_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let one = tmp.path().join("one.csv");
    std::fs::write(&one, "t_s,adc\n0.00,410\n").unwrap();
    let out = host_sim(&[os("fit"), one.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("one.csv") && stderr.contains("too short to fit: 1 sample(s)"), "{stderr}");
    assert!(!stdout.contains("NaN") && !stderr.contains("NaN"), "{stdout}{stderr}");
}

/// `can decode --strict` (for CI replays): exit 0 on a clean log, 4 when any frame was flagged
/// or lost, a report was stale, or the log held no frame, with the summary saying what; 1 when
/// the log cannot be read; without `--strict` the same logs exit 0.
#[test]
fn can_decode_strict_exit_codes() {
    let tmp = tempfile::tempdir().unwrap();
    let log = tmp.path().join("demo.log");
    let full = tmp.path().join("full.log");
    let out = host_sim(&[os("can"), os("demo-log"), os("--out"), full.as_os_str()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The first 200 frames (about 80 s, two releases): the display's output stays within a
    // pipe buffer.
    let head: Vec<String> = std::fs::read_to_string(&full).unwrap().lines().take(200).map(str::to_owned).collect();
    std::fs::write(&log, head.join("\n") + "\n").unwrap();
    let strict = |path: &Path| host_sim(&[os("can"), os("decode"), os("--strict"), path.as_os_str()]);
    let clean = strict(&log);
    assert_eq!(clean.status.code(), Some(0), "{}", String::from_utf8_lossy(&clean.stderr));
    let text = String::from_utf8_lossy(&clean.stdout);
    assert!(text.contains("loco  7 release  2"), "reports name locomotive and release: {text}");
    let lines: Vec<String> = std::fs::read_to_string(&log).unwrap().lines().map(str::to_owned).collect();
    // A replayed line (the 40th frame again at the 80th), a deleted line (the 100th), a
    // corrupted one: each makes --strict fail.
    let mut replayed = lines.clone();
    let (t80, _) = replayed[80].split_once(' ').unwrap();
    let copy = format!("{t80} {}", lines[40].split_once(' ').unwrap().1);
    replayed.insert(80, copy);
    let mut deleted = lines.clone();
    deleted.remove(100);
    let mut corrupted = lines.clone();
    corrupted[120] = corrupted[120].replacen('#', "#FF", 1).chars().take(corrupted[120].len()).collect();
    for (name, variant, needle) in
        [("replayed", replayed, "flagged"), ("deleted", deleted, "lost"), ("corrupted", corrupted, "flagged")]
    {
        let path = tmp.path().join(format!("{name}.log"));
        std::fs::write(&path, variant.join("\n") + "\n").unwrap();
        let out = strict(&path);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(4), "{name}: {stderr}");
        assert!(stderr.contains("--strict") && stderr.contains(needle), "{name}: {stderr}");
        let lenient = host_sim(&[os("can"), os("decode"), path.as_os_str()]);
        assert_eq!(lenient.status.code(), Some(0), "{name} without --strict");
    }
    // The log's last release replayed after the live session ended: flagged. The status frames
    // after the 150th removed (the heartbeat stops, the reports go on): the reports are shown
    // stale, never current. Both fail --strict.
    let no_heartbeat: Vec<String> =
        lines.iter().enumerate().filter(|(i, l)| *i < 150 || l.contains("18FF5080#")).map(|(_, l)| l.clone()).collect();
    let mut late = lines.clone();
    let (t_end, _) = lines[lines.len() - 1].split_once(' ').unwrap();
    let t_end: f64 = t_end.trim_matches(|c| c == '(' || c == ')').parse().unwrap();
    for (i, l) in lines.iter().enumerate().skip(150).filter(|(_, l)| l.contains("18FF5080#")) {
        late.push(format!("({:.6}) {}", t_end + 2.0 + i as f64 * 0.001, l.split_once(' ').unwrap().1));
    }
    // Nothing but blank lines, and an unreadable path.
    let cases = [
        ("late", late.join("\n") + "\n", 4, "flagged"),
        ("no-heartbeat", no_heartbeat.join("\n") + "\n", 4, "shown stale"),
        ("empty", "\n\n".to_owned(), 4, "no frame"),
    ];
    for (name, text, code, needle) in cases {
        let path = tmp.path().join(format!("{name}.log"));
        std::fs::write(&path, text).unwrap();
        let out = strict(&path);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{name}: {stderr}");
        assert!(stderr.contains(needle), "{name}: {stderr}");
    }
    let missing = strict(&tmp.path().join("no-such.log"));
    assert_eq!(missing.status.code(), Some(1), "{}", String::from_utf8_lossy(&missing.stderr));
}

#[test]
fn fleet_ingest_status_and_report_and_a_bad_trace_exits_3() {
    let dir = tempfile::tempdir().unwrap();
    let set = dir.path().join("wear");
    let out = host_sim(&[
        os("fleet"),
        os("degrade"),
        os("--out"),
        set.as_os_str(),
        os("--healthy"),
        os("1"),
        os("--leak"),
        os("1"),
        os("--clog"),
        os("0"),
        os("--releases"),
        os("6"),
        os("--onset"),
        os("2"),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let db = dir.path().join("fleet.sqlite");
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "# locomotive: loco-07\nt_s,adc\n0.00,409\n0.01,abc\n").unwrap();
    let out = host_sim(&[os("fleet"), os("ingest"), os("--db"), db.as_os_str(), set.as_os_str(), bad.as_os_str()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains("stored 12 releases (12 new)"), "{err}");
    assert!(err.contains("bad.csv:4: column 2 is not a number"), "{err}");
    let out = host_sim(&[os("fleet"), os("ingest"), os("--db"), db.as_os_str(), set.as_os_str()]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("(0 new)"));
    let out = host_sim(&[os("fleet"), os("status"), os("--db"), db.as_os_str()]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 2, "{text}");
    assert!(lines[0].starts_with("loco-01  releases 6  latest normal"), "{text}");
    let report = dir.path().join("report");
    let out = host_sim(&[os("fleet"), os("report"), os("--db"), db.as_os_str(), os("--out"), report.as_os_str()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read_to_string(report.join("index.html")).unwrap().contains("loco-02"));
    let parquet = dir.path().join("fleet.parquet");
    let out = host_sim(&[os("fleet"), os("export"), os("--db"), db.as_os_str(), os("--out"), parquet.as_os_str()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("wrote 12 releases"));
    assert!(std::fs::read(&parquet).unwrap().starts_with(b"PAR1"));
    let missing = dir.path().join("none.sqlite");
    let out = host_sim(&[os("fleet"), os("status"), os("--db"), missing.as_os_str()]);
    assert_eq!(out.status.code(), Some(1));
}
