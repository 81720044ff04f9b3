//! Firmware tasks: the QEMU runs (twin check, monitor), the CAN equality with the host, the cost
//! bench, the lints. Builds and runs go through the `fw-*` aliases of `.cargo/config.toml`, whose
//! runner is `timeout 120 qemu-system-arm … -icount shift=0` (a hung image fails, runs are
//! deterministic).

use crate::util::{cargo, cargo_bin, output, require, run, stdout_of, step, target_dir, Result, Scratch};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The firmware's Rust target.
pub const TARGET: &str = "thumbv7em-none-eabihf";
/// Extended identifier of the fault report frame, as candump writes it.
const FAULT_ID: &str = "18FF5080";

fn require_qemu() -> Result<()> {
    require("qemu-system-arm")?;
    require("timeout")?;
    // The runner (firmware/qemu-run.sh) decodes the firmware's defmt log with it.
    require("defmt-print")?;
    let machines = stdout_of(Command::new("qemu-system-arm").args(["-machine", "help"]))?;
    if !machines.lines().any(|l| l.starts_with("mps2-an386")) {
        return Err("this qemu-system-arm has no mps2-an386 machine (QEMU >= 5.2 needed)".into());
    }
    Ok(())
}

/// `cargo ALIAS ARGS` as a command (for output capture).
fn alias(name: &str, args: &[&str]) -> Command {
    let mut cmd = Command::new(cargo_bin());
    cmd.arg(name).arg("--quiet").args(args);
    cmd
}

/// Rebuilds the default firmware (compiled-in nominal trace) so it is the current artefact.
fn restore_default_build() -> Result<()> {
    let mut cmd = alias("fw-build", &[]);
    cmd.env_remove("PBM_FW_TRACE");
    run(&mut cmd)
}

/// `cargo xtask fw-qemu`: `twin-check` must reproduce the host's golden checkpoints bit for bit
/// and `classifier-check` the host's classifier golden vectors (`tests/golden/
/// classifier_golden.txt`, the file `tests/classifier_golden.rs` checks) exactly (exit 0); their
/// self-tests with one golden value perturbed must fail (so a pass is a check that can fail);
/// the `monitor` app, and its extended-twin image, must run the compiled-in release and send a
/// fault report.
pub fn qemu() -> Result<()> {
    require_qemu()?;
    for (name, check) in [("twin-check", "fw-run"), ("classifier-check", "fw-classifier-check")] {
        step(&format!("firmware: {name} in QEMU (expect exit 0)"));
        run(&mut alias(check, &[]))?;
        step(&format!("firmware: {name} self-test with a corrupted golden value (expect a non-zero exit)"));
        let status = output(&mut alias(check, &["--features", "selftest-corrupt-golden"]))?.status;
        match status.code() {
            Some(0) => {
                return Err(format!("the corrupted-golden self-test of {name} exited 0: it cannot see a mismatch"))
            }
            Some(124) => return Err(format!("the corrupted-golden self-test of {name} timed out instead of failing")),
            _ => println!("self-test failed as it must ({status})"),
        }
    }
    step("firmware: monitor application in QEMU on the compiled-in trace");
    let mut monitor = alias("fw-monitor", &[]);
    monitor.env_remove("PBM_FW_TRACE");
    let log = stdout_of(&mut monitor)?;
    check_candump(&log)?;
    if !log.contains(&format!(" can0 {FAULT_ID}#")) {
        return Err(format!("monitor sent no fault report frame ({FAULT_ID})"));
    }
    println!("monitor passed: {} candump lines, fault report sent", log.lines().count());
    // The extended twin's image (feature `extensions`, default mechanism heat_transfer=20,
    // coefficients from build.rs): it must run the release to its verdict too. It is over the
    // cost budget (bench/firmware.md), so it is run here, not benched against the bounds.
    step("firmware: monitor with the extended twin (feature extensions) in QEMU");
    let mut extended = alias("fw-monitor", &["--features", "extensions"]);
    extended.env_remove("PBM_FW_TRACE").env_remove("PBM_FW_MECHANISM");
    let log = stdout_of(&mut extended)?;
    check_candump(&log)?;
    if !log.contains(&format!(" can0 {FAULT_ID}#")) {
        return Err(format!("the extended-twin monitor sent no fault report frame ({FAULT_ID})"));
    }
    println!("extended-twin monitor passed: {} candump lines, fault report sent", log.lines().count());
    restore_default_build()
}

