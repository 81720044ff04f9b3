//! Replay: recorded traces fed, one sample at a time, through the very same per-sample path the
//! firmware runs ([`Pipeline::step`]: monitor, diagnosis policy, CAN schedule; ADC counts in).
//!
//! The input is a trace file, a data set directory (with `manifest.csv`) or a fleet archive
//! ([`pbm_io::archive`]; its releases in the archive's order, as the data set with its manifest
//! in (locomotive, release) order would replay them: the same table, outputs and CAN log). Every sample is
//! taken as part of one release (`valve_open = true`), starting at the release command as SPEC
//! §5 says a trace does. `p_bar` traces are first turned into ADC counts with the sensor map
//! ([`adc_from_bar`], no noise added). Traces must be sampled at 100 Hz (±1 ms per interval):
//! the monitor's clock is the sample count.
//!
//! A trace is streamed: memory does not grow with its length unless a plot of it is asked for.
//! Outputs: a summary table (per trace: label, samples, NMSE of the twin against the
//! measurement per [`nmse_pct`](pbm::metrics::nmse_pct), max |residual|, sensor-fault samples,
//! final estimates, the diagnosis); optionally one results CSV per trace (columns
//! [`RESULT_COLUMNS`]) plus `summary.csv`, one SVG per trace, and the CAN frames of every trace
//! as one candump log. A trace that cannot be read is reported with its file and line and
//! skipped (its partial outputs removed); every other trace is replayed and every output
//! written, and the run's [`Skipped`] says what was left out.

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use pbm::can::{CanFrame, PowerUp};
use pbm::metrics::Nmse;
use pbm::monitor::MonitorStep;
use pbm::pipeline::Pipeline;
use pbm::report::{FaultReport, Verdict};
use pbm::sensor::adc_from_bar;
use pbm::twin::SAMPLE_PERIOD_S;
use pbm::{AdcCounts, BarG, PressureQ24};
use pbm_io::archive::results::{verdict_label, write_results, ResultRow};
use pbm_io::archive::{is_archive, ArchiveReader, ArchivedRelease};
use pbm_io::can_bus::FrameSink;
use pbm_io::can_log::{CandumpWriter, DEFAULT_IFACE};
use pbm_io::dataset::{select, Selection, TraceItem};
use pbm_io::error::{FileError, Skipped};
use pbm_io::table::CsvFile;
use pbm_io::trace::{Samples, Trace, TraceErrorKind, TraceReader, Value};
use pbm_report::plot::{write_replay_svg, ReplayPlot};
use rayon::prelude::*;
use std::collections::VecDeque;
use std::io::BufRead;
use std::path::{Path, PathBuf};

/// Options of a replay.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayOptions {
    /// Write one results CSV per trace (and `summary.csv`) into this directory.
    pub out: Option<PathBuf>,
    /// Write one SVG plot per trace (measured vs twin pressure, residual) into this directory.
    pub plot: Option<PathBuf>,
    /// Write the CAN frames the monitor sends as one candump log.
    pub can_log: Option<PathBuf>,
    /// Only replay data set traces of this split (`train` or `test`).
    pub split: Option<String>,
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Show a progress bar (stderr) when there is more than one trace.
    pub progress: bool,
    /// Write one row per release (the table's fields) to this Parquet file
    /// ([`pbm_io::archive::results`]).
    pub results_parquet: Option<PathBuf>,
}

/// Columns of the per-trace results CSV.
pub const RESULT_COLUMNS: [&str; 12] = [
    "t_s",
    "adc",
    "measured_bar",
    "twin_bar",
    "residual_bar",
    "twin_travel_mm",
    "sensor_fault",
    "est_phase",
    "est_orifice_mm",
    "est_leak_mm",
    "est_supply_bar_g",
    "est_plateau_bar_g",
];

/// Columns of `summary.csv`.
pub const SUMMARY_COLUMNS: [&str; 13] = [
    "file",
    "label",
    "locomotive",
    "samples",
    "nmse_pct",
    "max_abs_residual_bar",
    "sensor_faults",
    "final_bar",
    "est_orifice_mm",
    "est_leak_mm",
    "est_supply_bar_g",
    "diagnosis",
    "error",
];

/// Tolerance on the 10 ms sample interval, s.
pub use pbm_io::trace::PERIOD_TOLERANCE_S;

/// Gap between two traces in a replay's CAN log, µs.
pub const TRACE_GAP_US: u64 = 10_000_000;

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

/// Builds a [`TraceSummary`] one sample at a time (constant memory).
#[derive(Debug, Clone, Default)]
pub struct Summariser {
    samples: usize,
    valid: usize,
    nmse: Nmse,
    max_abs_residual_bar: f64,
    /// The last second of valid measured pressures.
    tail: VecDeque<f64>,
    last: Option<MonitorStep>,
}

