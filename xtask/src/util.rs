//! Running programs and reporting steps.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// A task's error: a message for the user (what failed and what to do).
pub type Result<T> = std::result::Result<T, String>;

/// The repository root (this crate lives in `xtask/` below it).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// Prints a step heading.
pub fn step(title: &str) {
    println!("\n=== {title}");
}

/// Whether `program` is on the PATH.
pub fn have(program: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {program}")])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Fails with an install hint unless `program` is on the PATH.
pub fn require(program: &str) -> Result<()> {
    if have(program) {
        Ok(())
    } else {
        Err(format!("{program} not found: run `cargo xtask setup` first"))
    }
}

fn describe(cmd: &Command) -> String {
    let mut s = cmd.get_program().to_string_lossy().into_owned();
    for a in cmd.get_args() {
        s.push(' ');
        s.push_str(&a.to_string_lossy());
    }
    s
}

/// Runs a command with inherited output; an error names it and its exit status.
pub fn run(cmd: &mut Command) -> Result<()> {
    let status = cmd.status().map_err(|e| format!("cannot start `{}`: {e}", describe(cmd)))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("`{}` failed ({status})", describe(cmd)))
    }
}

/// Runs a command and returns its output whatever its exit status (the caller judges it).
pub fn output(cmd: &mut Command) -> Result<Output> {
    cmd.output().map_err(|e| format!("cannot start `{}`: {e}", describe(cmd)))
}

/// Runs a command and returns its standard output; fails (with its standard error) unless it
/// exits 0.
pub fn stdout_of(cmd: &mut Command) -> Result<String> {
    let out = output(cmd)?;
    if !out.status.success() {
        return Err(format!("`{}` failed ({}):\n{}", describe(cmd), out.status, String::from_utf8_lossy(&out.stderr)));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// `cargo ARGS` with inherited output.
pub fn cargo(args: &[&str]) -> Result<()> {
    run(Command::new(cargo_bin()).args(args))
}

/// The cargo that runs this task (so a pinned toolchain stays pinned).
pub fn cargo_bin() -> String {
    std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned())
}

/// The cargo target directory of the root workspace.
pub fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root().join("target"), PathBuf::from)
}

/// A fresh scratch directory under the target directory, removed when dropped.
pub struct Scratch(pub PathBuf);

impl Scratch {
    /// Creates (anew) `target/xtask/NAME`.
    pub fn new(name: &str) -> Result<Self> {
        let dir = target_dir().join("xtask").join(name);
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        Ok(Self(dir))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
