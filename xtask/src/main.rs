//! `cargo xtask`: the project's scripts as one Rust tool (the embassy `ci` pattern).
//!
//! ```text
//! cargo xtask setup             install what the project needs (Rust target, QEMU, LLVM tools,
//!                               Chromium, can-utils, Python venvs with cantools and with the
//!                               Python package's pinned dependencies); idempotent
//! cargo xtask test-all          every check CI runs: setup, fmt, clippy, all tests, firmware
//! cargo xtask demo [ARGS]       setup, then the main job: `host-sim demo ARGS`
//! cargo xtask fw-qemu           firmware twin check (and its failing self-test), monitor run
//! cargo xtask fw-can-equality   QEMU CAN frames == `host-sim replay --can-log`, byte for byte
//! cargo xtask fw-bench [--check]  firmware cost figures -> bench/firmware.md (or check bounds)
//! cargo xtask fw-lint           rustfmt + clippy -D warnings of the firmware workspace
//! cargo xtask fw-board          NUCLEO-F446RE board image: rustfmt, clippy -D warnings, build,
//!                               size against the 32 KiB / 8 KiB budget
//! cargo xtask can-check         socketcan build, cantools decodes every frame the project emits
//! cargo xtask report-check      `host-sim demo --quick` seen in headless Chromium
//! cargo xtask python          the Python package: pip install ./crates/py into target/py-venv,
//!                               pytest (Python = CLI = firmware frames, Dask local cluster)
//! cargo xtask replay-memory     peak memory of `host-sim replay` on a 63 MB trace (≤ 64 MiB)
//! cargo xtask shifted-sets      releases the model was not trained on: right / refused / wrong
//! cargo xtask sensor-fault-battery [SEED]  every sensor fault on every class: no wrong class
//! ```
//!
//! Installing system packages happens only in `setup`; every check says what is missing and
//! fails instead of installing it. Firmware steps go through the `fw-*` cargo aliases of
//! `.cargo/config.toml` (one definition of how the firmware is built and run).

mod board;
mod can;
mod firmware;
mod fw_bench;
mod python;
mod replay_memory;
mod report;
mod setup;
mod util;

use std::process::ExitCode;
use util::{cargo, step, Result};

const USAGE: &str = "usage: cargo xtask <setup | test-all | demo [ARGS] | fw-qemu | fw-can-equality | \
fw-bench [--check] | fw-lint | fw-board | can-check | report-check | python | replay-memory | shifted-sets | sensor-fault-battery [SEED]>";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((command, rest)) = args.split_first() else {
        eprintln!("{USAGE}");
        return ExitCode::from(2);
    };
    // Every task runs from the repository root, wherever cargo was called.
    if let Err(e) = std::env::set_current_dir(util::root()) {
        eprintln!("xtask: cannot enter the repository root: {e}");
        return ExitCode::FAILURE;
    }
    let result = match (command.as_str(), rest) {
        ("setup", []) => setup::install(),
        ("test-all", []) => test_all(),
        ("demo", args) => demo(args),
        ("fw-qemu", []) => firmware::qemu(),
        ("fw-can-equality", []) => firmware::can_equality(),
        ("fw-bench", []) => firmware::bench(false),
        ("fw-bench", [flag]) if flag == "--check" => firmware::bench(true),
        ("fw-lint", []) => firmware::lint(),
        ("fw-board", []) => board::check(),
        ("can-check", []) => can::check(),
        ("report-check", []) => report::check(),
        ("replay-memory", []) => replay_memory::check(),
        ("python", []) => python::task(),
        ("shifted-sets", []) => robustness(&["shifted-sets"]),
        ("sensor-fault-battery", seed) if seed.len() <= 1 => {
            robustness(&[&["sensor-fault-battery"][..], &seed.iter().map(String::as_str).collect::<Vec<_>>()].concat())
        }
        _ => {
            eprintln!("{USAGE}");
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask {command}: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Every check of the project, in the order that fails fastest; README's test command and CI.
fn test_all() -> Result<()> {
    setup::install()?;
    step("format");
    cargo(&["fmt", "--all", "--", "--check"])?;
    step("clippy (host, all targets)");
    cargo(&["clippy", "--workspace", "--all-targets", "--", "-D", "warnings"])?;
    step("clippy (core on thumbv7em-none-eabihf)");
    cargo(&["clippy", "-p", "parking-brake-monitor", "--target", firmware::TARGET, "--", "-D", "warnings"])?;
    step("firmware: rustfmt + clippy");
    firmware::lint()?;
    step("firmware: NUCLEO-F446RE board image (rustfmt, clippy, build, size)");
    board::check()?;
    step("CAN: socketcan build, cantools");
    can::check()?;
    step("firmware: CAN frames in QEMU equal the host's, cost within bounds");
    firmware::can_equality()?;
    firmware::bench(true)?;
    step("report in headless Chromium");
    report::check()?;
    step("tests (host)");
    cargo(&["test", "--workspace"])?;
    step("Python package: pip install ./crates/py, pytest (Python = CLI = firmware frames, Dask)");
    python::check()?;
    step("replay of a 63 MB trace within 64 MiB");
    replay_memory::check()?;
    step("firmware in QEMU");
    firmware::qemu()?;
    println!("\ntest-all: all checks passed");
    Ok(())
}

/// The robustness measurements of the README (`crates/lab/examples/robustness.rs`).
fn robustness(args: &[&str]) -> Result<()> {
    let mut a = vec!["run", "--release", "-q", "-p", "pbm-lab", "--example", "robustness", "--"];
    a.extend_from_slice(args);
    cargo(&a)
}

/// The main job: the fleet demo that ends in `report/index.html`.
fn demo(args: &[String]) -> Result<()> {
    setup::install()?;
    let mut a = vec!["run", "--release", "-q", "-p", "host-sim", "--", "demo"];
    a.extend(args.iter().map(String::as_str));
    cargo(&a)
}