/// Valid samples averaged for [`TraceSummary::final_bar`] (1 s at 100 Hz).
const FINAL_SAMPLES: usize = 100;

impl Summariser {
    /// Adds one replayed sample.
    pub fn push(&mut self, s: &ReplaySample) {
        self.samples += 1;
        self.last = Some(s.step);
        if s.step.measured.is_ok() {
            self.valid += 1;
            let measured = s.measured_bar();
            self.nmse.push(measured, s.twin_bar());
            self.max_abs_residual_bar = self.max_abs_residual_bar.max(s.residual_bar().abs());
            if self.tail.len() == FINAL_SAMPLES {
                self.tail.pop_front();
            }
            self.tail.push_back(measured);
        }
    }

    /// The summary of the samples pushed.
    pub fn finish(self, file: &str, label: &str, locomotive: &str, diagnosis: Option<FaultReport>) -> TraceSummary {
        TraceSummary {
            file: file.to_owned(),
            label: label.to_owned(),
            locomotive: locomotive.to_owned(),
            samples: self.samples,
            nmse_pct: self.nmse.pct(),
            max_abs_residual_bar: self.max_abs_residual_bar,
            sensor_faults: self.samples - self.valid,
            final_bar: (!self.tail.is_empty()).then(|| self.tail.iter().sum::<f64>() / self.tail.len() as f64),
            last: self.last,
            diagnosis,
        }
    }
}

/// Summarises a replay held in memory.
pub fn summarise(file: &str, label: &str, locomotive: &str, samples: &[ReplaySample]) -> TraceSummary {
    let mut s = Summariser::default();
    samples.iter().for_each(|x| s.push(x));
    s.finish(file, label, locomotive, None)
}

/// A frame the pipeline sent, with its time since the release command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TimedFrame {
    /// The monitor's sample clock: sample `i` at `i` × 10 ms, µs.
    pub time_us: u64,
    /// The frame.
    pub frame: CanFrame,
}

/// What replaying one release gave besides its samples.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Replayed {
    /// The diagnosis the controller closed (at the 60 s timeout, or at the trace's end).
    pub diagnosis: Option<FaultReport>,
    /// The frames sent, when they were kept.
    pub frames: Vec<TimedFrame>,
    /// Time of the last sample, µs on the sample clock.
    pub last_time_us: u64,
}

/// Why a replay stopped.
#[derive(Debug)]
pub enum ReplayError {
    /// The input is bad (file and line): skip it.
    Input(FileError),
    /// An output could not be written: the run fails.
    Output(anyhow::Error),
}

impl From<FileError> for ReplayError {
    fn from(e: FileError) -> Self {
        Self::Input(e)
    }
}

/// Feeds `(t_s, adc)` samples through a fresh pipeline of the nominal brake, calling
/// `on_sample` for each: the one replay loop of the host. A recorded trace is one release: the
/// valve command is on from its first sample; the diagnosis closes at the 60 s timeout or, for a
/// shorter trace, at its end ([`Pipeline::close`]). Frames are kept when `keep_frames`.
pub fn replay_samples(
    samples: impl Iterator<Item = Result<(f64, u16), FileError>>,
    keep_frames: bool,
    power_up: PowerUp,
    mut on_sample: impl FnMut(&ReplaySample) -> Result<()>,
) -> Result<Replayed, ReplayError> {
    let mut pipeline = Pipeline::nominal().map_err(|e| ReplayError::Output(anyhow::anyhow!("nominal twin: {e}")))?;
    pipeline.set_identity(power_up);
    let mut out = Replayed::default();
    let mut keep = |time_us: u64, frames: &[CanFrame]| {
        if keep_frames {
            out.frames.extend(frames.iter().map(|&frame| TimedFrame { time_us, frame }));
        }
    };
    let mut diagnosis = None;
    let mut last_time_us = 0;
    for (index, sample) in samples.enumerate() {
        let (t_s, adc) = sample?;
        let index =
            u32::try_from(index).map_err(|_| ReplayError::Output(anyhow::anyhow!("trace longer than 2^32 samples")))?;
        last_time_us = pbm::can::candump::sample_time_us(0, index);
        let step = pipeline.step(AdcCounts(adc), true);
        diagnosis = step.closed.or(diagnosis);
        keep(last_time_us, step.frames.as_slice());
        on_sample(&ReplaySample { t_s, adc, step: step.monitor }).map_err(ReplayError::Output)?;
    }
    if let Some((closed, frames)) = pipeline.close() {
        diagnosis = Some(closed);
        keep(last_time_us, frames.as_slice());
    }
    out.diagnosis = diagnosis;
    out.last_time_us = last_time_us;
    Ok(out)
}