/// Every line is a candump log line `(SECONDS.MICROS) can0 ID#DATA`.
fn check_candump(log: &str) -> Result<()> {
    if log.trim().is_empty() {
        return Err("monitor sent no CAN frame".into());
    }
    for line in log.lines() {
        let ok = line.strip_prefix('(').and_then(|r| r.split_once(") can0 ")).is_some_and(|(time, frame)| {
            let (id, data) = frame.split_once('#').unwrap_or(("", "x"));
            time.split_once('.').is_some_and(|(s, us)| {
                !s.is_empty()
                    && s.bytes().all(|b| b.is_ascii_digit())
                    && us.len() == 6
                    && us.bytes().all(|b| b.is_ascii_digit())
            }) && (id.len() == 3 || id.len() == 8)
                && id.bytes().all(|b| b.is_ascii_hexdigit())
                && data.len() % 2 == 0
                && data.len() <= 16
                && data.bytes().all(|b| b.is_ascii_hexdigit())
        });
        if !ok {
            return Err(format!("monitor wrote a line that is not a candump log line: {line}"));
        }
    }
    Ok(())
}

/// The traces of the equality check: the 6 test and 6 `_0000` training traces of the small
/// set (all six classes), every sensor-fault trace (each plausibility check that closes a
/// diagnosis), the releases outside the five classes from the independent plant, and one
/// release cut at 15 s (made here) so that the end of the input, not the window, closes it.
fn equality_traces(scratch: &Path) -> Result<Vec<PathBuf>> {
    let mut traces = Vec::new();
    for class in ["normal", "air_leak", "orifice_block", "leak_and_block", "low_supply", "orifice_missing"] {
        for split in ["test", "train"] {
            traces.push(PathBuf::from(format!("tests/data/small/traces/{split}/{class}_0000.csv")));
        }
    }
    let listed = |dir: &str, prefix: &str| -> Result<Vec<PathBuf>> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| format!("cannot list {dir}: {e}"))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension().is_some_and(|x| x == "csv")
                    && p.file_name().is_some_and(|n| n.to_string_lossy().starts_with(prefix))
            })
            .collect();
        v.sort();
        Ok(v)
    };
    traces.extend(listed("tests/data/sensor_fault", "")?);
    traces.extend(listed("tests/data/independent", "unfamiliar_")?);
    let source = "tests/data/small/traces/test/orifice_block_0000.csv";
    let text = std::fs::read_to_string(source).map_err(|e| format!("cannot read {source}: {e}"))?;
    let mut rows = 0;
    let cut: Vec<&str> = text
        .lines()
        .take_while(|l| {
            if l.starts_with('#') || l.starts_with("t_s") {
                return true;
            }
            rows += 1;
            rows <= 1500
        })
        .collect();
    let short = scratch.join("orifice_block_cut_15s.csv");
    std::fs::write(&short, cut.join("\n") + "\n").map_err(|e| format!("cannot write {}: {e}", short.display()))?;
    traces.push(short);
    for t in &traces {
        if !t.is_file() {
            return Err(format!("missing trace {}", t.display()));
        }
    }
    Ok(traces)
}

