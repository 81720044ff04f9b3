//! `cargo xtask can-check`: the CAN checks `cargo test --workspace` does not cover.
//!
//! 1. `host-sim` with the `socketcan` feature (off by default, so the workspace build never
//!    compiles it): check and clippy with warnings denied.
//! 2. Python cantools (the venv of `cargo xtask setup`) decodes every frame the project emits,
//!    unchanged, to the values of the project's own decoder (`host-sim can decode --format csv`),
//!    with an independently computed E2E CRC: the demonstration log, the code sweep (every code,
//!    values at and beyond the edges) and the replay of the small data set; the two streams
//!    with `--strict` (nothing flagged or lost), the sweep `--codec-only`.
//! 3. can-utils `log2asc` / `asc2log` round-trip the project's candump logs (absolute time
//!    stamps): one ASC header, the same frames at the same times relative to the first.

use crate::setup::{venv_python, CANTOOLS_VERSION};
use crate::util::{cargo, require, run, stdout_of, target_dir, Result, Scratch};
use std::process::Command;

/// Runs both checks.
pub fn check() -> Result<()> {
    cargo(&["check", "--quiet", "-p", "host-sim", "--features", "socketcan"])?;
    cargo(&[
        "clippy",
        "--quiet",
        "-p",
        "host-sim",
        "--features",
        "socketcan",
        "--all-targets",
        "--",
        "-D",
        "warnings",
    ])?;
    let py = venv_python();
    if !py.exists() {
        return Err(format!("no cantools venv at {}: run `cargo xtask setup` first", py.display()));
    }
    // The `test` profile: the host-sim `cargo test --workspace` builds, so CI compiles once.
    cargo(&["build", "--quiet", "--profile", "test", "-p", "host-sim"])?;
    let hs = target_dir().join("debug/host-sim");
    let work = Scratch::new("can-check")?;
    let log = |name: &str| work.0.join(format!("{name}.log"));
    run(Command::new(&hs).args(["can", "demo-log", "--out"]).arg(log("demo")))?;
    run(Command::new(&hs).args(["can", "demo-log", "--sweep", "--out"]).arg(log("sweep")))?;
    stdout_of(Command::new(&hs).args(["replay", "tests/data/small", "--can-log"]).arg(log("small")))?;
    let mut failed = Vec::new();
    for name in ["demo", "sweep", "small"] {
        println!("--- {name}.log");
        let decoded = work.0.join(format!("{name}.decoded.csv"));
        // The demonstration and replay logs are streams: every freshness check applies, and
        // `--strict` fails on anything flagged or lost. The sweep is a codec sweep, no stream.
        let mode = if name == "sweep" { "--codec-only" } else { "--strict" };
        let csv = stdout_of(Command::new(&hs).args(["can", "decode", "--format", "csv", mode]).arg(log(name)))?;
        std::fs::write(&decoded, csv).map_err(|e| format!("cannot write {}: {e}", decoded.display()))?;
        let mut cmd = Command::new(&py);
        cmd.arg("xtask/checks/can_cantools_check.py").arg("can/brake_monitor.dbc").arg(log(name)).arg(&decoded);
        if name == "sweep" {
            cmd.arg("--require-all-labels");
        }
        if run(&mut cmd).is_err() {
            failed.push(name);
        }
    }
    if !failed.is_empty() {
        return Err(format!("cantools disagrees with host-sim on {}", failed.join(", ")));
    }
    println!("can-check: every frame decodes with cantools {CANTOOLS_VERSION} to host-sim's values");
    for name in ["demo", "small"] {
        let frames = asc_round_trip(&log(name), &work.0.join(format!("{name}.asc")))?;
        println!("can-check: log2asc/asc2log round trip of {name}.log: {frames} frames, one header, same times");
    }
    Ok(())
}

/// One frame of a candump log: (time µs, `ID#DATA`).
fn candump_frames(text: &str) -> Result<Vec<(u64, String)>> {
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let mut it = l.split_whitespace();
            let (time, _iface, frame) = (it.next(), it.next(), it.next());
            let t = time
                .and_then(|t| t.strip_prefix('(')?.strip_suffix(')')?.split_once('.'))
                .and_then(|(s, us)| Some(s.parse::<u64>().ok()? * 1_000_000 + us.parse::<u64>().ok()?));
            match (t, frame) {
                (Some(t), Some(f)) => Ok((t, f.to_owned())),
                _ => Err(format!("not a candump line: {l}")),
            }
        })
        .collect()
}

/// can-utils `log2asc` then `asc2log` on a candump log: the ASC file has exactly one header,
/// dated in the log's year (absolute time stamps), and the frames come back identical at the same
/// times relative to the first frame. (`asc2log` dates its output by the ASC header when it can
/// parse it, else by the current time, so absolute times are compared through the header.)
fn asc_round_trip(log: &std::path::Path, asc: &std::path::Path) -> Result<usize> {
    require("log2asc")?;
    require("asc2log")?;
    let original = std::fs::read_to_string(log).map_err(|e| format!("{}: {e}", log.display()))?;
    let frames = candump_frames(&original)?;
    let asc_text = stdout_of(Command::new("log2asc").arg("-I").arg(log).arg("can0"))?;
    std::fs::write(asc, &asc_text).map_err(|e| format!("{}: {e}", asc.display()))?;
    let headers: Vec<&str> = asc_text.lines().filter(|l| l.starts_with("date ")).collect();
    if headers.len() != 1 {
        return Err(format!("log2asc wrote {} headers for {} (zero-based time stamps?)", headers.len(), log.display()));
    }
    // The log epoch is 2026-01-01T00:00:00Z.
    if !headers[0].ends_with(" 2026") {
        return Err(format!("ASC header {:?} is not dated at the log epoch", headers[0]));
    }
    let back = candump_frames(&stdout_of(Command::new("asc2log").arg("-I").arg(asc))?)?;
    if back.len() != frames.len() {
        return Err(format!("{}: {} frames, {} after log2asc/asc2log", log.display(), frames.len(), back.len()));
    }
    let (t0, b0) = (frames.first().map_or(0, |f| f.0), back.first().map_or(0, |f| f.0));
    for (i, (a, b)) in frames.iter().zip(&back).enumerate() {
        if a.1 != b.1 || a.0 - t0 != b.0 - b0 {
            return Err(format!("{} frame {}: {:?} came back as {:?}", log.display(), i + 1, a, b));
        }
    }
    Ok(frames.len())
}