/// ADC counts of a sample value (pressures through the sensor map, no noise).
fn adc_of(value: Value) -> u16 {
    match value {
        Value::Adc(c) => c,
        Value::Bar(p) => adc_from_bar(BarG(p)).0,
    }
}

/// The samples of a streamed trace, checked at 100 Hz.
fn stream<R: BufRead>(reader: &mut TraceReader<R>) -> impl Iterator<Item = Result<(f64, u16), FileError>> + '_ {
    reader.expect_period(SAMPLE_PERIOD_S, PERIOD_TOLERANCE_S);
    reader.map(|s| s.map(|s| (s.t_s, adc_of(s.value))).map_err(FileError::from))
}

/// Replays a trace held in memory; returns every sample and the diagnosis closed.
pub fn replay_trace_with_diagnosis(trace: &Trace) -> Result<(Vec<ReplaySample>, Option<FaultReport>)> {
    trace.check_sample_period(SAMPLE_PERIOD_S, PERIOD_TOLERANCE_S)?;
    let adc: Box<dyn Iterator<Item = u16>> = match &trace.samples {
        Samples::Adc(v) => Box::new(v.iter().copied()),
        Samples::Bar(v) => Box::new(v.iter().map(|&p| adc_from_bar(BarG(p)).0)),
    };
    let mut samples = Vec::with_capacity(trace.t_s.len());
    let run = replay_samples(trace.t_s.iter().copied().zip(adc).map(Ok), false, PowerUp::default(), |s| {
        samples.push(*s);
        Ok(())
    });
    match run {
        Ok(r) => Ok((samples, r.diagnosis)),
        Err(ReplayError::Input(e)) => Err(e.into()),
        Err(ReplayError::Output(e)) => Err(e),
    }
}

/// Replays a trace held in memory through a fresh monitor of the nominal brake.
pub fn replay_trace(trace: &Trace) -> Result<Vec<ReplaySample>> {
    Ok(replay_trace_with_diagnosis(trace)?.0)
}

fn opt(v: Option<f32>, decimals: usize) -> String {
    v.map_or_else(String::new, |x| format!("{x:.decimals$}"))
}

/// The fields of one results CSV row.
fn result_fields(s: &ReplaySample) -> [String; 12] {
    let (measured, residual) = if s.step.measured.is_ok() {
        (format!("{:.5}", s.measured_bar()), format!("{:.5}", s.residual_bar()))
    } else {
        (String::new(), String::new())
    };
    let e = &s.step.estimates;
    [
        format!("{:.2}", s.t_s),
        s.adc.to_string(),
        measured,
        format!("{:.5}", s.twin_bar()),
        residual,
        format!("{:.3}", s.step.twin.travel.to_mm()),
        s.step.measured.err().map_or("", |f| f.label()).to_owned(),
        format!("{:?}", e.phase),
        opt(e.orifice_mm, 4),
        opt(e.leak_mm, 4),
        opt(e.supply_bar_g, 4),
        opt(e.plateau_bar_g, 4),
    ]
}

/// The traces under `path` (a trace file or a data set directory, optionally one split), and
/// the manifest rows refused.
pub fn items(path: &Path, split: Option<&str>) -> Result<(Vec<TraceItem>, Skipped)> {
    select(path, &Selection { split: split.map(str::to_owned), per_label: 0 })
}

/// The replay of one item.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceReplay {
    /// Its summary.
    pub summary: TraceSummary,
    /// Frames and closing time (frames only when a CAN log was asked for).
    pub replayed: Replayed,
}

/// The plotted series of a replay (time, measured, twin, residual), thinned so that memory stays
/// bounded however long the trace: every sample up to [`PLOT_POINTS`] points, then every second,
/// fourth, … sample (a plot is a few thousand pixels wide; a 60 s release keeps all 6000).
#[derive(Default)]
struct PlotSeries {
    columns: [Vec<f64>; 4],
    stride: usize,
    seen: usize,
}

/// Most points a replay plot keeps per series before it thins them.
pub const PLOT_POINTS: usize = 16_384;

impl PlotSeries {
    fn push(&mut self, s: &ReplaySample) {
        let stride = self.stride.max(1);
        if self.seen % stride == 0 {
            for (c, v) in self.columns.iter_mut().zip([s.t_s, s.measured_bar(), s.twin_bar(), s.residual_bar()]) {
                c.push(v);
            }
            if self.columns[0].len() >= PLOT_POINTS {
                for c in &mut self.columns {
                    let mut i = 0;
                    c.retain(|_| {
                        i += 1;
                        i % 2 == 1
                    });
                }
                self.stride = stride * 2;
            }
        }
        self.seen += 1;
    }
}

