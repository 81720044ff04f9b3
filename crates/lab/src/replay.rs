//! `host-sim replay PATH`: feeds recorded traces, one sample at a time, through the very same
//! per-sample pipeline the firmware runs ([`pbm::monitor::Monitor::update`], ADC counts in).
//!
//! PATH is a trace file or a data set directory (with `manifest.csv`). Every sample is taken as
//! part of one release (`valve_open = true`), starting at the release command as SPEC §5 says
//! a trace does. `p_bar` traces are first turned into ADC counts with the sensor map
//! ([`adc_from_bar`], no noise added). Traces must be sampled at 100 Hz (±1 ms per interval):
//! the monitor's clock is the sample count.
//!
//! Outputs: a summary table on stdout (per trace: label, samples, NMSE of the twin against the
//! measurement per [`nmse_pct`], max |residual|, sensor-fault samples, final estimates);
//! with `--out DIR` one results CSV per trace (columns [`RESULT_HEADER`]) plus `summary.csv`;
//! with `--plot DIR` one SVG per trace. A trace that cannot be read is reported (file and
//! line) and the others are still replayed; the command then exits with an error.

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use pbm::metrics::nmse_pct;
use pbm::monitor::MonitorStep;
use pbm::pipeline::Pipeline;
use pbm::report::FaultReport;
use pbm::sensor::adc_from_bar;
use pbm::twin::SAMPLE_PERIOD_S;
use pbm::{AdcCounts, BarG, PressureQ24, TwinParams};
use pbm_io::dataset::{read_manifest, trace_path, MANIFEST};
use pbm_io::trace::{read_trace, Samples, Trace};
use pbm_report::plot::{write_replay_svg, ReplayPlot};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options of `host-sim replay`.
#[derive(Debug, Clone, clap::Args)]
pub struct ReplayArgs {
    /// A trace file, or a data set directory containing manifest.csv.
    pub path: PathBuf,
    /// Write one results CSV per trace (and summary.csv) into this directory.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write one SVG plot per trace (measured vs twin pressure, residual) into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the CAN frames the monitor sends as a candump log (wired by `pbm_io::can_log`).
    #[arg(long)]
    pub can_log: Option<PathBuf>,
    /// Only replay data set traces of this split (`train` or `test`).
    #[arg(long)]
    pub split: Option<String>,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// Header of the per-trace results CSV.
pub const RESULT_HEADER: &str = "t_s,adc,measured_bar,twin_bar,residual_bar,twin_travel_mm,sensor_fault,\
est_phase,est_orifice_mm,est_leak_mm,est_supply_bar_g,est_plateau_bar_g";

/// Tolerance on the 10 ms sample interval, s.
pub const PERIOD_TOLERANCE_S: f64 = 1e-3;

/// One replayed sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplaySample {
    /// Time from the trace, s.
    pub t_s: f64,
    /// ADC counts fed to the monitor.
    pub adc: u16,
    /// What the monitor returned.
    pub step: MonitorStep,
}

impl ReplaySample {
    /// Measured gauge pressure, bar (NaN on a sensor fault).
    pub fn measured_bar(&self) -> f64 {
        self.step.measured.map_or(f64::NAN, |p| p.to_bar_g().0)
    }
    /// Twin gauge pressure, bar.
    pub fn twin_bar(&self) -> f64 {
        self.step.twin.pressure.to_bar_g().0
    }
    /// Measured − twin, bar (NaN on a sensor fault).
    pub fn residual_bar(&self) -> f64 {
        if self.step.measured.is_ok() {
            f64::from(self.step.residual_q24) / f64::from(PressureQ24::ONE_BAR)
        } else {
            f64::NAN
        }
    }
}

