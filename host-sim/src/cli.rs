//! The commands and flags of `host-sim`, each turned into a library call. Defaults come from the
//! libraries' option structs, so a default is written once.

use anyhow::Result;
use clap::{Args, Parser, Subcommand};
use pbm::mechanism::Mechanism;
use pbm::{FaultClass, TwinParams};
use pbm_demo::demo::DemoOptions;
use pbm_fleet::scenario::DegradationOptions;
use pbm_io::error::Skipped;
use pbm_lab::audit::AuditRunOptions;
use pbm_lab::audit_sweep::SweepOptions;
use pbm_lab::bench::BenchOptions;
use pbm_lab::can_cmd::{DecodeFormat, DecodeOptions, DemoLogOptions, SendOptions};
use pbm_lab::estimate::EstimateOptions;
use pbm_lab::fit::{FitOptions, FitParams};
use pbm_lab::generate::{Conditions, GenerateOptions, SplitMode};
use pbm_lab::metro::MetroOptions;
use pbm_lab::replay::ReplayOptions;
use pbm_lab::simulate::{Engine, SimulateOptions};
use pbm_ml::evaluate::EvaluateOptions;
use pbm_ml::train::TrainOptions;
use std::path::PathBuf;

/// Host tools for the spring parking brake monitor.
#[derive(Parser)]
#[command(name = "host-sim", version, about = "Host tools for the spring parking brake monitor")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// The commands.
#[derive(Subcommand)]
pub enum Command {
    /// Simulate one release (noise-free) and write its trace as CSV (t_s,p_bar,x_mm).
    Simulate(SimulateArgs),
    /// Generate a synthetic fleet data set (manifest, ADC traces, ground truth).
    Generate(GenerateArgs),
    /// Model-discrepancy audit of a data set of releases of one locomotive.
    Audit(AuditArgs),
    /// Hidden-effect sweep of the audit: hit rate over seeded random mechanisms.
    AuditSweep(SweepArgs),
    /// The audit on real pneumatic data (the MetroPT-3 extract).
    AuditMetro(MetroArgs),
    /// Print throughput figures (twin, monitor pipeline, generate) and write bench/host.md.
    Bench(BenchArgs),
    /// Replay a trace, a data set or a fleet archive through the monitor pipeline (results CSV,
    /// summary, plots, results Parquet).
    Replay(ReplayArgs),
    /// Fleet archives: many releases in one Parquet file (docs/archive.md); pack, unpack.
    #[command(subcommand)]
    Archive(ArchiveCommand),
    /// CAN reports: decode a candump log or interface as the cab display shows it, send, demo log.
    #[command(subcommand)]
    Can(CanCommand),
    /// Batch least-squares fit of twin parameters per trace (the paper's θ or the fault parameters).
    Fit(FitArgs),
    /// Accuracy of the online estimator against known truth: table, CSV, scatter plots.
    Estimate(EstimateArgs),
    /// Train the paper's three classifiers and ours; quantize ours to int8.
    Train(TrainArgs),
    /// Accuracy and confusion matrices of the trained classifiers on a data set's test split.
    Evaluate(EvaluateArgs),
    /// The main job in one run: fleet data, training, evaluation, CAN replay, audit, report/index.html.
    Demo(DemoArgs),
    /// The fleet history: store releases per locomotive, show verdicts, trends and early warnings.
    #[command(subcommand)]
    Fleet(FleetCommand),
}

