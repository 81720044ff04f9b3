//! `host-sim`: command-line front end of the host tools.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use pbm::TwinParams;
use pbm_lab::simulate::{simulate, write_csv, Engine};
use std::io::Write;
use std::path::PathBuf;

#[derive(Parser)]
#[command(name = "host-sim", version, about = "Host tools for the spring parking brake monitor")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate one release (noise-free) and write its trace as CSV (t_s,p_bar,x_mm).
    Simulate(SimulateArgs),
    /// Generate a synthetic fleet data set (SPEC §7 layout, ADC traces, manifest, truth).
    Generate(pbm_lab::generate::GenerateArgs),
    /// Model-discrepancy audit of a data set of releases of one locomotive (issue 9).
    Audit(pbm_lab::audit::AuditArgs),
    /// Hidden-effect sweep of the audit: hit rate over seeded random mechanisms.
    AuditSweep(pbm_lab::audit_sweep::SweepArgs),
    /// The audit on real pneumatic data (MetroPT-3 head, SPEC §8).
    AuditMetro(pbm_lab::metro::MetroArgs),
    /// Print throughput figures (twin, monitor pipeline, generate) and write bench/host.md.
    Bench(pbm_lab::bench::BenchArgs),
    /// Replay a trace or a data set through the monitor pipeline (results CSV, summary, plots).
    Replay(pbm_lab::replay::ReplayArgs),
    /// CAN reports: decode a candump log or interface as the cab display shows it, send, demo log.
    Can(pbm_lab::can_cmd::CanArgs),
    /// Batch least-squares fit of twin parameters per trace (the paper's θ or the fault parameters).
    Fit(pbm_lab::fit::FitArgs),
    /// Accuracy of the online estimator against known truth: table, CSV, scatter plots.
    Estimate(pbm_lab::estimate::EstimateArgs),
    /// Train the paper's three classifiers and ours; quantize ours to int8.
    Train(pbm_ml::train::TrainArgs),
    /// Accuracy and confusion matrices of the trained classifiers on a data set's test split.
    Evaluate(pbm_ml::evaluate::EvaluateArgs),
    /// The main job in one run: fleet data, training, evaluation, CAN replay, audit, report/index.html.
    Demo(pbm_demo::demo::DemoArgs),
}

#[derive(clap::Args)]
struct SimulateArgs {
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
    #[arg(long, default_value_t = 60.0)]
    duration: f64,
    /// Output file (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also write an SVG of the release (pressure from both engines, piston travel).
    #[arg(long)]
    plot: Option<PathBuf>,
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate(args) => cmd_simulate(&args),
        Command::Generate(args) => pbm_lab::generate::run(&args),
        Command::Audit(args) => pbm_lab::audit_plot::run(&args),
        Command::AuditSweep(args) => pbm_lab::audit_sweep::run(&args),
        Command::AuditMetro(args) => pbm_lab::metro::run(&args),
        Command::Bench(args) => pbm_lab::bench::run(&args),
        Command::Replay(args) => pbm_lab::replay::run(&args),
        Command::Can(args) => pbm_lab::can_cmd::run(&args),
        Command::Fit(args) => pbm_lab::fit::run(&args),
        Command::Estimate(args) => pbm_lab::estimate::run(&args),
        Command::Train(args) => pbm_ml::train::run(&args),
        Command::Evaluate(args) => pbm_ml::evaluate::run(&args),
        Command::Demo(args) => pbm_demo::demo::run(&args),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn cmd_simulate(a: &SimulateArgs) -> Result<()> {
    if !(a.duration.is_finite() && a.duration > 0.0 && a.duration <= 3600.0) {
        bail!("--duration must be in (0, 3600] s, got {}", a.duration);
    }
    let params =
        TwinParams::nominal().with_orifice_mm(a.orifice_mm).with_leak_mm(a.leak_mm).with_supply_bar_g(a.supply_bar);
    let trace = simulate(a.engine, &params, a.duration).map_err(|e| anyhow::anyhow!("invalid parameters: {e}"))?;
    if let Some(path) = &a.plot {
        pbm_lab::simulate::write_release_svg(path, &params, a.duration)?;
    }
    let meta = [
        ("source", format!("host-sim simulate --engine {:?}", a.engine).to_lowercase()),
        ("orifice_mm", a.orifice_mm.to_string()),
        ("leak_mm", a.leak_mm.to_string()),
        ("supply_bar", a.supply_bar.to_string()),
    ];
    match &a.out {
        Some(path) => {
            let f = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
            let mut w = std::io::BufWriter::new(f);
            write_csv(&mut w, &trace, &meta)?;
            w.flush()?;
        }
        None => {
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::new(stdout.lock());
            write_csv(&mut w, &trace, &meta)?;
            w.flush()?;
        }
    }
    Ok(())
}
