//! `cargo xtask python`: the Python package (`crates/py`, module `pbm`) built from the repository
//! with pip + maturin into the venv `target/py-venv`, then its pytest suite: `pbm.replay` equals
//! `host-sim replay --can-log` on the traces of the firmware's CAN equality check (so Python =
//! CLI = firmware), decoder / twin / audit / fleet history equal their commands, archives round
//! trip, and the fleet replay on a 2-worker Dask local cluster equals the single-process run.

use crate::util::{cargo, output, root, run, step, target_dir, Result};
use std::process::Command;

/// The pinned Python packages of the venv (build backend, the package's dependencies, tests).
pub const PINS: [&str; 5] =
    ["maturin==1.16.0", "numpy==2.4.6", "pyarrow==26.0.1", "dask[distributed]==2026.8.0", "pytest==9.2.0"];

/// The venv of the Python package.
pub fn venv_dir() -> std::path::PathBuf {
    target_dir().join("py-venv")
}

fn venv_bin(program: &str) -> std::path::PathBuf {
    venv_dir().join("bin").join(program)
}

/// The import check that says the venv holds exactly [`PINS`].
fn pins_check() -> String {
    let pairs: Vec<String> = PINS
        .iter()
        .map(|p| {
            let (name, version) = p.split_once("==").unwrap_or((p, ""));
            let name = name.split('[').next().unwrap_or(name);
            format!("('{name}', '{version}')")
        })
        .collect();
    format!(
        "import sys, importlib.metadata as m\n\
         bad = [n for n, v in [{}] if m.version(n) != v]\n\
         sys.exit(1 if bad else 0)",
        pairs.join(", ")
    )
}

/// `setup`: the venv with [`PINS`] (left alone when it already has them).
pub fn venv() -> Result<()> {
    let py = venv_bin("python");
    if output(Command::new(&py).args(["-c", &pins_check()])).is_ok_and(|o| o.status.success()) {
        return Ok(());
    }
    let start = std::time::Instant::now();
    crate::setup::make_venv(&venv_dir())?;
    println!("setup: {} into {}", PINS.join(" "), venv_dir().display());
    run(Command::new(&py).args(["-m", "pip", "install", "--quiet", "--disable-pip-version-check"]).args(PINS))?;
    println!("setup: Python venv in {:.0} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// Installs the package from the repository (`pip install ./crates/py`, maturin as the PEP 517
/// backend) and runs its tests against `host-sim`.
pub fn check() -> Result<()> {
    let py = venv_bin("python");
    if !output(Command::new(&py).args(["-c", &pins_check()])).is_ok_and(|o| o.status.success()) {
        return Err(format!("{} lacks the pinned packages: run `cargo xtask setup` first", venv_dir().display()));
    }
    let start = std::time::Instant::now();
    // PATH: pip runs the venv's maturin (no build isolation: the pinned one, no download).
    let path = std::env::var_os("PATH").unwrap_or_default();
    let mut paths = vec![venv_dir().join("bin")];
    paths.extend(std::env::split_paths(&path));
    let path = std::env::join_paths(paths).map_err(|e| format!("PATH: {e}"))?;
    // Release, as a user's `pip install ./crates/py` builds it (the `report-check` step has
    // already built host-sim's release dependencies). Not the `test` profile: cargo builds a
    // library as a test harness executable there, which Python cannot load.
    run(Command::new(&py)
        .args(["-m", "pip", "install", "--quiet", "--disable-pip-version-check", "--no-build-isolation"])
        .arg("--force-reinstall")
        .arg("--no-deps")
        .arg(root().join("crates/py"))
        .env("PATH", &path))?;
    println!("python: package built and installed in {:.0} s", start.elapsed().as_secs_f64());
    cargo(&["build", "--quiet", "--profile", "test", "-p", "host-sim"])?;
    run(Command::new(&py)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(root().join("crates/py/tests"))
        .current_dir(root().join("crates/py"))
        .env("PBM_HOST_SIM", target_dir().join("debug/host-sim"))
        .env("PATH", &path))?;
    println!("python: build, install and tests in {:.0} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// `cargo xtask python`: setup of the venv, then [`check`].
pub fn task() -> Result<()> {
    step("Python package: pip install ./crates/py, pytest");
    venv()?;
    check()
}