/// Runs a command; returns the inputs it skipped.
pub fn run(command: Command) -> Result<Skipped> {
    let done = |r: Result<()>| r.map(|()| Skipped::none());
    match command {
        Command::Simulate(a) => done(pbm_lab::simulate::run(&a.into())),
        Command::Generate(a) => done(pbm_lab::generate::run(&a.try_into()?)),
        Command::Audit(a) => pbm_lab::audit_plot::run(&a.path.clone(), &a.into()),
        Command::AuditSweep(a) => done(pbm_lab::audit_sweep::run(&a.try_into()?)),
        Command::AuditMetro(a) => done(pbm_lab::metro::run(&a.path.clone(), &a.into())),
        Command::Bench(a) => done(pbm_lab::bench::run(&a.into())),
        Command::Replay(a) => pbm_lab::replay::run(&a.path.clone(), &a.into()),
        Command::Archive(ArchiveCommand::Pack(a)) => {
            let (summary, skipped) = pbm_io::archive::pack(&a.inputs, &a.out)?;
            eprintln!("{summary}");
            Ok(skipped)
        }
        Command::Archive(ArchiveCommand::Unpack(a)) => {
            let (summary, skipped) = pbm_io::archive::unpack(&a.archive, &a.out)?;
            eprintln!("{summary}");
            Ok(skipped)
        }
        Command::Can(CanCommand::Decode(a)) => done(pbm_lab::can_cmd::decode(&a.into())),
        Command::Can(CanCommand::Send(a)) => done(pbm_lab::can_cmd::send(&a.into())),
        Command::Can(CanCommand::DemoLog(a)) => done(pbm_lab::can_cmd::demo_log(&a.into())),
        Command::Fit(a) => pbm_lab::fit::run(&a.input.clone(), &a.into()),
        Command::Estimate(a) => pbm_lab::estimate::run(&a.into()),
        Command::Train(a) => pbm_ml::train::run(&a.into()),
        Command::Evaluate(a) => pbm_ml::evaluate::run(&a.into()),
        Command::Demo(a) => done(pbm_demo::demo::run(&a.into())),
        Command::Fleet(FleetCommand::Ingest(a)) => pbm_fleet::commands::run_ingest(&a.into()),
        Command::Fleet(FleetCommand::Status(a)) => done(pbm_fleet::commands::run_status(&a.into())),
        Command::Fleet(FleetCommand::Degrade(a)) => done(pbm_fleet::commands::run_degrade(&a.into())),
        Command::Fleet(FleetCommand::Report(a)) => done(pbm_fleet::commands::run_report(&a.into())),
        Command::Fleet(FleetCommand::Export(a)) => done(pbm_fleet::commands::run_export(&a.into())),
    }
}

// ---- simulate ------------------------------------------------------------------------------

#[derive(Args)]
pub struct SimulateArgs {
    /// Twin implementation: the fixed-point core or the f64 reference.
    #[arg(long, value_enum, default_value_t = Engine::Fixed)]
    engine: Engine,
    /// Release orifice diameter, mm.
    #[arg(long, default_value_t = TwinParams::NOMINAL_ORIFICE_MM)]
    orifice_mm: f64,
    /// Leak orifice diameter to atmosphere, mm (0 = none).
    #[arg(long, default_value_t = 0.0)]
    leak_mm: f64,
    /// Supply pressure, bar g.
    #[arg(long, default_value_t = TwinParams::NOMINAL_SUPPLY_BAR_G)]
    supply_bar: f64,
    /// Duration, s.
    #[arg(long, default_value_t = SimulateOptions::default().duration_s)]
    duration: f64,
    /// Output file (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also write an SVG of the release (pressure from both engines, piston travel).
    #[arg(long)]
    plot: Option<PathBuf>,
}

impl From<SimulateArgs> for SimulateOptions {
    fn from(a: SimulateArgs) -> Self {
        let params =
            TwinParams::nominal().with_orifice_mm(a.orifice_mm).with_leak_mm(a.leak_mm).with_supply_bar_g(a.supply_bar);
        Self { engine: a.engine, params, duration_s: a.duration, out: a.out, plot: a.plot }
    }
}

// ---- generate ------------------------------------------------------------------------------

fn generate_defaults() -> GenerateOptions {
    GenerateOptions::new(PathBuf::new())
}