/// `DIR/name` with its extension replaced by `ext`.
fn output_path(dir: &Path, name: &str, ext: &str) -> PathBuf {
    dir.join(name).with_extension(ext)
}

/// The identity a replayed release's CAN frames carry: the fleet number of `locomotive`
/// ([`pbm::can::codec::fleet_number`], whose low 6 bits every frame carries) and the release count of a monitor that has seen
/// `earlier_releases` recorded releases before it (what the firmware sends). An error says why
/// when the locomotive's number does not fit the frames' 12 bits: it is refused, not wrapped
/// onto the locomotive 4096 below it.
pub fn release_identity(locomotive: &str, earlier_releases: u32) -> Result<PowerUp, String> {
    match pbm::can::codec::fleet_number(locomotive) {
        Some(number) => Ok(PowerUp { locomotive: number, release_count: earlier_releases }),
        None => Err(format!(
            "locomotive {:?}: its number is above {}, the largest the CAN frames carry (12 bits); \
             its frames would be those of the locomotive 4096 below it",
            locomotive.trim(),
            pbm::can::codec::MAX_FLEET_NUMBER
        )),
    }
}

/// Replays one item and writes its outputs (results CSV, plot); a bad input removes what was
/// written of them. Its CAN frames carry the locomotive number of the item's locomotive
/// ([`pbm::can::codec::locomotive_number`]) and release number 2 (power-up 1, release command
/// 2), as the firmware's do.
pub fn replay_item(item: &TraceItem, opts: &ReplayOptions) -> Result<TraceReplay, ReplayError> {
    replay_item_after(item, opts, 0)
}

/// [`replay_item`] for a locomotive whose monitor has already seen `earlier_releases` recorded
/// releases (each trace is a power-up and a release command: two release numbers).
pub fn replay_item_after(
    item: &TraceItem,
    opts: &ReplayOptions,
    earlier_releases: u32,
) -> Result<TraceReplay, ReplayError> {
    replay_item_observing(item, opts, earlier_releases, opts.can_log.is_some(), |_| {})
}

/// [`replay_item_after`] that also keeps the frames sent when `keep_frames` (whatever
/// `opts.can_log` says) and shows every replayed sample to `observe` (e.g. to keep a thinned
/// release curve), so a caller that needs them does not replay twice.
pub fn replay_item_observing(
    item: &TraceItem,
    opts: &ReplayOptions,
    earlier_releases: u32,
    keep_frames: bool,
    observe: impl FnMut(&ReplaySample),
) -> Result<TraceReplay, ReplayError> {
    let mut reader = TraceReader::open(&item.path).map_err(FileError::from)?;
    let label = item.label.clone().or_else(|| reader.meta("label").map(str::to_owned)).unwrap_or_else(|| "-".into());
    let locomotive =
        item.locomotive.clone().or_else(|| reader.meta("locomotive").map(str::to_owned)).unwrap_or_else(|| "-".into());
    replay_release(&item.name, &label, &locomotive, stream(&mut reader), opts, earlier_releases, keep_frames, observe)
}

/// Replays one release's `(t_s, adc)` samples under the output name `name` and writes its
/// outputs (results CSV, plot); a bad input removes what was written of them. The one body of
/// [`replay_item_observing`] (a trace file) and of the archive replay (a row group). Keeps the
/// frames sent when `keep_frames` and shows every replayed sample to `observe`.
#[allow(clippy::too_many_arguments)]
fn replay_release(
    name: &str,
    label: &str,
    locomotive: &str,
    samples: impl Iterator<Item = Result<(f64, u16), FileError>>,
    opts: &ReplayOptions,
    earlier_releases: u32,
    keep_frames: bool,
    mut observe: impl FnMut(&ReplaySample),
) -> Result<TraceReplay, ReplayError> {
    let identity = match release_identity(locomotive, earlier_releases) {
        Ok(identity) => identity,
        // Frames that are not kept carry nobody's number: the replay's other outputs stand.
        Err(_) if !keep_frames => PowerUp { locomotive: 0, release_count: earlier_releases },
        Err(why) => return Err(FileError::new(name, 0, why).into()),
    };
    let results_path = opts.out.as_deref().map(|d| output_path(d, name, "csv"));
    let mut results = match &results_path {
        Some(p) => {
            let mut f = CsvFile::create(p).map_err(ReplayError::Output)?;
            f.record(RESULT_COLUMNS).map_err(ReplayError::Output)?;
            Some(f)
        }
        None => None,
    };
    let mut series: Option<PlotSeries> = opts.plot.as_ref().map(|_| PlotSeries::default());
    let mut summariser = Summariser::default();
    let run = replay_samples(samples, keep_frames, identity, |s| {
        observe(s);
        summariser.push(s);
        if let Some(f) = results.as_mut() {
            f.record(result_fields(s))?;
        }
        if let Some(p) = series.as_mut() {
            p.push(s);
        }
        Ok(())
    });
    let replayed = match run {
        Ok(r) => r,
        Err(e) => {
            drop(results);
            if let Some(p) = &results_path {
                let _ = std::fs::remove_file(p);
            }
            return Err(e);
        }
    };
    if let Some(f) = results {
        f.finish().map_err(ReplayError::Output)?;
    }
    let summary = summariser.finish(name, label, locomotive, replayed.diagnosis);
    if let (Some(dir), Some(PlotSeries { columns: [t, m, tw, r], .. })) = (&opts.plot, &series) {
        let path = output_path(dir, name, "svg");
        let nmse = summary.nmse_pct.map_or_else(|| "n/a".to_owned(), |v| format!("{v:.2} %"));
        let title = format!("{name} ({label}, {locomotive}), NMSE {nmse}");
        let plot = ReplayPlot { title: &title, t_s: t, measured_bar: m, twin_bar: tw, residual_bar: r };
        if let Some(p) = path.parent() {
            std::fs::create_dir_all(p)
                .with_context(|| format!("cannot create {}", p.display()))
                .map_err(ReplayError::Output)?;
        }
        write_replay_svg(&path, &plot).map_err(ReplayError::Output)?;
    }
    Ok(TraceReplay { summary, replayed })
}