/// Per-trace summary.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceSummary {
    /// Trace file as named in the manifest (or the path given).
    pub file: String,
    /// Label from the manifest or the trace metadata (`-` if none).
    pub label: String,
    /// Locomotive from the manifest or the trace metadata (`-` if none).
    pub locomotive: String,
    /// Samples replayed.
    pub samples: usize,
    /// NMSE (%) of the twin against the valid measured samples, SPEC §6.
    pub nmse_pct: Option<f64>,
    /// Largest |measured − twin| over valid samples, bar.
    pub max_abs_residual_bar: f64,
    /// Samples that were a sensor fault.
    pub sensor_faults: usize,
    /// Mean measured pressure over the last second of valid samples, bar g.
    pub final_bar: Option<f64>,
    /// The last step of the monitor.
    pub last: Option<MonitorStep>,
    /// The diagnosis the monitor closed for the release (`None` if it closed none).
    pub diagnosis: Option<FaultReport>,
}

/// Replays one parsed trace through a fresh monitor of the nominal brake.
pub fn replay_trace(trace: &Trace) -> Result<Vec<ReplaySample>> {
    Ok(replay_trace_with_diagnosis(trace)?.0)
}

/// Replays one parsed trace through the firmware's per-sample path ([`Pipeline::step`]: monitor,
/// diagnosis policy, CAN schedule) of the nominal brake, and returns every sample with the
/// diagnosis the controller closes for the release. A recorded trace is one release: the valve
/// command is on from its first sample; the diagnosis closes at the 60 s timeout or, for a
/// shorter trace, at its end ([`Pipeline::close`]).
pub fn replay_trace_with_diagnosis(trace: &Trace) -> Result<(Vec<ReplaySample>, Option<FaultReport>)> {
    trace.check_sample_period(SAMPLE_PERIOD_S, PERIOD_TOLERANCE_S)?;
    let mut pipeline = Pipeline::new(&TwinParams::nominal()).map_err(|e| anyhow::anyhow!("nominal twin: {e}"))?;
    let adc: Vec<u16> = match &trace.samples {
        Samples::Adc(v) => v.clone(),
        Samples::Bar(v) => v.iter().map(|&p| adc_from_bar(BarG(p)).0).collect(),
    };
    let mut report = None;
    let samples = trace
        .t_s
        .iter()
        .zip(adc)
        .map(|(&t_s, adc)| {
            let step = pipeline.step(AdcCounts(adc), true);
            report = step.closed.or(report);
            ReplaySample { t_s, adc, step: step.monitor }
        })
        .collect();
    if let Some((closed, _)) = pipeline.close() {
        report = Some(closed);
    }
    Ok((samples, report))
}

/// Summarises a replay.
pub fn summarise(file: &str, label: &str, locomotive: &str, samples: &[ReplaySample]) -> TraceSummary {
    let valid: Vec<&ReplaySample> = samples.iter().filter(|s| s.step.measured.is_ok()).collect();
    let measured: Vec<f64> = valid.iter().map(|s| s.measured_bar()).collect();
    let twin: Vec<f64> = valid.iter().map(|s| s.twin_bar()).collect();
    let tail = &measured[measured.len().saturating_sub(100)..];
    TraceSummary {
        file: file.to_owned(),
        label: label.to_owned(),
        locomotive: locomotive.to_owned(),
        samples: samples.len(),
        nmse_pct: nmse_pct(&measured, &twin),
        max_abs_residual_bar: valid.iter().map(|s| s.residual_bar().abs()).fold(0.0, f64::max),
        sensor_faults: samples.len() - valid.len(),
        final_bar: (!tail.is_empty()).then(|| tail.iter().sum::<f64>() / tail.len() as f64),
        last: samples.last().map(|s| s.step),
        diagnosis: None,
    }
}

fn opt(v: Option<f32>, decimals: usize) -> String {
    v.map_or_else(String::new, |x| format!("{x:.decimals$}"))
}