#[derive(Args)]
pub struct GenerateArgs {
    /// Output directory (created; must be empty or absent unless --force).
    #[arg(long)]
    out: PathBuf,
    /// Number of locomotives in the fleet.
    #[arg(long, default_value_t = generate_defaults().locomotives)]
    locomotives: usize,
    /// Training traces per class.
    #[arg(long, default_value_t = generate_defaults().per_class)]
    per_class: usize,
    /// Test traces per class.
    #[arg(long, default_value_t = generate_defaults().test_per_class)]
    test_per_class: usize,
    /// Random seed: the same seed gives the same bytes.
    #[arg(long, default_value_t = generate_defaults().seed)]
    seed: u64,
    /// Classes to generate (comma-separated labels; `orifice_missing` allowed).
    #[arg(long, value_delimiter = ',', default_values_t = FaultClass::PAPER.map(|c| c.label().to_owned()))]
    classes: Vec<String>,
    /// How locomotives are assigned to the splits.
    #[arg(long, value_enum, default_value_t = SplitMode::HeldOut)]
    split: SplitMode,
    /// Held-out locomotives for the test split (with --split held-out).
    #[arg(long, default_value_t = generate_defaults().test_locomotives)]
    test_locomotives: usize,
    /// Worker threads (0 = all cores). The output does not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Overwrite a non-empty output directory.
    #[arg(long)]
    force: bool,
    /// A mechanism the base model lacks, NAME=VALUE (repeatable); see the list below.
    #[arg(long = "effect", value_parser = pbm_lab::plant::parse_effect, long_help = effect_long_help())]
    effects: Vec<(Mechanism, f64)>,
    /// Sensor or ADC fault KIND[=VALUE][@ONSET_S|@random] on every trace (repeatable, applied in
    /// order): frozen, dead[=BAR], noisy[=SIGMA_BAR], spikes[=FRACTION], dropouts[=P],
    /// lost_resolution[=BITS], clipped[=BAR], impossible_rate[=STEP_BAR],
    /// implausible_level[=GAIN], offset[=BAR], open_circuit, short_circuit. The manifest label
    /// stays the release's true class; the fault is in the trace's `# sensor_fault:` metadata
    /// and truth.csv's `sensor_fault` column. Without @ONSET the onset is drawn per trace in
    /// 1..50 s.
    #[arg(long = "sensor-fault", value_parser = pbm_lab::sensor_faults::parse_spec)]
    sensor_faults: Vec<pbm_lab::sensor_faults::FaultSpec>,
    /// Transducer noise before the ADC, σ in bar (specification: 0.01).
    #[arg(long, default_value_t = Conditions::SPEC.noise_bar)]
    noise_bar: f64,
    /// Relative manufacturing spread of V0, F0, K, Cf, Fc and Fs per locomotive (specification: 0.05).
    #[arg(long, default_value_t = Conditions::SPEC.spread)]
    spread: f64,
    /// Range of the locomotives' regulator settings, LO,HI in bar g (specification: 7.67,7.73).
    #[arg(long, value_delimiter = ',', num_args = 2, default_values_t = [Conditions::SPEC.regulator_bar_g.0, Conditions::SPEC.regulator_bar_g.1])]
    regulator_bar: Vec<f64>,
}

/// The `--effect` help: every mechanism from the core's table.
fn effect_long_help() -> String {
    format!(
        "A mechanism the base model lacks, NAME=VALUE (repeatable), e.g. transport_delay=0.1.\n\n{}",
        pbm_lab::plant::effect_help()
    )
}

impl TryFrom<GenerateArgs> for GenerateOptions {
    type Error = anyhow::Error;
    fn try_from(a: GenerateArgs) -> Result<Self> {
        let mut effects = pbm::mechanism::Extensions::NONE;
        for (i, &(m, v)) in a.effects.iter().enumerate() {
            if a.effects[..i].iter().any(|&(n, _)| n == m) {
                anyhow::bail!("--effect {m} given twice");
            }
            effects[m] = v;
        }
        let [lo, hi] = a.regulator_bar[..] else { anyhow::bail!("--regulator-bar takes LO,HI") };
        Ok(Self {
            out: a.out,
            locomotives: a.locomotives,
            per_class: a.per_class,
            test_per_class: a.test_per_class,
            seed: a.seed,
            classes: pbm_lab::generate::parse_classes(&a.classes)?,
            split: a.split,
            test_locomotives: a.test_locomotives,
            threads: a.threads,
            force: a.force,
            effects,
            sensor_faults: a.sensor_faults,
            conditions: Conditions { noise_bar: a.noise_bar, spread: a.spread, regulator_bar_g: (lo, hi) },
        })
    }
}

// ---- audits --------------------------------------------------------------------------------

#[derive(Args)]
pub struct AuditArgs {
    /// Data set directory (manifest.csv + traces) of releases of one locomotive.
    path: PathBuf,
    /// Write the verdict as JSON (with a `warnings` array: unknown metadata keys).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write residual and comparison plots (SVG) into this directory.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Write a self-contained HTML report (inline SVG) to this file; without a value to
    /// `audit_report.html` in the `--plot` directory, or in the current directory.
    #[arg(long, num_args = 0..=1, value_name = "FILE")]
    report: Option<Option<PathBuf>>,
    /// Do not try pairs of mechanisms.
    #[arg(long)]
    no_pairs: bool,
}

impl From<AuditArgs> for AuditRunOptions {
    fn from(a: AuditArgs) -> Self {
        let report = a.report.map(|r| match (r, &a.plot) {
            (Some(file), _) => file,
            (None, Some(dir)) => dir.join(pbm_lab::audit::REPORT_FILE),
            (None, None) => PathBuf::from(pbm_lab::audit::REPORT_FILE),
        });
        Self { json: a.json, plot: a.plot, report, pairs: !a.no_pairs }
    }
}