/// Each locomotive's monitor numbers its releases on: the k-th trace of a locomotive (in the
/// data set's or archive's order) is its release k, so every report in a replay's CAN log
/// belongs to one locomotive and one release.
#[derive(Debug, Default)]
struct ReleaseNumbering(std::collections::HashMap<Option<u16>, u32>);

impl ReleaseNumbering {
    /// The releases the locomotive's monitor has seen before this one.
    fn next(&mut self, locomotive: Option<&str>) -> u32 {
        // A number the frames cannot carry (`None`) is refused when its frames are kept.
        let loco = locomotive.map_or(Some(0), pbm::can::codec::fleet_number);
        let n = self.0.entry(loco).or_insert(0);
        let before = *n;
        *n = n.wrapping_add(1);
        before
    }
}

/// Replays every item in parallel; results in input order, a bad input as its [`FileError`].
/// Fails only when an output cannot be written.
pub fn replay_all(items: &[TraceItem], opts: &ReplayOptions) -> Result<Vec<Result<TraceReplay, FileError>>> {
    let bar =
        if opts.progress && items.len() > 1 { ProgressBar::new(items.len() as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("replay [{bar:40}] {pos}/{len} traces {elapsed_precise} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    // No more threads than traces (0 = one per core).
    let threads = if opts.threads == 0 { 0 } else { opts.threads.min(items.len().max(1)) };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("cannot start worker threads")?;
    let mut numbering = ReleaseNumbering::default();
    let earlier: Vec<u32> = items.iter().map(|item| numbering.next(item.locomotive.as_deref())).collect();
    let results: Vec<Result<Result<TraceReplay, FileError>>> = pool.install(|| {
        items
            .par_iter()
            .zip(earlier.par_iter())
            .map(|(item, &before)| {
                let r = match replay_item_after(item, opts, before) {
                    Ok(r) => Ok(Ok(r)),
                    Err(ReplayError::Input(e)) => Ok(Err(e)),
                    Err(ReplayError::Output(e)) => Err(e),
                };
                bar.inc(1);
                r
            })
            .collect()
    });
    bar.finish_and_clear();
    results.into_iter().collect()
}

/// Writes the frames of the replays that succeeded, in order, as one candump log with absolute
/// time stamps from [`pbm::can::candump::LOG_EPOCH_US`]: trace `k` starts [`TRACE_GAP_US`]
/// after the last sample of trace `k − 1`. For one trace the log is
/// byte for byte what the firmware writes in QEMU. Returns the number of frames.
pub fn write_can_log<'a>(path: &Path, replays: impl IntoIterator<Item = &'a Replayed>) -> Result<u64> {
    let file = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    write_can_log_to(std::io::BufWriter::new(file), replays).with_context(|| format!("cannot write {}", path.display()))
}

/// [`write_can_log`] into any writer (the Python package keeps the log in memory): the one
/// place that lays out a replay's candump log. Returns the number of frames.
pub fn write_can_log_to<'a, W: std::io::Write>(
    out: W,
    replays: impl IntoIterator<Item = &'a Replayed>,
) -> std::io::Result<u64> {
    let mut sink = CandumpWriter::new(out, DEFAULT_IFACE);
    let mut base_us = pbm::can::candump::LOG_EPOCH_US;
    for r in replays {
        for f in &r.frames {
            sink.send(base_us + f.time_us, &f.frame)?;
        }
        base_us += r.last_time_us + TRACE_GAP_US;
    }
    let frames = sink.frames();
    sink.finish()?;
    Ok(frames)
}

/// Replays `items` and writes their frames as one candump log ([`write_can_log`]); the bad
/// inputs are skipped.
pub fn replay_to_can_log(path: &Path, items: &[TraceItem]) -> Result<(u64, Skipped)> {
    let opts = ReplayOptions { can_log: Some(path.to_owned()), ..ReplayOptions::default() };
    let results = replay_all(items, &opts)?;
    let mut skipped = Skipped::none();
    let mut ok = Vec::new();
    for r in results {
        match r {
            Ok(t) => ok.push(t.replayed),
            Err(e) => skipped.push(e),
        }
    }
    Ok((write_can_log(path, &ok)?, skipped))
}

/// The summary fields of one trace (the columns [`SUMMARY_COLUMNS`] but the last).
fn summary_fields(s: &TraceSummary) -> [String; 12] {
    let e = s.last.map(|l| l.estimates);
    [
        s.file.clone(),
        s.label.clone(),
        s.locomotive.clone(),
        s.samples.to_string(),
        s.nmse_pct.map_or_else(String::new, |v| format!("{v:.3}")),
        format!("{:.4}", s.max_abs_residual_bar),
        s.sensor_faults.to_string(),
        s.final_bar.map_or_else(String::new, |v| format!("{v:.3}")),
        opt(e.and_then(|e| e.orifice_mm), 3),
        opt(e.and_then(|e| e.leak_mm), 3),
        opt(e.and_then(|e| e.supply_bar_g), 3),
        diagnosis(s),
    ]
}

/// The monitor's diagnosis of a trace as a display shows it (`-` if none was closed).
fn diagnosis(s: &TraceSummary) -> String {
    s.diagnosis.map_or_else(|| "-".to_owned(), |r| r.verdict.to_string())
}

/// Writes `summary.csv`: one row per trace, a skipped one with its error.
pub fn write_summary_csv(path: &Path, items: &[TraceItem], results: &[Result<TraceReplay, FileError>]) -> Result<()> {
    let mut f = CsvFile::create(path)?;
    f.record(SUMMARY_COLUMNS)?;
    for (item, r) in items.iter().zip(results) {
        match r {
            Ok(t) => {
                let mut fields = summary_fields(&t.summary).to_vec();
                fields.push(String::new());
                f.record(fields)?;
            }
            Err(e) => {
                let mut fields = vec![String::new(); SUMMARY_COLUMNS.len()];
                fields[0] = item.name.clone();
                fields[SUMMARY_COLUMNS.len() - 1] = e.to_string();
                f.record(fields)?;
            }
        }
    }
    f.finish()
}

/// Prints the summary table.
pub fn print_table(items: &[TraceItem], results: &[Result<TraceReplay, FileError>]) {
    let width = items.iter().map(|i| i.name.len()).max().unwrap_or(4).max(4);
    println!(
        "{:<width$}  {:<15} {:<10} {:>7} {:>8} {:>9} {:>6} {:>7} {:>7} {:>6} {:>6}  diagnosis",
        "file", "label", "loco", "samples", "NMSE %", "max|r| b", "sfault", "final", "orif", "leak", "supply"
    );
    for (item, r) in items.iter().zip(results) {
        match r {
            Ok(t) => {
                let s = &t.summary;
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
            Err(e) => println!("{:<width$}  SKIPPED: {e}", item.name),
        }
    }
}

/// Refuses a run whose outputs (results, plots, summary, CAN log) would overwrite one of its
/// inputs (a trace, the manifest, the truth file).
fn guard_inputs(path: &Path, items: &[TraceItem], opts: &ReplayOptions) -> Result<()> {
    let mut outputs: Vec<PathBuf> = Vec::new();
    for item in items {
        outputs.extend(opts.out.as_deref().map(|d| output_path(d, &item.name, "csv")));
        outputs.extend(opts.plot.as_deref().map(|d| output_path(d, &item.name, "svg")));
    }
    outputs.extend(opts.out.as_deref().map(|d| d.join("summary.csv")));
    outputs.extend(opts.can_log.clone());
    outputs.extend(opts.results_parquet.clone());
    let mut inputs: Vec<PathBuf> = items.iter().map(|i| i.path.clone()).collect();
    if path.is_dir() {
        inputs.extend([path.join(pbm_io::dataset::MANIFEST), path.join(pbm_io::dataset::TRUTH)]);
    }
    pbm_io::files::refuse_overwriting_inputs(outputs.iter().map(PathBuf::as_path), inputs.iter().map(PathBuf::as_path))
        .map_err(anyhow::Error::msg)
}

/// The samples of an archived release, checked at 100 Hz; an error names the archive and the
/// release.
fn archive_samples<'a>(
    archive: &'a str,
    r: &'a ArchivedRelease,
) -> impl Iterator<Item = Result<(f64, u16), FileError>> + 'a {
    let mut previous: Option<f64> = None;
    r.t_s.iter().zip(&r.adc).enumerate().map(move |(k, (&t, &c))| {
        if let Some(p) = previous {
            let found_s = t - p;
            if (found_s - SAMPLE_PERIOD_S).abs() > PERIOD_TOLERANCE_S {
                let kind = TraceErrorKind::SamplePeriod { expected_s: SAMPLE_PERIOD_S, found_s };
                return Err(FileError::new(
                    archive,
                    0,
                    format!("release {} of {}: sample {k}: {kind}", r.release, r.locomotive),
                ));
            }
        }
        previous = Some(t);
        Ok((t, c))
    })
}