/// Writes the per-trace results CSV.
pub fn write_results(w: &mut impl std::io::Write, samples: &[ReplaySample]) -> std::io::Result<()> {
    let mut out = String::with_capacity(samples.len() * 96 + 256);
    out.push_str(RESULT_HEADER);
    out.push('\n');
    for s in samples {
        let fault = match s.step.measured {
            Ok(_) => "",
            Err(f) => f.label(),
        };
        let (measured, residual) = if s.step.measured.is_ok() {
            (format!("{:.5}", s.measured_bar()), format!("{:.5}", s.residual_bar()))
        } else {
            (String::new(), String::new())
        };
        let e = &s.step.estimates;
        let _ = writeln!(
            out,
            "{:.2},{},{measured},{:.5},{residual},{:.3},{fault},{:?},{},{},{},{}",
            s.t_s,
            s.adc,
            s.twin_bar(),
            s.step.twin.travel().mm(),
            e.phase,
            opt(e.orifice_mm, 4),
            opt(e.leak_mm, 4),
            opt(e.supply_bar_g, 4),
            opt(e.plateau_bar_g, 4),
        );
    }
    w.write_all(out.as_bytes())
}

/// One trace to replay: where it is, how to name its outputs, what the manifest says.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayItem {
    /// Path of the trace file.
    pub path: PathBuf,
    /// Name used in the summary and for output files (relative path in a data set).
    pub name: String,
    /// Label from the manifest, if any.
    pub label: Option<String>,
    /// Locomotive from the manifest, if any.
    pub locomotive: Option<String>,
}

/// The traces under PATH (a trace file or a data set directory).
pub fn items(path: &Path, split: Option<&str>) -> Result<Vec<ReplayItem>> {
    if path.is_dir() {
        if !path.join(MANIFEST).is_file() {
            bail!("{} is a directory without {MANIFEST}", path.display());
        }
        let rows = read_manifest(path)?;
        Ok(rows
            .into_iter()
            .filter(|r| split.is_none_or(|s| r.split == s))
            .map(|r| ReplayItem {
                path: trace_path(path, &r),
                name: r.file,
                label: Some(r.label),
                locomotive: Some(r.locomotive),
            })
            .collect())
    } else {
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        Ok(vec![ReplayItem { path: path.to_owned(), name, label: None, locomotive: None }])
    }
}

