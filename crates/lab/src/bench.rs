//! `host-sim bench`: throughput figures of the twin, the monitor pipeline and `generate`, and
//! the accuracy study behind [`GENERATE_STEP_S`]. Prints a report and writes it (Markdown) to
//! `--report` (default `bench/host.md`).

use crate::generate::{draw_fault, fleet, generate, simulate_plant, GenerateOptions, GENERATE_STEP_S};
use crate::reference::REFERENCE_STEP_S;
use anyhow::{Context, Result};
use pbm::features::{ReleaseFeatures, ReleaseSample};
use pbm::monitor::Monitor;
use pbm::{AdcCounts, FaultClass, Twin, TwinParams};
use std::fmt::Write as _;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

/// Options of the bench run.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchOptions {
    /// Twin-alone samples to time (single thread).
    pub twin_samples: u64,
    /// Monitor-pipeline samples to time (single thread).
    pub pipeline_samples: u64,
    /// Training traces per class for the generate timing (paper size: 1100 + 50, 5 classes).
    pub per_class: usize,
    /// Test traces per class for the generate timing.
    pub test_per_class: usize,
    /// Skip the generate timing.
    pub skip_generate: bool,
    /// Skip the integration-step accuracy study.
    pub skip_step_study: bool,
    /// Scratch directory for the generated set (removed afterwards).
    pub scratch: Option<PathBuf>,
    /// Where to write the Markdown report.
    pub report: PathBuf,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            twin_samples: 12_000_000,
            pipeline_samples: 3_000_000,
            per_class: 1100,
            test_per_class: 50,
            skip_generate: false,
            skip_step_study: false,
            scratch: None,
            report: PathBuf::from("bench/host.md"),
        }
    }
}

/// Samples per second, by wall clock and by the thread's CPU time (`None` off Linux).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rate {
    /// Samples per wall-clock second.
    pub wall: f64,
    /// Samples per CPU second of the measuring thread.
    pub cpu: Option<f64>,
}

impl std::fmt::Display for Rate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.2} M samples/s wall", self.wall / 1e6)?;
        if let Some(c) = self.cpu {
            write!(f, ", {:.2} M samples/s per CPU second", c / 1e6)?;
        }
        Ok(())
    }
}

fn rate(samples: u64, start: Instant, cpu0: Option<f64>) -> Rate {
    let wall = samples as f64 / start.elapsed().as_secs_f64();
    let cpu = thread_cpu_seconds().zip(cpu0).map(|(b, a)| b - a).filter(|&c| c > 0.0).map(|c| samples as f64 / c);
    Rate { wall, cpu }
}

/// Samples per second of the fixed-point twin alone (`Twin::update`), one thread, in releases
/// of 6000 samples (restarted with `reset`, as the monitor does at each release).
pub fn twin_throughput(samples: u64) -> Result<Rate> {
    let mut twin = Twin::new(&TwinParams::nominal()).map_err(|e| anyhow::anyhow!("{e}"))?;
    let cpu0 = thread_cpu_seconds();
    let start = Instant::now();
    let mut done = 0;
    while done < samples {
        twin.reset();
        for _ in 0..6000 {
            black_box(twin.update(black_box(true)));
        }
        done += 6000;
    }
    Ok(rate(done, start, cpu0))
}

/// Samples per second of the per-sample monitor and release features (`Monitor::update`, then
/// `ReleaseFeatures::update` during the release, as `Pipeline::step` runs them), one thread, fed
/// with the ADC samples of a generated healthy release.
pub fn pipeline_throughput(samples: u64) -> Result<Rate> {
    let fleet = fleet(1, 1);
    let job = crate::generate::TraceJob { class: FaultClass::Normal, test: false, k: 0, locomotive: 0 };
    let (adc, _) = crate::generate::run_job(&job, &fleet, 1, &Default::default())?;
    let mut monitor = Monitor::new(&TwinParams::nominal()).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut features = ReleaseFeatures::new();
    let cpu0 = thread_cpu_seconds();
    let start = Instant::now();
    let mut done = 0;
    while done < samples {
        // Valve closed for one sample, then a release: the monitor restarts its twin.
        black_box(monitor.update(AdcCounts(410), false));
        for &c in &adc {
            let step = monitor.update(black_box(AdcCounts(c)), true);
            features.update(&ReleaseSample::from(&step));
            black_box(&features);
        }
        done += adc.len() as u64 + 1;
    }
    Ok(rate(done, start, cpu0))
}

/// CPU time (user + system, all threads) of this process so far, s; `None` off Linux. Wall
/// clock on a shared machine measures the neighbours too; CPU time does not.
pub fn process_cpu_seconds() -> Option<f64> {
    cpu_seconds("/proc/self/stat")
}

/// CPU time of the calling thread so far, s; `None` off Linux.
pub fn thread_cpu_seconds() -> Option<f64> {
    cpu_seconds("/proc/thread-self/stat")
}