/// Replays one release read from the archive `archive` (as named in errors), as
/// [`replay_item_after`] replays a trace file: label `-` when the archive has none.
pub fn replay_archived(
    archive: &str,
    r: &ArchivedRelease,
    opts: &ReplayOptions,
    earlier_releases: u32,
) -> Result<TraceReplay, ReplayError> {
    replay_archived_observing(archive, r, opts, earlier_releases, opts.can_log.is_some(), |_| {})
}

/// [`replay_archived`] that also keeps the frames sent when `keep_frames` and shows every
/// replayed sample to `observe` (as [`replay_item_observing`] does for a trace file).
pub fn replay_archived_observing(
    archive: &str,
    r: &ArchivedRelease,
    opts: &ReplayOptions,
    earlier_releases: u32,
    keep_frames: bool,
    observe: impl FnMut(&ReplaySample),
) -> Result<TraceReplay, ReplayError> {
    let label = r.label.as_deref().unwrap_or("-");
    replay_release(
        &r.release,
        label,
        &r.locomotive,
        archive_samples(archive, r),
        opts,
        earlier_releases,
        keep_frames,
        observe,
    )
}

/// Releases of an archive read (and then replayed) together: enough to keep the cores busy,
/// few enough that memory stays a few releases whatever the archive's size.
pub const ARCHIVE_CHUNK: usize = 32;