#[derive(Args)]
pub struct SweepArgs {
    /// Number of single-mechanism hidden-effect cases.
    #[arg(long, default_value_t = SweepOptions::default().cases)]
    cases: u64,
    /// First seed (case k uses seed + k).
    #[arg(long, default_value_t = SweepOptions::default().seed)]
    seed: u64,
    /// Mechanisms to draw from (comma-separated names; default all).
    #[arg(long, value_delimiter = ',')]
    effects: Vec<String>,
    /// Magnitude range `LO,HI` replacing the plausible ranges (e.g. to probe a limit).
    #[arg(long, value_delimiter = ',', num_args = 2, allow_negative_numbers = true)]
    range: Vec<f64>,
    /// Also run this many two-mechanism cases (distinct mechanisms, both plausible).
    #[arg(long, default_value_t = 0)]
    pairs: u64,
    /// Also run this many null cases (clean plant; the audit must say `none`).
    #[arg(long, default_value_t = 0)]
    null_cases: u64,
    /// Also run this many open-world cases: an effect outside the library (hunting regulator,
    /// leak above a pressure, supply cut, icing orifice, rough bore patch, tearing seal,
    /// transducer bow), half of them mixed with a library mechanism; the audit must never say
    /// `none` while the base NMSE is ≥ 3× the noise floor's.
    #[arg(long, default_value_t = 0)]
    open_world: u64,
    /// Print the audit summary of every missed case.
    #[arg(long)]
    verbose: bool,
}

impl TryFrom<SweepArgs> for SweepOptions {
    type Error = anyhow::Error;
    fn try_from(a: SweepArgs) -> Result<Self> {
        let effects = a.effects.iter().map(|n| pbm_lab::plant::effect_by_name(n.trim())).collect::<Result<_>>()?;
        let range = match a.range[..] {
            [] => None,
            [lo, hi] => Some((lo, hi)),
            _ => anyhow::bail!("--range takes LO,HI"),
        };
        Ok(Self {
            cases: a.cases,
            seed: a.seed,
            effects,
            range,
            pairs: a.pairs,
            null_cases: a.null_cases,
            open_world: a.open_world,
            verbose: a.verbose,
        })
    }
}

#[derive(Args)]
pub struct MetroArgs {
    /// The MetroPT-3 CSV record.
    #[arg(default_value = pbm_lab::metro::DEFAULT_PATH)]
    path: PathBuf,
    /// Write the verdict as JSON (the keys of `host-sim audit --json` but the per-trace NMSE: one record).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Plots: a `.svg` file (measured vs adiabatic vs extended), or a directory that receives
    /// `metro_curves.svg` and `metro_residual.svg`.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Instead of the file: a sweep of this many synthetic records, each with one mechanism
    /// hidden at a magnitude drawn from `--seed`; prints the hit rate.
    #[arg(long, value_name = "CASES")]
    synthetic_sweep: Option<usize>,
    /// Seed of `--synthetic-sweep`.
    #[arg(long, default_value_t = MetroOptions::default().seed)]
    seed: u64,
}

impl From<MetroArgs> for MetroOptions {
    fn from(a: MetroArgs) -> Self {
        Self { json: a.json, plot: a.plot, synthetic_sweep: a.synthetic_sweep, seed: a.seed }
    }
}

// ---- bench ---------------------------------------------------------------------------------

#[derive(Args)]
pub struct BenchArgs {
    /// Twin-alone samples to time (single thread).
    #[arg(long, default_value_t = BenchOptions::default().twin_samples)]
    twin_samples: u64,
    /// Monitor-pipeline samples to time (single thread).
    #[arg(long, default_value_t = BenchOptions::default().pipeline_samples)]
    pipeline_samples: u64,
    /// Training traces per class for the generate timing (paper size: 1100 + 50, 5 classes).
    #[arg(long, default_value_t = BenchOptions::default().per_class)]
    per_class: usize,
    /// Test traces per class for the generate timing.
    #[arg(long, default_value_t = BenchOptions::default().test_per_class)]
    test_per_class: usize,
    /// Skip the generate timing.
    #[arg(long)]
    skip_generate: bool,
    /// Skip the integration-step accuracy study.
    #[arg(long)]
    skip_step_study: bool,
    /// Scratch directory for the generated set (removed afterwards).
    #[arg(long)]
    scratch: Option<PathBuf>,
    /// Where to write the Markdown report.
    #[arg(long, default_value_os_t = BenchOptions::default().report)]
    report: PathBuf,
}

