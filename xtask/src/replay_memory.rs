//! `cargo xtask replay-memory`: peak memory of `host-sim replay` on a 63 MB trace (≈ 4.6 M samples,
//! 12.8 hours at 100 Hz), measured with `/usr/bin/time -v`; fails above 64 MiB. The trace reader
//! streams and the plot keeps a bounded number of points, so the figure does not grow with the
//! trace's length (a 60 s trace needs about the same).

use crate::util::{cargo, output, require, target_dir, Result, Scratch};
use std::io::Write;
use std::process::Command;

/// Size of the trace, bytes.
const TRACE_BYTES: u64 = 63_000_000;
/// The bound on the peak resident set, KiB.
const BOUND_KIB: u64 = 64 * 1024;

/// Writes a `t_s,adc` trace of at least [`TRACE_BYTES`]: the ADC counts of a recorded release
/// repeated, on a continuous 10 ms clock.
fn write_trace(path: &std::path::Path) -> Result<u64> {
    let source = "tests/data/small/traces/test/normal_0000.csv";
    let text = std::fs::read_to_string(source).map_err(|e| format!("cannot read {source}: {e}"))?;
    let counts: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .filter_map(|l| l.split(',').nth(1))
        .collect();
    if counts.is_empty() {
        return Err(format!("{source} has no samples"));
    }
    let file = std::fs::File::create(path).map_err(|e| format!("cannot create {}: {e}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let werr = |e: std::io::Error| format!("cannot write {}: {e}", path.display());
    writeln!(w, "t_s,adc").map_err(werr)?;
    let (mut n, mut bytes) = (0u64, 8u64);
    while bytes < TRACE_BYTES {
        for c in &counts {
            let line = format!("{}.{:02},{c}\n", n / 100, n % 100);
            bytes += line.len() as u64;
            w.write_all(line.as_bytes()).map_err(werr)?;
            n += 1;
        }
    }
    w.flush().map_err(werr)?;
    Ok(n)
}

/// Runs the measurement.
pub fn check() -> Result<()> {
    require("/usr/bin/time")?;
    let scratch = Scratch::new("replay-memory")?;
    let trace = scratch.0.join("long.csv");
    let samples = write_trace(&trace)?;
    let size = std::fs::metadata(&trace).map_err(|e| e.to_string())?.len();
    // The `test` profile (opt-level 3), which `cargo test --workspace` builds anyway.
    cargo(&["build", "--quiet", "--profile", "test", "-p", "host-sim"])?;
    let host_sim = target_dir().join("debug/host-sim");
    let out = output(
        Command::new("/usr/bin/time")
            .arg("-v")
            .arg(&host_sim)
            .arg("replay")
            .arg(&trace)
            .arg("--out")
            .arg(scratch.0.join("out"))
            .arg("--plot")
            .arg(scratch.0.join("plot"))
            .arg("--can-log")
            .arg(scratch.0.join("long.log")),
    )?;
    let err = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        return Err(format!("replay failed ({}):\n{err}", out.status));
    }
    let field = |name: &str| -> Option<String> {
        err.lines().find_map(|l| l.trim().strip_prefix(name).map(|v| v.trim().to_owned()))
    };
    let rss: u64 = field("Maximum resident set size (kbytes):")
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| format!("no peak memory in the output of /usr/bin/time:\n{err}"))?;
    let wall = field("Elapsed (wall clock) time (h:mm:ss or m:ss):").unwrap_or_default();
    println!(
        "replay-memory: {size} B trace ({samples} samples) with --out, --plot and --can-log: peak RSS {rss} KiB \
         ({:.1} MiB; bound {} MiB), wall {wall}",
        rss as f64 / 1024.0,
        BOUND_KIB / 1024
    );
    if rss > BOUND_KIB {
        return Err(format!("peak memory {rss} KiB above the bound of {BOUND_KIB} KiB"));
    }
    Ok(())
}
