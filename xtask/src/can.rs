//! `cargo xtask can-check`: the CAN checks `cargo test --workspace` does not cover.
//!
//! 1. `host-sim` with the `socketcan` feature (off by default, so the workspace build never
//!    compiles it): check and clippy with warnings denied.
//! 2. Python cantools (the venv of `cargo xtask setup`) decodes every frame the project emits,
//!    unchanged, to the values of the project's own decoder (`host-sim can decode --format csv`),
//!    with an independently computed E2E CRC: the demonstration log, the code sweep (every code,
//!    values at and beyond the edges) and the replay of the small data set.

use crate::setup::{venv_python, CANTOOLS_VERSION};
use crate::util::{cargo, run, stdout_of, target_dir, Result, Scratch};
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
        let csv = stdout_of(Command::new(&hs).args(["can", "decode", "--format", "csv"]).arg(log(name)))?;
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
    Ok(())
}