/// `cargo xtask fw-can-equality`: for each trace, the CAN frames the firmware sends in QEMU equal
/// byte for byte the candump log `host-sim replay TRACE --can-log FILE` writes. The firmware
/// plays a trace compiled into flash (`PBM_FW_TRACE`, read by its build script), so `monitor` is
/// rebuilt per trace (a relink, a few seconds).
pub fn can_equality() -> Result<()> {
    require_qemu()?;
    let scratch = Scratch::new("can-equality")?;
    let traces = equality_traces(&scratch.0)?;
    // The `test` profile: the host-sim `cargo test --workspace` builds, so CI compiles once.
    cargo(&["build", "--quiet", "--profile", "test", "-p", "host-sim"])?;
    let host_sim = target_dir().join("debug/host-sim");
    let mut failures = Vec::new();
    let mut distinct = BTreeSet::new();
    for (n, t) in traces.iter().enumerate() {
        let abs = std::fs::canonicalize(t).map_err(|e| format!("{}: {e}", t.display()))?;
        let host_log = scratch.0.join(format!("{n}-host.log"));
        stdout_of(Command::new(&host_sim).arg("replay").arg(&abs).arg("--can-log").arg(&host_log))?;
        let host = std::fs::read_to_string(&host_log).map_err(|e| format!("{}: {e}", host_log.display()))?;
        let mut monitor = alias("fw-monitor", &[]);
        monitor.env("PBM_FW_TRACE", &abs);
        let out = output(&mut monitor)?;
        let fw = String::from_utf8_lossy(&out.stdout).into_owned();
        let err = String::from_utf8_lossy(&out.stderr);
        let verdict =
            err.lines().filter_map(|l| l.strip_prefix("monitor: diagnosis closed ")).next_back().unwrap_or("");
        let name = t.strip_prefix("tests/data/").unwrap_or(t).display().to_string();
        if !out.status.success() {
            failures.push(format!("{name}: firmware exit status {} (124 = timeout)\n{err}", out.status));
        } else if fw != host {
            let first = fw.lines().zip(host.lines()).position(|(a, b)| a != b);
            failures.push(format!(
                "{name}: QEMU and host logs differ ({} firmware lines, {} host lines, first difference at line {})",
                fw.lines().count(),
                host.lines().count(),
                first.map_or("end".to_owned(), |i| (i + 1).to_string())
            ));
        } else if !fw.contains(&format!(" can0 {FAULT_ID}#")) {
            failures.push(format!("{name}: no fault report frame ({FAULT_ID}) sent"));
        } else {
            println!("ok    {name}: {} frames identical; {verdict}", fw.lines().count());
        }
        distinct.insert(fw);
    }
    restore_default_build()?;
    // The check must be able to see a difference: different traces give different logs.
    if distinct.len() < 2 {
        return Err("all firmware logs are identical: the trace is not reaching the firmware".into());
    }
    if !failures.is_empty() {
        return Err(format!("QEMU and host-sim CAN logs differ:\n  {}", failures.join("\n  ")));
    }
    println!("fw-can-equality: {} traces, firmware CAN frames identical to host-sim replay --can-log", traces.len());
    Ok(())
}

/// `cargo xtask fw-lint`: rustfmt and clippy (warnings denied) for the firmware workspace, which
/// `cargo fmt --all` / `cargo clippy --workspace` of the root do not cover.
pub fn lint() -> Result<()> {
    cargo(&["fmt", "--manifest-path", "firmware/Cargo.toml", "--", "--check"])?;
    cargo(&["fw-clippy"])?;
    cargo(&[
        "clippy",
        "--manifest-path",
        "firmware/Cargo.toml",
        "--target",
        TARGET,
        "--all-targets",
        "--all-features",
        "--",
        "-D",
        "warnings",
    ])?;
    // An image of one mechanism (the core's `mechanism_image` code: the orifice flow out of
    // line, the extended path with only that mechanism's terms; build.rs's default magnitude).
    cargo(&[
        "clippy",
        "--manifest-path",
        "firmware/Cargo.toml",
        "--target",
        TARGET,
        "--all-targets",
        "--features",
        "valve_lag",
        "--",
        "-D",
        "warnings",
    ])?;
    // The library as the board image links it (without the QEMU drivers): the board
    // workspace's clippy does not lint this path dependency.
    cargo(&[
        "clippy",
        "--manifest-path",
        "firmware/Cargo.toml",
        "--target",
        TARGET,
        "--lib",
        "--no-default-features",
        "--",
        "-D",
        "warnings",
    ])?;
    println!("fw-lint: OK");
    Ok(())
}

/// `cargo xtask fw-bench [--check]`: the firmware cost figures ([`crate::fw_bench`]).
pub fn bench(check: bool) -> Result<()> {
    require_qemu()?;
    crate::fw_bench::bench(check)
}