fn cpu_seconds(stat_file: &str) -> Option<f64> {
    let stat = std::fs::read_to_string(stat_file).ok()?;
    // Fields after the command name (which may contain spaces) start at state, field 3;
    // utime and stime are fields 14 and 15, in clock ticks (100 per second on Linux).
    let rest = stat.get(stat.rfind(')')? + 2..)?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// One case of the step study: a name and the plant.
fn step_study_cases() -> Vec<(String, TwinParams)> {
    let n = TwinParams::nominal();
    let mut cases = vec![("normal".to_owned(), n)];
    for (name, p) in [
        ("air_leak 0.5 mm", n.with_leak_mm(0.5)),
        ("air_leak 1.2 mm", n.with_leak_mm(1.2)),
        ("orifice_block 0.35 mm", n.with_orifice_mm(0.35)),
        ("orifice_block 1.0 mm", n.with_orifice_mm(1.0)),
        ("leak_and_block 1.2/0.35 mm", n.with_leak_mm(1.2).with_orifice_mm(0.35)),
        ("leak_and_block 0.5/1.0 mm", n.with_leak_mm(0.5).with_orifice_mm(1.0)),
        ("low_supply 3.5 bar", n.with_supply_bar_g(3.5)),
        ("low_supply 7.2 bar", n.with_supply_bar_g(7.2)),
        ("orifice_missing 2.5 mm", n.with_orifice_mm(2.5)),
        ("orifice_missing 4.0 mm", n.with_orifice_mm(4.0)),
    ] {
        cases.push((name.to_owned(), p));
    }
    // A spread locomotive, to cover parameters away from nominal.
    let loco = fleet(1, 1).remove(0).params;
    let mut rng = crate::generate::TraceJob { class: FaultClass::Normal, test: false, k: 0, locomotive: 0 }.rng(1);
    cases.push(("normal, loco-01 of seed 1".to_owned(), draw_fault(&loco, FaultClass::Normal, &mut rng)));
    cases
}

/// Integration steps tried by the study, s (each divides the 10 ms sample period).
pub const STUDY_STEPS_S: [f64; 6] = [50e-6, 100e-6, 200e-6, 250e-6, 500e-6, 1e-3];

/// Result of [`step_study`], one entry per step of [`STUDY_STEPS_S`].
#[derive(Debug, Clone, PartialEq)]
pub struct StepStudy {
    /// Per case: NMSE (%) against the 20 µs reference (NaN when the pressure never exceeds
    /// the 0.2 bar g NMSE threshold).
    pub nmse: Vec<(String, Vec<f64>)>,
    /// Mean single-thread time per 60 s trace, s.
    pub seconds_per_trace: Vec<f64>,
    /// Worst absolute pressure difference over all cases and samples, bar.
    pub max_abs_err_bar: Vec<f64>,
}

/// Simulates the extreme parameters of every class at each of [`STUDY_STEPS_S`] and compares
/// with the 20 µs reference.
pub fn step_study() -> Result<StepStudy> {
    let mut rows = Vec::new();
    let mut seconds = vec![0.0; STUDY_STEPS_S.len()];
    let mut max_err = vec![0.0f64; STUDY_STEPS_S.len()];
    let cases = step_study_cases();
    for (name, params) in &cases {
        let (fine, _) = simulate_plant(params, REFERENCE_STEP_S, crate::generate::TRACE_SAMPLES)?;
        let mut nmse = Vec::new();
        for (i, &h) in STUDY_STEPS_S.iter().enumerate() {
            let start = Instant::now();
            let (coarse, _) = simulate_plant(params, h, crate::generate::TRACE_SAMPLES)?;
            seconds[i] += start.elapsed().as_secs_f64();
            nmse.push(pbm::metrics::nmse_pct(&fine, &coarse).unwrap_or(f64::NAN));
            max_err[i] = fine.iter().zip(&coarse).fold(max_err[i], |m, (a, b)| m.max((a - b).abs()));
        }
        rows.push((name.clone(), nmse));
    }
    for s in &mut seconds {
        *s /= cases.len() as f64;
    }
    Ok(StepStudy { nmse: rows, seconds_per_trace: seconds, max_abs_err_bar: max_err })
}

/// Runs the throughput figures (stdout) and writes the Markdown report.
pub fn run(a: &BenchOptions) -> Result<()> {
    let mut md = String::new();
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("model name")).map(|l| l.split(':').nth(1).unwrap_or("").trim().to_owned())
        })
        .unwrap_or_else(|| "unknown CPU".to_owned());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let _ = writeln!(md, "# host-sim bench\n");
    let _ = writeln!(
        md,
        "Command: `cargo run --release -p host-sim -- bench` (release profile). Machine: {cpu}, {cores} cores"
    );
    let _ = writeln!(
        md,
        "(shared with other jobs: wall-clock rates include time lost to them; per-CPU-second rates do not).\n"
    );
    println!("machine: {cpu}, {cores} cores");

    let twin = twin_throughput(a.twin_samples)?;
    let line = format!("twin alone (pbm::Twin::update), 1 thread: {twin} (target >= 10 M)");
    println!("{line}");
    let _ = writeln!(md, "- {line}");
    let pipe = pipeline_throughput(a.pipeline_samples)?;
    let line = format!("monitor and release features (Monitor::update + ReleaseFeatures::update), 1 thread: {pipe}");
    println!("{line}");
    let _ = writeln!(md, "- {line}");

    if !a.skip_generate {
        let scratch = a.scratch.clone().unwrap_or_else(|| std::env::temp_dir().join("host-sim-bench-generate"));
        let args = GenerateOptions {
            per_class: a.per_class,
            test_per_class: a.test_per_class,
            force: true,
            ..GenerateOptions::new(scratch.clone())
        };
        let cpu0 = process_cpu_seconds();
        let s = generate(&args, true)?;
        let cpu = process_cpu_seconds().zip(cpu0).map(|(b, a)| b - a);
        let _ = std::fs::remove_dir_all(&scratch);
        let line = format!(
            "generate {} traces x 6000 samples (step {} ms), {} threads: {:.2} s wall ({:.0} traces/s, {:.1} MB written)",
            s.traces,
            GENERATE_STEP_S * 1e3,
            s.threads,
            s.elapsed.as_secs_f64(),
            s.traces as f64 / s.elapsed.as_secs_f64(),
            s.bytes as f64 / 1e6
        );
        println!("{line}");
        let _ = writeln!(md, "- {line}");
        if let Some(cpu) = cpu {
            let line = format!(
                "generate CPU time: {cpu:.1} s ({:.2} ms per trace; ≈ {:.1} s wall on {cores} otherwise idle cores)",
                cpu / s.traces as f64 * 1e3,
                cpu / cores as f64
            );
            println!("{line}");
            let _ = writeln!(md, "- {line}");
        }
    }

    if !a.skip_step_study {
        let StepStudy { nmse: rows, seconds_per_trace: seconds, max_abs_err_bar } = step_study()?;
        let _ = writeln!(md, "\n## Integration step of the generator's f64 plant\n");
        let _ = writeln!(md, "NMSE (%, SPEC §6 Eq. 16) of the 100 Hz pressure against the 20 µs reference step:\n");
        let head: Vec<String> = STUDY_STEPS_S.iter().map(|h| format!("{} µs", h * 1e6)).collect();
        let _ = writeln!(md, "| case | {} |", head.join(" | "));
        let _ = writeln!(md, "|---|{}", "---|".repeat(head.len()));
        println!("step study: NMSE % vs 20 us reference");
        println!("{:<30} {}", "case", head.iter().map(|h| format!("{h:>10}")).collect::<String>());
        let mut worst = vec![0.0f64; STUDY_STEPS_S.len()];
        for (name, nmse) in &rows {
            for (w, v) in worst.iter_mut().zip(nmse) {
                *w = w.max(*v);
            }
            let cells: Vec<String> = nmse.iter().map(|v| format!("{v:.5}")).collect();
            println!("{name:<30} {}", cells.iter().map(|c| format!("{c:>10}")).collect::<String>());
            let _ = writeln!(md, "| {name} | {} |", cells.join(" | "));
        }
        let cells: Vec<String> = worst.iter().map(|v| format!("{v:.5}")).collect();
        println!("{:<30} {}", "worst", cells.iter().map(|c| format!("{c:>10}")).collect::<String>());
        let _ = writeln!(md, "| **worst** | {} |", cells.join(" | "));
        let cells: Vec<String> = max_abs_err_bar.iter().map(|v| format!("{v:.5}")).collect();
        println!("{:<30} {}", "max |dp| bar, all cases", cells.iter().map(|c| format!("{c:>10}")).collect::<String>());
        let _ = writeln!(md, "| max abs. difference, bar (all cases) | {} |", cells.join(" | "));
        let cells: Vec<String> = seconds.iter().map(|s| format!("{:.1} ms", s * 1e3)).collect();
        println!("{:<30} {}", "time per 60 s trace", cells.iter().map(|c| format!("{c:>10}")).collect::<String>());
        let _ = writeln!(md, "| time per 60 s trace (1 thread) | {} |", cells.join(" | "));
        let _ = writeln!(md, "\nThe generator uses {} µs (`GENERATE_STEP_S`).", GENERATE_STEP_S * 1e6);
    }

    if let Some(dir) = a.report.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    std::fs::write(&a.report, md).with_context(|| format!("cannot write {}", a.report.display()))?;
    println!("report written to {}", a.report.display());
    Ok(())
}