impl From<BenchArgs> for BenchOptions {
    fn from(a: BenchArgs) -> Self {
        Self {
            twin_samples: a.twin_samples,
            pipeline_samples: a.pipeline_samples,
            per_class: a.per_class,
            test_per_class: a.test_per_class,
            skip_generate: a.skip_generate,
            skip_step_study: a.skip_step_study,
            scratch: a.scratch,
            report: a.report,
        }
    }
}

// ---- replay --------------------------------------------------------------------------------

#[derive(Args)]
pub struct ReplayArgs {
    /// A trace file, a data set directory containing manifest.csv, or a fleet archive (Parquet).
    path: PathBuf,
    /// Write one results CSV per trace (and summary.csv) into this directory.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write one SVG plot per trace (measured vs twin pressure, residual) into this directory.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Write the CAN frames the monitor sends as one candump log.
    #[arg(long)]
    can_log: Option<PathBuf>,
    /// Only replay data set traces of this split (`train` or `test`).
    #[arg(long)]
    split: Option<String>,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Write one row per release (the table's fields) to this Parquet file (docs/archive.md).
    #[arg(long)]
    results_parquet: Option<PathBuf>,
}

impl From<ReplayArgs> for ReplayOptions {
    fn from(a: ReplayArgs) -> Self {
        Self {
            out: a.out,
            plot: a.plot,
            can_log: a.can_log,
            split: a.split,
            threads: a.threads,
            progress: true,
            results_parquet: a.results_parquet,
        }
    }
}

// ---- archive -------------------------------------------------------------------------------

/// Subcommands of `host-sim archive`.
#[derive(Subcommand)]
pub enum ArchiveCommand {
    /// Pack data sets (directories with manifest.csv) and ADC trace files into one fleet
    /// archive, one row group per release, sorted by (locomotive, release).
    Pack(ArchivePackArgs),
    /// Write a fleet archive back as a data set: manifest.csv and one trace CSV per release.
    Unpack(ArchiveUnpackArgs),
}

#[derive(Args)]
pub struct ArchivePackArgs {
    /// Data set directories and trace files (a trace file needs `# locomotive:` metadata).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// The archive to write.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args)]
pub struct ArchiveUnpackArgs {
    /// The fleet archive.
    archive: PathBuf,
    /// The data set directory to write (must be absent or empty).
    #[arg(long)]
    out: PathBuf,
}

// ---- can -----------------------------------------------------------------------------------

/// Subcommands of `host-sim can`.
#[derive(Subcommand)]
pub enum CanCommand {
    /// Decode a candump log (or stdin, or a CAN interface) and print the reports as the cab
    /// display shows them; flag and skip bad frames; summary at the end.
    Decode(DecodeArgs),
    /// Send the frames of a candump log onto a CAN interface (needs `--features socketcan`).
    Send(SendArgs),
    /// Write a demonstration candump log: simulated releases through the monitor and the CAN
    /// reporter, with scripted verdicts covering every diagnosis and reason code.
    DemoLog(DemoLogArgs),
}

#[derive(Args)]
pub struct DecodeArgs {
    /// candump log file, `-` for standard input.
    #[arg(required_unless_present = "can_iface")]
    file: Option<PathBuf>,
    /// Listen on this SocketCAN interface instead (Linux, `--features socketcan`).
    #[arg(long)]
    can_iface: Option<String>,
    /// With --can-iface: stop after this many seconds without a frame (default: never).
    #[arg(long)]
    idle_timeout: Option<f64>,
    /// Also print status/heartbeat frames.
    #[arg(long)]
    status: bool,
    /// Output format.
    #[arg(long, value_enum, default_value_t = DecodeFormat::Text)]
    format: DecodeFormat,
    /// Exit 4 when any frame was flagged or lost, a fault report was stale, or the log held no
    /// frame (for CI replays; an unreadable log is exit 1); the summary says what.
    #[arg(long)]
    strict: bool,
    /// Check integrity only (identifier, length, CRC, signal values), not freshness: for codec
    /// sweeps (`can demo-log --sweep`), whose frames are no stream.
    #[arg(long)]
    codec_only: bool,
}

impl From<DecodeArgs> for DecodeOptions {
    fn from(a: DecodeArgs) -> Self {
        Self {
            file: a.file,
            can_iface: a.can_iface,
            idle_timeout: a.idle_timeout,
            status: a.status,
            format: a.format,
            strict: a.strict,
            codec_only: a.codec_only,
        }
    }
}

#[derive(Args)]
pub struct SendArgs {
    /// candump log file, `-` for standard input.
    file: PathBuf,
    /// SocketCAN interface to send on, e.g. vcan0.
    #[arg(long)]
    can_iface: String,
    /// Keep the log's timing (sleep between frames) instead of sending as fast as possible.
    #[arg(long)]
    realtime: bool,
}

impl From<SendArgs> for SendOptions {
    fn from(a: SendArgs) -> Self {
        Self { file: a.file, can_iface: a.can_iface, realtime: a.realtime }
    }
}

#[derive(Args)]
pub struct DemoLogArgs {
    /// Output file (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Interface name written in the log.
    #[arg(long, default_value_t = DemoLogOptions::default().iface)]
    iface: String,
    /// Instead of simulated releases, sweep the codec: every diagnosis, reason, sensor and
    /// estimator code with field values at and beyond the edges of their ranges.
    #[arg(long)]
    sweep: bool,
}

impl From<DemoLogArgs> for DemoLogOptions {
    fn from(a: DemoLogArgs) -> Self {
        Self { out: a.out, iface: a.iface, sweep: a.sweep }
    }
}

// ---- fit, estimate -------------------------------------------------------------------------

#[derive(Args)]
pub struct FitArgs {
    /// A trace file, or a data set directory (with manifest.csv).
    input: PathBuf,
    /// Parameters to fit.
    #[arg(long, value_enum, default_value_t = FitParams::Paper)]
    params: FitParams,
    /// Nelder–Mead iteration limit per trace.
    #[arg(long, default_value_t = FitOptions::default().max_iters)]
    max_iters: u64,
    /// With a data set: fit only traces of this split (train/test).
    #[arg(long)]
    split: Option<String>,
    /// With a data set: at most this many traces per class (0 = all).
    #[arg(long, default_value_t = 0)]
    per_class: usize,
}

impl From<FitArgs> for FitOptions {
    fn from(a: FitArgs) -> Self {
        Self { params: a.params, max_iters: a.max_iters, split: a.split, per_class: a.per_class }
    }
}

#[derive(Args)]
pub struct EstimateArgs {
    /// Data set directory from `host-sim generate` (omit with --synthetic).
    dataset: Option<PathBuf>,
    /// Write the scatter plots (SVG) and estimates.csv here.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Instead of a data set: this many synthetic traces per class.
    #[arg(long)]
    synthetic: Option<usize>,
    /// Seed of the synthetic traces.
    #[arg(long, default_value_t = EstimateOptions::default().seed)]
    seed: u64,
    /// With a data set: only this split (train/test).
    #[arg(long, default_value_t = EstimateOptions::default().split)]
    split: String,
    /// With a data set: at most this many traces per class (0 = all).
    #[arg(long, default_value_t = EstimateOptions::default().per_class)]
    per_class: usize,
    /// Nelder–Mead iterations of the batch fit per trace (0 = no batch fit).
    #[arg(long, default_value_t = EstimateOptions::default().batch_iters)]
    batch_iters: u64,
}

impl From<EstimateArgs> for EstimateOptions {
    fn from(a: EstimateArgs) -> Self {
        Self {
            dataset: a.dataset,
            plot: a.plot,
            synthetic: a.synthetic,
            seed: a.seed,
            split: a.split,
            per_class: a.per_class,
            batch_iters: a.batch_iters,
        }
    }
}

// ---- train, evaluate -----------------------------------------------------------------------

#[derive(Args)]
pub struct TrainArgs {
    /// Data set directory (manifest.csv + traces); rows with split `train` are used.
    dataset: PathBuf,
    /// Directory for the trained models (created).
    #[arg(long, default_value = "models")]
    out: PathBuf,
    /// Seed of initialisation, validation split and shuffling: same seed, same models.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also write the int8 model as Rust source for the core (e.g. src/classifier/model_weights.rs).
    #[arg(long)]
    export_rs: Option<PathBuf>,
    /// Also write golden vectors (features → int8 logits, class) for the exported model.
    #[arg(long)]
    golden: Option<PathBuf>,
    /// Also train ours on a copy of every training release whose air arrives up to 0.3 s late
    /// (a transport delay). Off by default: the core's features are delay-robust by design and,
    /// measured on the paper-size set, the copies cost early accuracy.
    #[arg(long)]
    augment: bool,
    /// Train nothing: keep the network compiled into the core and only recompute its class
    /// regions (the out-of-distribution guard) from DATASET's training releases; with
    /// --export-rs, write it back as the core's model source.
    #[arg(long)]
    refit_region: bool,
}

impl From<TrainArgs> for TrainOptions {
    fn from(a: TrainArgs) -> Self {
        Self {
            dataset: a.dataset,
            out: a.out,
            seed: a.seed,
            export_rs: a.export_rs,
            golden: a.golden,
            augment: a.augment,
            refit_region: a.refit_region,
        }
    }
}

#[derive(Args)]
pub struct EvaluateArgs {
    /// Data set directory; rows with split `test` are evaluated.
    dataset: PathBuf,
    /// Directory of the models written by `host-sim train`.
    #[arg(long, default_value = "models")]
    models: PathBuf,
    /// Write the results as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write SVG plots (confusion matrices, accuracy vs time) into this directory.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Also run leave-one-locomotive-out for ours (retrains once per locomotive on all splits).
    #[arg(long)]
    lolo: bool,
    /// Also print the confusion matrix of ours (int8) at every snapshot time.
    #[arg(long)]
    verbose: bool,
    /// Seed for the leave-one-locomotive-out training.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

impl From<EvaluateArgs> for EvaluateOptions {
    fn from(a: EvaluateArgs) -> Self {
        Self {
            dataset: a.dataset,
            models: a.models,
            json: a.json,
            plot: a.plot,
            lolo: a.lolo,
            verbose: a.verbose,
            seed: a.seed,
        }
    }
}

// ---- demo ----------------------------------------------------------------------------------

#[derive(Args)]
pub struct DemoArgs {
    /// Seed of everything: data set, training, the hidden audit effect.
    #[arg(long, default_value_t = DemoOptions::default().seed)]
    seed: u64,
    /// Report directory (index.html, svg/, can/).
    #[arg(long, default_value_os_t = DemoOptions::default().out)]
    out: PathBuf,
    /// Data set directory [default: data/demo-fleet; with --quick: OUT/fleet].
    #[arg(long)]
    data: Option<PathBuf>,
    /// Small, fast variant (40 + 10 traces per class) for tests.
    #[arg(long)]
    quick: bool,
    /// Firmware cost figures to include if present (read, not computed, and labelled so).
    #[arg(long, default_value_os_t = DemoOptions::default().firmware_report)]
    firmware_report: PathBuf,
    /// Test traces per class replayed with CAN logging.
    #[arg(long, default_value_t = DemoOptions::default().can_per_class)]
    can_per_class: usize,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// The MetroPT-3 record of the real-data audit.
    #[arg(long, default_value_os_t = DemoOptions::default().metro)]
    metro: PathBuf,
}

impl From<DemoArgs> for DemoOptions {
    fn from(a: DemoArgs) -> Self {
        Self {
            seed: a.seed,
            out: a.out,
            data: a.data,
            quick: a.quick,
            firmware_report: a.firmware_report,
            can_per_class: a.can_per_class,
            threads: a.threads,
            metro: a.metro,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn defaults_are_the_libraries() {
        let Cli { command: Command::Generate(g) } = Cli::parse_from(["host-sim", "generate", "--out", "d"]) else {
            panic!("generate");
        };
        let g = GenerateOptions::try_from(g).expect("valid");
        assert_eq!(g, GenerateOptions::new(PathBuf::from("d")));
        let Cli { command: Command::Demo(d) } = Cli::parse_from(["host-sim", "demo"]) else { panic!("demo") };
        assert_eq!(DemoOptions::from(d), DemoOptions::default());
        let Cli { command: Command::Bench(b) } = Cli::parse_from(["host-sim", "bench"]) else { panic!("bench") };
        assert_eq!(BenchOptions::from(b), BenchOptions::default());
    }

    #[test]
    fn effect_help_lists_every_mechanism() {
        let help = Cli::command().find_subcommand_mut("generate").expect("generate").render_long_help().to_string();
        for m in Mechanism::ALL {
            assert!(help.contains(m.name()), "{m} missing from `generate --help`");
        }
    }
}

// ---- fleet ---------------------------------------------------------------------------------

#[derive(Subcommand)]
pub enum FleetCommand {
    /// Store releases in the fleet database: traces and data sets are replayed through the
    /// monitor, candump logs decoded as the cab display decodes them. Re-ingesting does not
    /// duplicate a release.
    Ingest(FleetIngestArgs),
    /// One line per locomotive: releases, verdict mix, latest estimates with their trend, and
    /// early warnings of a drift toward a fault.
    Status(FleetStatusArgs),
    /// Write a slow-degradation data set: healthy locomotives and locomotives whose leak grows
    /// or whose release orifice clogs over many releases.
    Degrade(FleetDegradeArgs),
    /// Write the fleet page (DIR/index.html, self-contained): a table of locomotives, then each
    /// locomotive's trends against the fault edges.
    Report(FleetReportArgs),
    /// Export every stored release as one Parquet file (for pandas, polars, DuckDB, Spark).
    Export(FleetExportArgs),
}

#[derive(Args)]
pub struct FleetExportArgs {
    /// The fleet database (SQLite file).
    #[arg(long)]
    db: PathBuf,
    /// The Parquet file to write.
    #[arg(long)]
    out: PathBuf,
}

impl From<FleetExportArgs> for pbm_fleet::commands::ExportRun {
    fn from(a: FleetExportArgs) -> Self {
        Self { db: a.db, out: a.out }
    }
}

#[derive(Args)]
pub struct FleetReportArgs {
    /// The fleet database (SQLite file).
    #[arg(long)]
    db: PathBuf,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
}

impl From<FleetReportArgs> for pbm_fleet::commands::ReportRun {
    fn from(a: FleetReportArgs) -> Self {
        Self { db: a.db, out: a.out }
    }
}

#[derive(Args)]
pub struct FleetIngestArgs {
    /// The fleet database (SQLite file, created if absent).
    #[arg(long)]
    db: PathBuf,
    /// Trace files, data set directories (with manifest.csv), fleet archives and candump logs.
    #[arg(required = true)]
    paths: Vec<PathBuf>,
    /// Worker threads for replaying traces (0 = all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

impl From<FleetIngestArgs> for pbm_fleet::commands::IngestRun {
    fn from(a: FleetIngestArgs) -> Self {
        Self { db: a.db, paths: a.paths, options: pbm_fleet::ingest::IngestOptions { threads: a.threads } }
    }
}

#[derive(Args)]
pub struct FleetStatusArgs {
    /// The fleet database (SQLite file).
    #[arg(long)]
    db: PathBuf,
}

impl From<FleetStatusArgs> for pbm_fleet::commands::StatusRun {
    fn from(a: FleetStatusArgs) -> Self {
        Self { db: a.db }
    }
}

#[derive(Args)]
pub struct FleetDegradeArgs {
    /// Output directory (must be empty or absent).
    #[arg(long)]
    out: PathBuf,
    /// Healthy locomotives (named first: loco-01, …).
    #[arg(long, default_value_t = 2)]
    healthy: usize,
    /// Locomotives whose leak grows from none to --leak-end-mm.
    #[arg(long, default_value_t = 1)]
    leak: usize,
    /// Locomotives whose release orifice clogs from 1.25 mm to --orifice-end-mm.
    #[arg(long, default_value_t = 1)]
    clog: usize,
    /// Releases per locomotive.
    #[arg(long, default_value_t = DegradationOptions::new(0, Vec::new()).releases)]
    releases: usize,
    /// Release (0-based) at which the wear starts.
    #[arg(long, default_value_t = DegradationOptions::new(0, Vec::new()).onset)]
    onset: usize,
    /// Leak diameter at the last release, mm.
    #[arg(long, default_value_t = DegradationOptions::new(0, Vec::new()).leak_end_mm)]
    leak_end_mm: f64,
    /// Release orifice diameter at the last release, mm.
    #[arg(long, default_value_t = DegradationOptions::new(0, Vec::new()).orifice_end_mm)]
    orifice_end_mm: f64,
    /// Locomotives with a healthy brake whose pressure transducer fails from --onset on.
    #[arg(long, default_value_t = 0)]
    sensor: usize,
    /// The transducer fault of the --sensor locomotives, as the generator's --sensor-fault
    /// (KIND[=VALUE][@ONSET_S|@random]).
    #[arg(long, value_parser = pbm_lab::sensor_faults::parse_spec,
          default_value = "spikes=0.01@random")]
    sensor_fault: pbm_lab::sensor_faults::FaultSpec,
    /// Random seed (fleet spread and sensor noise).
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

impl From<FleetDegradeArgs> for pbm_fleet::commands::DegradeRun {
    fn from(a: FleetDegradeArgs) -> Self {
        Self {
            out: a.out,
            healthy: a.healthy,
            leak: a.leak,
            clog: a.clog,
            sensor: a.sensor,
            options: DegradationOptions {
                seed: a.seed,
                wear: Vec::new(),
                releases: a.releases,
                onset: a.onset,
                leak_end_mm: a.leak_end_mm,
                orifice_end_mm: a.orifice_end_mm,
                sensor_fault: a.sensor_fault,
            },
        }
    }
}