/// Replays one item and writes its outputs; the error names the file (and line).
pub fn replay_item(item: &ReplayItem, out: Option<&Path>, plot: Option<&Path>) -> Result<TraceSummary> {
    let trace = read_trace(&item.path)?;
    let (samples, diagnosis) = replay_trace_with_diagnosis(&trace)?;
    let label = item.label.as_deref().or(trace.meta("label")).unwrap_or("-");
    let locomotive = item.locomotive.as_deref().or(trace.meta("locomotive")).unwrap_or("-");
    let summary = TraceSummary { diagnosis, ..summarise(&item.name, label, locomotive, &samples) };
    if let Some(dir) = out {
        let path = output_path(dir, &item.name, "csv");
        create_parent(&path)?;
        let mut buf = Vec::new();
        write_results(&mut buf, &samples)?;
        std::fs::write(&path, buf).with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(dir) = plot {
        let path = output_path(dir, &item.name, "svg");
        create_parent(&path)?;
        let t: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
        let m: Vec<f64> = samples.iter().map(ReplaySample::measured_bar).collect();
        let tw: Vec<f64> = samples.iter().map(ReplaySample::twin_bar).collect();
        let r: Vec<f64> = samples.iter().map(ReplaySample::residual_bar).collect();
        let nmse = summary.nmse_pct.map_or_else(|| "n/a".to_owned(), |v| format!("{v:.2} %"));
        let title = format!("{} ({label}, {locomotive}), NMSE {nmse}", item.name);
        write_replay_svg(
            &path,
            &ReplayPlot { title: &title, t_s: &t, measured_bar: &m, twin_bar: &tw, residual_bar: &r },
        )?;
    }
    Ok(summary)
}

/// `DIR/name` with its extension replaced by `ext`.
fn output_path(dir: &Path, name: &str, ext: &str) -> PathBuf {
    dir.join(name).with_extension(ext)
}

fn create_parent(path: &Path) -> Result<()> {
    if let Some(p) = path.parent() {
        std::fs::create_dir_all(p).with_context(|| format!("cannot create {}", p.display()))?;
    }
    Ok(())
}

/// Header of the summary table and `summary.csv`.
pub const SUMMARY_HEADER: &str =
    "file,label,locomotive,samples,nmse_pct,max_abs_residual_bar,sensor_faults,final_bar,est_orifice_mm,est_leak_mm,\
est_supply_bar_g,diagnosis,error";

fn summary_csv_row(s: &TraceSummary) -> String {
    let e = s.last.map(|l| l.estimates);
    format!(
        "{},{},{},{},{},{:.4},{},{},{},{},{},{},",
        s.file,
        s.label,
        s.locomotive,
        s.samples,
        s.nmse_pct.map_or_else(String::new, |v| format!("{v:.3}")),
        s.max_abs_residual_bar,
        s.sensor_faults,
        s.final_bar.map_or_else(String::new, |v| format!("{v:.3}")),
        opt(e.and_then(|e| e.orifice_mm), 3),
        opt(e.and_then(|e| e.leak_mm), 3),
        opt(e.and_then(|e| e.supply_bar_g), 3),
        diagnosis(s),
    )
}

/// The monitor's diagnosis of a trace as a display shows it (`-` if none was closed).
fn diagnosis(s: &TraceSummary) -> String {
    s.diagnosis.map_or_else(|| "-".to_owned(), |r| r.verdict.to_string())
}

/// Prints the summary table.
pub fn print_table(results: &[(ReplayItem, Result<TraceSummary, String>)]) {
    let width = results.iter().map(|(i, _)| i.name.len()).max().unwrap_or(4).max(4);
    println!(
        "{:<width$}  {:<15} {:<10} {:>7} {:>8} {:>9} {:>6} {:>7} {:>7} {:>6} {:>6}  diagnosis",
        "file", "label", "loco", "samples", "NMSE %", "max|r| b", "sfault", "final", "orif", "leak", "supply"
    );
    for (item, r) in results {
        match r {
            Ok(s) => {
                let e = s.last.map(|l| l.estimates);
                println!(
                    "{:<width$}  {:<15} {:<10} {:>7} {:>8} {:>9.3} {:>6} {:>7} {:>7} {:>6} {:>6}  {}",
                    s.file,
                    s.label,
                    s.locomotive,
                    s.samples,
                    s.nmse_pct.map_or_else(|| "n/a".to_owned(), |v| format!("{v:.2}")),
                    s.max_abs_residual_bar,
                    s.sensor_faults,
                    s.final_bar.map_or_else(|| "n/a".to_owned(), |v| format!("{v:.3}")),
                    opt(e.and_then(|e| e.orifice_mm), 2),
                    opt(e.and_then(|e| e.leak_mm), 2),
                    opt(e.and_then(|e| e.supply_bar_g), 2),
                    diagnosis(s)
                );
            }
            Err(e) => println!("{:<width$}  ERROR: {e}", item.name),
        }
    }
}

/// Replays every item in parallel (results in input order); bad files are `Err` entries.
pub fn replay_all(
    items: Vec<ReplayItem>,
    out: Option<&Path>,
    plot: Option<&Path>,
    threads: usize,
    progress: bool,
) -> Result<Vec<(ReplayItem, Result<TraceSummary, String>)>> {
    let bar = if progress { ProgressBar::new(items.len() as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("replay [{bar:40}] {pos}/{len} traces {elapsed_precise} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("cannot start worker threads")?;
    let results = pool.install(|| {
        items
            .into_par_iter()
            .map(|item| {
                let r = replay_item(&item, out, plot).map_err(|e| format!("{e:#}"));
                bar.inc(1);
                (item, r)
            })
            .collect()
    });
    bar.finish_and_clear();
    Ok(results)
}

/// `host-sim replay`.
pub fn run(a: &ReplayArgs) -> Result<()> {
    let items = items(&a.path, a.split.as_deref())?;
    if items.is_empty() {
        bail!("no traces to replay in {}", a.path.display());
    }
    if let Some(path) = &a.can_log {
        // One CAN stream for all traces, in order, through the firmware's per-sample pipeline.
        let frames = write_replay_can_log(path, &items)?;
        eprintln!("wrote {frames} CAN frames to {}", path.display());
    }
    let progress = items.len() > 1;
    let results = replay_all(items, a.out.as_deref(), a.plot.as_deref(), a.threads, progress)?;
    print_table(&results);
    if let Some(dir) = &a.out {
        let mut csv = String::from(SUMMARY_HEADER);
        csv.push('\n');
        for (item, r) in &results {
            match r {
                Ok(s) => csv.push_str(&summary_csv_row(s)),
                Err(e) => {
                    let _ = write!(csv, "{},,,,,,,,,,,,\"{}\"", item.name, e.replace('"', "'"));
                }
            }
            csv.push('\n');
        }
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let p = dir.join("summary.csv");
        std::fs::write(&p, csv).with_context(|| format!("cannot write {}", p.display()))?;
    }
    let failed: Vec<&String> = results.iter().filter_map(|(_, r)| r.as_ref().err()).collect();
    for e in &failed {
        eprintln!("error: {e}");
    }
    if !failed.is_empty() {
        bail!("{} of {} traces could not be replayed (the others were)", failed.len(), results.len());
    }
    Ok(())
}

/// Gap between two traces in a replay log, µs.
pub const TRACE_GAP_US: u64 = 10_000_000;

/// `host-sim replay --can-log FILE`: replays each item's trace (every sample a release
/// sample, as `replay` does) through a fresh [`pbm::pipeline::Pipeline`], the per-sample path
/// the firmware runs (monitor, diagnosis policy, transmit schedule), and writes its frames to a
/// candump log; the end of each trace closes its diagnosis ([`pbm::pipeline::Pipeline::close`]).
/// Time stamps are the monitor's sample clock (sample `i` at `i` × 10 ms), as in the firmware;
/// trace `k` starts [`TRACE_GAP_US`] after the last sample of trace `k − 1`. For one trace the
/// log is byte for byte what the firmware writes in QEMU. Returns the number of frames written.
pub fn write_replay_can_log(path: &std::path::Path, items: &[ReplayItem]) -> anyhow::Result<u64> {
    use anyhow::Context as _;
    let file = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut sink = pbm_io::can_log::CandumpWriter::new(std::io::BufWriter::new(file), pbm_io::can_log::DEFAULT_IFACE);
    let mut base_us = 0u64;
    for item in items {
        let trace = pbm_io::trace::read_trace(&item.path)?;
        trace.check_sample_period(pbm::twin::SAMPLE_PERIOD_S, PERIOD_TOLERANCE_S)?;
        let adc: Vec<u16> = match &trace.samples {
            pbm_io::trace::Samples::Adc(v) => v.clone(),
            pbm_io::trace::Samples::Bar(v) => v.iter().map(|&p| pbm::sensor::adc_from_bar(pbm::BarG(p)).0).collect(),
        };
        let mut pipeline = pbm::pipeline::Pipeline::nominal().map_err(|e| anyhow::anyhow!("nominal twin: {e}"))?;
        let mut last_us = base_us;
        let write_err = || format!("cannot write {}", path.display());
        for (i, &code) in adc.iter().enumerate() {
            let index = u32::try_from(i).context("trace longer than 2^32 samples")?;
            last_us = pbm::pipeline::candump::sample_time_us(base_us, index);
            for f in pipeline.step(pbm::AdcCounts(code), true).frames.as_slice() {
                pbm_io::can_bus::FrameSink::send(&mut sink, last_us, f).with_context(write_err)?;
            }
        }
        if let Some((_, frames)) = pipeline.close() {
            for f in frames.as_slice() {
                pbm_io::can_bus::FrameSink::send(&mut sink, last_us, f).with_context(write_err)?;
            }
        }
        base_us = last_us + TRACE_GAP_US;
    }
    let frames = sink.frames();
    sink.finish().with_context(|| format!("cannot write {}", path.display()))?;
    Ok(frames)
}
