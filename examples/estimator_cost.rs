//! Cost of the online estimator per sample: a host proxy for the Cortex-M4 budget.
//!
//! `cargo run --release --example estimator_cost [SAMPLES]` measures wall time per update and,
//! when `valgrind` is installed, re-runs itself under `valgrind --tool=callgrind` to count
//! executed x86-64 instructions per call of `ReleaseEstimator::update` (split into the nine
//! accumulate-only samples of a block and the block-end sample that runs the regressions) and of
//! the whole `Monitor::update` pipeline. The figures are printed and written to
//! `bench/estimator.md`. The input is a nominal release by the core twin, then the plateau.
//!
//! x86-64 instruction counts are a proxy: the M4 (Thumb-2, single-precision FPU, no 64-bit
//! multiply-accumulate in one instruction) differs; the firmware measures on the emulated M4.

use pbm::estimator::{EstimatorConfig, Phase, ReleaseEstimator};
use pbm::monitor::Monitor;
use pbm::sensor::adc_from_bar;
use pbm::{AdcCounts, PressureQ24, Twin, TwinParams};
use std::hint::black_box;
use std::process::Command;
use std::time::Instant;

const CHILD_ENV: &str = "PBM_ESTIMATOR_COST_CHILD";

fn pressures(n: usize) -> Vec<PressureQ24> {
    let mut twin = Twin::new(&TwinParams::nominal()).expect("nominal twin");
    let mut p = PressureQ24::ATMOSPHERE;
    (0..n)
        .map(|_| {
            let now = p;
            p = twin.update(true).pressure;
            now
        })
        .collect()
}

#[inline(never)]
fn est_accumulate(e: &mut ReleaseEstimator, p: PressureQ24) {
    // Distinct bodies keep the linker from folding the two wrappers into one symbol.
    black_box(1u8);
    let _ = black_box(e.update(Some(black_box(p)), true));
}

#[inline(never)]
fn est_block_end(e: &mut ReleaseEstimator, p: PressureQ24) {
    black_box(2u16);
    let _ = black_box(e.update(Some(black_box(p)), true));
}

#[inline(never)]
fn est_block_end_plateau(e: &mut ReleaseEstimator, p: PressureQ24) {
    black_box(3u32);
    let _ = black_box(e.update(Some(black_box(p)), true));
}

#[inline(never)]
fn monitor_update(m: &mut Monitor, c: AdcCounts) {
    black_box(m.update(black_box(c), true));
}

fn run_estimator(ps: &[PressureQ24]) {
    let mut e = ReleaseEstimator::new(&TwinParams::nominal(), EstimatorConfig::default()).expect("estimator");
    for (i, &p) in ps.iter().enumerate() {
        if i % 10 == 9 && e.phase() == Phase::Plateau {
            est_block_end_plateau(&mut e, p);
        } else if i % 10 == 9 {
            est_block_end(&mut e, p);
        } else {
            est_accumulate(&mut e, p);
        }
    }
    black_box(e.estimates());
}

fn run_monitor(adc: &[AdcCounts]) {
    let mut m = Monitor::new(&TwinParams::nominal()).expect("monitor");
    for &c in adc {
        monitor_update(&mut m, c);
    }
    black_box(m.status());
}

/// Inclusive instruction count of every function whose name contains `name`, from
/// `callgrind_annotate --inclusive=yes` output.
fn inclusive_ir(annotate: &str, name: &str) -> Option<u64> {
    annotate.lines().filter(|l| l.contains(name) && !l.contains("[inlined]")).find_map(|l| {
        let n = l.split_whitespace().next()?;
        n.replace(',', "").parse().ok()
    })
}

/// Block-end samples that the estimator processes in its plateau phase (same run, no valgrind).
fn ps_plateau_blocks(ps: &[PressureQ24]) -> usize {
    let mut e = ReleaseEstimator::new(&TwinParams::nominal(), EstimatorConfig::default()).expect("estimator");
    let mut n = 0;
    for (i, &p) in ps.iter().enumerate() {
        if i % 10 == 9 && e.phase() == Phase::Plateau {
            n += 1;
        }
        let _ = e.update(Some(p), true);
    }
    n
}