/// The replays of a run, in its order: each item's replay or why it was skipped.
pub type Replays = Vec<Result<TraceReplay, FileError>>;

/// Replays the releases of the fleet archive `path` (one split's, when `opts` asks) in the
/// archive's order, reading [`ARCHIVE_CHUNK`] row groups at a time in parallel; returns the
/// items (name: the release id) and their results as [`replay_all`] does. An archive that
/// cannot be opened is an error; a bad release is its result's error.
pub fn replay_archive(path: &Path, opts: &ReplayOptions) -> Result<(Vec<TraceItem>, Replays)> {
    let reader = ArchiveReader::open(path)?;
    let groups = reader.selected();
    let item_of = |i: usize, label: Option<String>| {
        let (name, locomotive) = match reader.key(i) {
            Some(Ok((loco, release))) => (release.to_owned(), Some(loco.to_owned())),
            _ => (format!("row group {i}"), None),
        };
        TraceItem { path: path.to_owned(), name, label, locomotive }
    };
    let all: Vec<TraceItem> = groups.iter().map(|&i| item_of(i, None)).collect();
    if all.is_empty() {
        bail!("no releases to replay in {}", path.display());
    }
    guard_inputs(path, &all, opts)?;
    let bar =
        if opts.progress && groups.len() > 1 { ProgressBar::new(groups.len() as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("replay [{bar:40}] {pos}/{len} releases {elapsed_precise} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let threads = if opts.threads == 0 { 0 } else { opts.threads.min(groups.len()) };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("cannot start worker threads")?;
    let name = reader.name().to_owned();
    let mut numbering = ReleaseNumbering::default();
    let (mut items, mut results) = (Vec::new(), Vec::new());
    for chunk in groups.chunks(ARCHIVE_CHUNK) {
        let read: Vec<Result<ArchivedRelease, FileError>> =
            pool.install(|| chunk.par_iter().map(|&i| reader.read(i)).collect());
        let mut jobs = Vec::with_capacity(chunk.len());
        for (&i, r) in chunk.iter().zip(read) {
            match r {
                Ok(r) if opts.split.as_deref().is_some_and(|s| r.split.as_deref() != Some(s)) => {}
                Ok(r) => {
                    let before = numbering.next(Some(&r.locomotive));
                    jobs.push((i, Ok((r, before))));
                }
                Err(e) => {
                    numbering.next(item_of(i, None).locomotive.as_deref());
                    jobs.push((i, Err(e)));
                }
            }
        }
        let replayed: Vec<Result<Result<TraceReplay, FileError>>> = pool.install(|| {
            jobs.par_iter()
                .map(|(_, job)| match job {
                    Ok((r, before)) => match replay_archived(&name, r, opts, *before) {
                        Ok(t) => Ok(Ok(t)),
                        Err(ReplayError::Input(e)) => Ok(Err(e)),
                        Err(ReplayError::Output(e)) => Err(e),
                    },
                    Err(e) => Ok(Err(e.clone())),
                })
                .collect()
        });
        for ((i, job), result) in jobs.into_iter().zip(replayed) {
            let label = job.ok().map(|(r, _)| r.label.unwrap_or_else(|| "-".to_owned()));
            items.push(item_of(i, label));
            results.push(result?);
        }
        bar.inc(chunk.len() as u64);
    }
    bar.finish_and_clear();
    Ok((items, results))
}

/// The results-Parquet row of each item ([`pbm_io::archive::results`]).
pub fn result_rows(items: &[TraceItem], results: &[Result<TraceReplay, FileError>]) -> Vec<ResultRow> {
    items
        .iter()
        .zip(results)
        .map(|(item, r)| match r {
            Ok(t) => {
                let s = &t.summary;
                let e = s.last.map(|l| l.estimates);
                let f = |v: Option<f32>| v.map(f64::from);
                let verdict = s.diagnosis.map(|d| d.verdict);
                ResultRow {
                    locomotive: (s.locomotive != "-").then(|| s.locomotive.clone()),
                    release: s.file.clone(),
                    label: (s.label != "-").then(|| s.label.clone()),
                    samples: i64::try_from(s.samples).ok(),
                    nmse_pct: s.nmse_pct,
                    max_abs_residual_bar: Some(s.max_abs_residual_bar),
                    sensor_fault_samples: i64::try_from(s.sensor_faults).ok(),
                    final_bar_g: s.final_bar,
                    est_orifice_mm: f(e.and_then(|e| e.orifice_mm)),
                    est_leak_mm: f(e.and_then(|e| e.leak_mm)),
                    est_supply_bar_g: f(e.and_then(|e| e.supply_bar_g)),
                    verdict: Some(verdict_label(verdict.as_ref())),
                    confidence_pct: match verdict {
                        Some(Verdict::Class { confidence_pct, .. }) => Some(i32::from(confidence_pct)),
                        _ => None,
                    },
                    no_diagnosis: match verdict {
                        Some(Verdict::CannotDiagnose(why)) => Some(why.to_string()),
                        _ => None,
                    },
                    diagnosis: Some(diagnosis(s)),
                    error: None,
                }
            }
            Err(e) => ResultRow {
                locomotive: item.locomotive.clone(),
                release: item.name.clone(),
                label: item.label.clone().filter(|l| l != "-"),
                error: Some(e.to_string()),
                ..ResultRow::default()
            },
        })
        .collect()
}

/// A replay run: every trace under `path` (a trace, a data set or a fleet archive), the table
/// on stdout, the outputs of `opts`. Returns what was skipped (bad inputs); fails only when
/// nothing could be replayed or an output could not be written.
pub fn run(path: &Path, opts: &ReplayOptions) -> Result<Skipped> {
    let (items, results, mut skipped) = if path.is_file() && is_archive(path) {
        let (items, results) = replay_archive(path, opts)?;
        (items, results, Skipped::none())
    } else {
        let (items, skipped) = items(path, opts.split.as_deref())?;
        if items.is_empty() {
            bail!(
                "no traces to replay in {}{}",
                path.display(),
                if skipped.is_empty() { String::new() } else { format!("\n{skipped}") }
            );
        }
        guard_inputs(path, &items, opts)?;
        let results = replay_all(&items, opts)?;
        (items, results, skipped)
    };
    print_table(&items, &results);
    if let Some(dir) = &opts.out {
        write_summary_csv(&dir.join("summary.csv"), &items, &results)?;
    }
    if let Some(file) = &opts.results_parquet {
        write_results(file, &result_rows(&items, &results))?;
    }
    if let Some(log) = &opts.can_log {
        let frames = write_can_log(log, results.iter().filter_map(|r| r.as_ref().ok()).map(|t| &t.replayed))?;
        eprintln!("wrote {frames} CAN frames to {}", log.display());
    }
    let replayed = results.iter().filter(|r| r.is_ok()).count();
    for e in results.into_iter().filter_map(Result::err) {
        skipped.push(e);
    }
    if replayed == 0 {
        bail!("no trace could be replayed\n{skipped}");
    }
    Ok(skipped)
}
