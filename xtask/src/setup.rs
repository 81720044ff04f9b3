//! `cargo xtask setup`: installs what the project needs on a fresh Debian machine with rustup.
//! Idempotent: what is there is left alone. The only place that installs anything.

use crate::util::{have, output, run, step, target_dir, Result};
use std::process::Command;

/// Rust target of the firmware and the components the checks use.
const RUST_TARGET: &str = "thumbv7em-none-eabihf";
const COMPONENTS: [&str; 2] = ["rustfmt", "clippy"];
/// Debian packages: (program that shows it is installed, package).
const APT: [(&str, &str); 5] = [
    ("qemu-system-arm", "qemu-system-arm"), // runs the firmware (mps2-an386)
    ("llvm-size", "llvm"),                  // firmware size and symbol figures
    ("chromium", "chromium"),               // the report seen as a person sees it
    ("log2asc", "can-utils"),               // candump log interoperability
    ("/usr/bin/time", "time"),              // peak memory of a replay
];
/// The off-the-shelf DBC tool the CAN check decodes every frame with (pinned).
pub const CANTOOLS_VERSION: &str = "45.1.0";
/// The defmt log decoder the QEMU runner (`firmware/qemu-run.sh`) pipes the firmware's log
/// through (pinned; speaks the wire format of defmt 1.x).
const DEFMT_PRINT_VERSION: &str = "1.2.0";

/// Installs everything; prints one line per thing it had to do.
pub fn install() -> Result<()> {
    step("setup");
    let installed = |args: &[&str]| -> Result<String> {
        Ok(String::from_utf8_lossy(&output(Command::new("rustup").args(args))?.stdout).into_owned())
    };
    if !installed(&["target", "list", "--installed"])?.lines().any(|l| l.trim() == RUST_TARGET) {
        run(Command::new("rustup").args(["target", "add", RUST_TARGET]))?;
    }
    let components = installed(&["component", "list", "--installed"])?;
    for c in COMPONENTS {
        if !components.lines().any(|l| l.starts_with(c)) {
            run(Command::new("rustup").args(["component", "add", c]))?;
        }
    }
    let missing: Vec<&str> = APT.iter().filter(|(prog, _)| !have(prog)).map(|(_, pkg)| *pkg).collect();
    if !missing.is_empty() {
        println!("setup: installing {} (apt)", missing.join(" "));
        let sudo = if is_root() { vec![] } else { vec!["sudo"] };
        let apt = |args: &[&str]| {
            let mut all: Vec<&str> = sudo.clone();
            all.push("apt-get");
            all.extend_from_slice(args);
            let mut cmd = Command::new(all[0]);
            cmd.args(&all[1..]).env("DEBIAN_FRONTEND", "noninteractive");
            run(&mut cmd)
        };
        apt(&["update", "-qq"])?;
        let mut args = vec!["install", "-y", "-qq"];
        args.extend(&missing);
        apt(&args)?;
    }
    cantools_venv()?;
    crate::python::venv()?;
    defmt_print()?;
    let qemu = output(Command::new("qemu-system-arm").arg("--version"))?;
    println!("setup: {}", String::from_utf8_lossy(&qemu.stdout).lines().next().unwrap_or("qemu-system-arm"));
    Ok(())
}

fn is_root() -> bool {
    output(Command::new("id").arg("-u")).is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

/// The Python interpreter of the cantools venv.
pub fn venv_python() -> std::path::PathBuf {
    target_dir().join("can-venv/bin/python")
}

/// A venv under the target directory with the pinned cantools (Debian's python3 needs
/// python3-venv for `-m venv`; pyenv's does not).
fn cantools_venv() -> Result<()> {
    let py = venv_python();
    let check = format!("import cantools, sys; sys.exit(cantools.__version__ != '{CANTOOLS_VERSION}')");
    if output(Command::new(&py).args(["-c", &check])).is_ok_and(|o| o.status.success()) {
        return Ok(());
    }
    let venv = target_dir().join("can-venv");
    make_venv(&venv)?;
    println!("setup: cantools {CANTOOLS_VERSION} into {}", venv.display());
    run(Command::new(&py)
        .args(["-m", "pip", "install", "--quiet", "--disable-pip-version-check"])
        .arg(format!("cantools=={CANTOOLS_VERSION}")))
}

/// Creates (anew) a venv at `venv`, installing python3-venv (apt) when `python3 -m venv` lacks it.
pub fn make_venv(venv: &std::path::Path) -> Result<()> {
    let make = || {
        let _ = std::fs::remove_dir_all(venv);
        output(Command::new("python3").args(["-m", "venv"]).arg(venv)).is_ok_and(|o| o.status.success())
    };
    if !make() {
        println!("setup: installing python3-venv (apt)");
        run(Command::new("apt-get").args(["install", "-y", "-qq", "python3-venv"]))?;
        if !make() {
            return Err(format!("cannot create a Python venv in {}", venv.display()));
        }
    }
    Ok(())
}

/// `defmt-print` (the firmware's defmt log decoder) from crates.io, built with its own lock file.
fn defmt_print() -> Result<()> {
    let installed = output(Command::new("defmt-print").arg("--version"))
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == format!("defmt-print {DEFMT_PRINT_VERSION}"));
    if installed {
        return Ok(());
    }
    println!("setup: defmt-print {DEFMT_PRINT_VERSION} (cargo install, about 3 minutes on 2 cores)");
    run(Command::new(crate::util::cargo_bin()).args([
        "install",
        "--locked",
        "--quiet",
        "defmt-print",
        "--version",
        DEFMT_PRINT_VERSION,
    ]))
}