fn main() {
    let samples: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(12_000);
    let ps = pressures(samples);
    let adc: Vec<AdcCounts> = ps.iter().map(|p| adc_from_bar(p.to_bar_g())).collect();
    if std::env::var_os(CHILD_ENV).is_some() {
        run_estimator(&ps);
        run_monitor(&adc);
        return;
    }

    let t = Instant::now();
    for _ in 0..20 {
        run_estimator(&ps);
    }
    let est_ns = t.elapsed().as_nanos() as f64 / (20 * samples) as f64;
    let t = Instant::now();
    for _ in 0..5 {
        run_monitor(&adc);
    }
    let mon_ns = t.elapsed().as_nanos() as f64 / (5 * samples) as f64;
    let mut report = format!(
        "# Estimator cost (host proxy)\n\n`cargo run --release --example estimator_cost {samples}`: nominal release by \
         the core twin, then plateau ({samples} samples).\n\n| figure | value |\n|---|---|\n\
         | wall time per `ReleaseEstimator::update` (x86-64) | {est_ns:.1} ns |\n\
         | wall time per `Monitor::update` (twin + estimator) | {mon_ns:.1} ns |\n"
    );

    let exe = std::env::current_exe().expect("own path");
    let out = std::env::temp_dir().join(format!("pbm-estimator-cost-{}.out", std::process::id()));
    let status = Command::new("valgrind")
        .args(["--tool=callgrind", "--quiet"])
        .arg(format!("--callgrind-out-file={}", out.display()))
        .arg(&exe)
        .arg(samples.to_string())
        .env(CHILD_ENV, "1")
        .status();
    let annotate = match status {
        Ok(s) if s.success() => Command::new("callgrind_annotate")
            .args(["--inclusive=yes", "--threshold=100"])
            .arg(&out)
            .output()
            .ok()
            .map(|o| String::from_utf8_lossy(&o.stdout).into_owned()),
        _ => None,
    };
    let _ = std::fs::remove_file(&out);
    match annotate {
        Some(a) => {
            let blocks = samples / 10;
            let acc = inclusive_ir(&a, "est_accumulate").map(|v| v as f64 / (samples - blocks) as f64);
            let plateau_blocks = ps_plateau_blocks(&ps);
            let end = inclusive_ir(&a, "est_block_end ").map(|v| v as f64 / (blocks - plateau_blocks) as f64);
            let end_plateau =
                inclusive_ir(&a, "est_block_end_plateau").map(|v| v as f64 / plateau_blocks.max(1) as f64);
            let mon = inclusive_ir(&a, "monitor_update").map(|v| v as f64 / samples as f64);
            let f = |v: Option<f64>| v.map_or("n/a".to_owned(), |v| format!("{v:.0}"));
            let avg = acc.zip(end).zip(end_plateau).map(|((a, e), p)| {
                (9.0 * a * blocks as f64 + e * (blocks - plateau_blocks) as f64 + p * plateau_blocks as f64)
                    / samples as f64
            });
            report.push_str(&format!(
                "| x86-64 instructions per estimator update, accumulate-only sample | {} |\n\
                 | x86-64 instructions per estimator update, block-end sample before the plateau (fill RLS) | {} |\n\
                 | x86-64 instructions per estimator update, block-end sample on the plateau (plateau RLS + supply) | {} |\n\
                 | x86-64 instructions per estimator update, average | {} |\n\
                 | x86-64 instructions per `Monitor::update` (whole pipeline), average | {} |\n\n\
                 Instruction counts: `valgrind --tool=callgrind`, inclusive cost of `#[inline(never)]` wrappers \
                 divided by the number of calls. Budget: 5000 M4 instructions per sample for the whole pipeline.\n",
                f(acc),
                f(end),
                f(end_plateau),
                f(avg),
                f(mon)
            ));
        }
        None => report.push_str("\nvalgrind/callgrind_annotate not available: no instruction counts.\n"),
    }
    print!("{report}");
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("bench");
    if std::fs::create_dir_all(&dir).is_ok() && std::fs::write(dir.join("estimator.md"), &report).is_ok() {
        eprintln!("wrote {}", dir.join("estimator.md").display());
    }
}
