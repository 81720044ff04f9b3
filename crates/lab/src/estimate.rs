//! `host-sim estimate`: accuracy of the online estimator on data with known truth.
//!
//! Every trace runs through [`pbm::monitor::Monitor::update`] (the firmware's entry point) and
//! the estimates after every sample are kept. Per parameter — equivalent inlet orifice, leak
//! and supply — the table gives the error of the final RLS estimate against the truth, the
//! error of the batch fit of the same parameters ([`crate::fit`], `Physical`) against the truth,
//! and the time at which the RLS estimate settles within 10 % for good.
//!
//! # Truth the estimator is judged against
//!
//! Only `Cf · A / V0` of an orifice enters the pressure equations, so no pressure-only method can
//! separate a locomotive's ±5 % spread of Cf and V0 from its orifice area. Diameters are therefore
//! compared with the *effective* truth `d · √((Cf/Cf₀)(V0₀/V0))` (nominal Cf₀ = 0.8, V0₀ = 3 L),
//! the diameter a nominal brake would need for the same flow. The raw truth is kept in the CSV.
//!
//! # Settling
//!
//! The settling time of a parameter is the first time after which the estimate exists and stays
//! within 10 % of the truth until the end of the trace; the band is at least 0.05 mm for the
//! diameters (10 % of the smallest leak of SPEC §4) so that a truth of 0 (no leak) has a band.
//! Never settled: `-` in the CSV, counted in the table.
//!
//! # Data
//!
//! A data set made by `host-sim generate` (`manifest.csv`, `truth.csv`, ADC traces), or, with
//! `--synthetic N`, N traces per class drawn in memory by the same generator code.

use crate::fit::{fit_trace, pressures_from_adc, FitParams};
use crate::generate::{fleet, run_job, TraceJob};
use anyhow::{bail, Context, Result};
use pbm::estimator::Estimates;
use pbm::monitor::Monitor;
use pbm::twin::SAMPLE_PERIOD_S;
use pbm::{AdcCounts, FaultClass, TwinParams};
use pbm_io::dataset::{Dataset, ManifestRow, TRUTH};
use pbm_io::error::{FileError, Skipped};
use pbm_io::table::{read_rows, CsvFile};
use rayon::prelude::*;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The estimated parameters compared with the truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Param {
    /// Equivalent inlet orifice diameter, mm.
    Orifice,
    /// Equivalent leak diameter, mm.
    Leak,
    /// Supply pressure, bar g.
    Supply,
}

impl Param {
    /// All compared parameters.
    pub const ALL: [Self; 3] = [Self::Orifice, Self::Leak, Self::Supply];

    /// Column name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Orifice => "orifice_mm",
            Self::Leak => "leak_mm",
            Self::Supply => "supply_bar_g",
        }
    }

    /// The RLS estimate of this parameter.
    pub fn of(self, e: &Estimates) -> Option<f64> {
        match self {
            Self::Orifice => e.orifice_mm,
            Self::Leak => e.leak_mm,
            Self::Supply => e.supply_bar_g,
        }
        .map(f64::from)
    }

    /// The settling band around `truth`.
    pub fn band(self, truth: f64) -> f64 {
        match self {
            Self::Orifice | Self::Leak => (0.1 * truth.abs()).max(0.05),
            Self::Supply => 0.1 * truth.abs(),
        }
    }
}

/// Ground truth of one trace (the columns of `truth.csv` the estimator is judged on, by name).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
pub struct Truth {
    /// File (relative to the data set) or synthetic name.
    pub file: String,
    /// Class label.
    pub label: String,
    /// Supply, bar g.
    pub supply_bar_g: f64,
    /// Inlet orifice diameter, mm.
    pub orifice_mm: f64,
    /// Leak diameter, mm.
    pub leak_mm: f64,
    /// Dead volume, L.
    pub v0_l: f64,
    /// Discharge coefficient.
    pub cf: f64,
}

impl Truth {
    /// From the plant parameters of a trace.
    pub fn from_params(file: String, label: String, p: &TwinParams) -> Self {
        Self {
            file,
            label,
            supply_bar_g: p.supply.0,
            orifice_mm: p.orifice.mm(),
            leak_mm: p.leak.mm(),
            v0_l: p.dead_volume_m3 * 1e3,
            cf: p.discharge_coeff,
        }
    }

    /// Diameter a nominal brake (Cf 0.8, V0 3 L) needs for the same conductance.
    fn effective(&self, d_mm: f64) -> f64 {
        let n = TwinParams::nominal();
        d_mm * ((self.cf / n.discharge_coeff) * (n.dead_volume_m3 * 1e3 / self.v0_l)).sqrt()
    }

    /// The value the estimator is judged against (module docs).
    pub fn value(&self, p: Param) -> f64 {
        match p {
            Param::Orifice => self.effective(self.orifice_mm),
            Param::Leak => self.effective(self.leak_mm),
            Param::Supply => self.supply_bar_g,
        }
    }
}

/// Reads `truth.csv` (columns by name: file, label, supply_bar_g, orifice_mm, leak_mm, v0_l, cf;
/// others ignored).
pub fn read_truth(data: &Dataset) -> Result<HashMap<String, Truth>, FileError> {
    let path = data.side_file(TRUTH)?;
    let rows: Vec<(usize, Truth)> = read_rows(&path)?;
    Ok(rows.into_iter().map(|(_, t)| (t.file.clone(), t)).collect())
}

/// What the estimator did on one trace.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseResult {
    /// The truth.
    pub truth: Truth,
    /// Estimates after the last sample.
    pub last: Estimates,
    /// Settling time per parameter ([`Param::ALL`] order), s.
    pub settle_s: [Option<f64>; 3],
    /// Batch fit of (orifice, leak, supply), if run.
    pub batch: Option<[f64; 3]>,
    /// NMSE of the batch fit, %.
    pub batch_nmse_pct: Option<f64>,
}

impl CaseResult {
    /// Final RLS estimate of `p`.
    pub fn rls(&self, p: Param) -> Option<f64> {
        p.of(&self.last)
    }
}

/// Runs the monitor over an ADC trace (valve open throughout) and returns the estimates after
/// every sample.
pub fn track(adc: &[u16]) -> Result<Vec<Estimates>> {
    let mut m = Monitor::new(&TwinParams::nominal()).map_err(|e| anyhow::anyhow!("monitor: {e}"))?;
    Ok(adc.iter().map(|&c| m.update(AdcCounts(c), true).estimates).collect())
}

/// Settling time of `p` in `track` against `truth` (module docs).
pub fn settle_time(track: &[Estimates], p: Param, truth: f64) -> Option<f64> {
    let band = p.band(truth);
    let inside = |e: &Estimates| p.of(e).is_some_and(|v| (v - truth).abs() <= band);
    if !track.last().is_some_and(inside) {
        return None;
    }
    let first_good = track.iter().rposition(|e| !inside(e)).map_or(0, |i| i + 1);
    Some(first_good as f64 * SAMPLE_PERIOD_S)
}

/// Evaluates one trace: RLS track, settling, and (with `batch_iters > 0`) the batch fit.
pub fn evaluate(truth: Truth, adc: &[u16], batch_iters: u64) -> Result<CaseResult> {
    let tr = track(adc)?;
    let last = tr.last().copied().unwrap_or(Estimates::NONE);
    let settle_s = Param::ALL.map(|p| settle_time(&tr, p, truth.value(p)));
    let (batch, batch_nmse_pct) = if batch_iters > 0 {
        let measured = pressures_from_adc(adc);
        let f = fit_trace(&measured, &TwinParams::nominal(), FitParams::Physical, batch_iters)?;
        // Report the batch diameters the way the RLS reports them: for the nominal Cf and V0.
        (Some([f.values[0], f.values[1], f.values[2]]), f.nmse_pct)
    } else {
        (None, None)
    };
    Ok(CaseResult { truth, last, settle_s, batch, batch_nmse_pct })
}

/// `n` synthetic traces per class (in memory, same generator code as `host-sim generate`).
pub fn synthetic_cases(classes: &[FaultClass], n: usize, seed: u64) -> Result<Vec<(Truth, Vec<u16>)>> {
    let locos = fleet(seed, 6);
    let jobs: Vec<TraceJob> = classes
        .iter()
        .flat_map(|&class| (0..n).map(move |k| TraceJob { class, test: true, k, locomotive: k % 6 }))
        .collect();
    jobs.par_iter()
        .map(|job| {
            let (adc, t) = run_job(job, &locos, seed, &pbm::mechanism::Extensions::NONE)?;
            Ok((Truth::from_params(job.file(), job.class.label().to_owned(), &t.params), adc))
        })
        .collect()
}

/// Options of the estimate run.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateOptions {
    /// A generated data set directory (with `truth.csv`; `None` with `synthetic`).
    pub dataset: Option<PathBuf>,
    /// Write the scatter plots (SVG) and estimates.csv here.
    pub plot: Option<PathBuf>,
    /// Instead of a data set: this many synthetic traces per class.
    pub synthetic: Option<usize>,
    /// Seed of the synthetic traces.
    pub seed: u64,
    /// With a data set: only this split (train/test).
    pub split: String,
    /// With a data set: at most this many traces per class (0 = all).
    pub per_class: usize,
    /// Nelder–Mead iterations of the batch fit per trace (0 = no batch fit).
    pub batch_iters: u64,
}

impl Default for EstimateOptions {
    fn default() -> Self {
        Self {
            dataset: None,
            plot: None,
            synthetic: None,
            seed: 7,
            split: "test".to_owned(),
            per_class: 20,
            batch_iters: 200,
        }
    }
}

/// A trace's ground truth and its ADC counts.
type TruthAndCounts = (Truth, Vec<u16>);

/// The selected traces of a data set with their truth; a trace without truth or unreadable is
/// skipped with its reason.
fn load_dataset(dir: &Path, split: &str, per_class: usize) -> Result<(Vec<TruthAndCounts>, Skipped)> {
    let data = Dataset::open(dir)?;
    let truth = read_truth(&data)?;
    let mut count = HashMap::<String, usize>::new();
    let chosen: Vec<&ManifestRow> = data
        .rows()
        .iter()
        .filter(|r| split.is_empty() || r.split == split)
        .filter(|r| {
            let n = count.entry(r.label.clone()).or_default();
            *n += 1;
            per_class == 0 || *n <= per_class
        })
        .collect();
    let loaded: Vec<Result<(Truth, Vec<u16>), FileError>> = chosen
        .par_iter()
        .map(|r| {
            let t = truth.get(&r.file).ok_or_else(|| FileError::new(&r.file, 0, format!("no row in {TRUTH}")))?;
            let trace = data.read_trace(r)?;
            Ok((t.clone(), trace.adc_counts()))
        })
        .collect();
    let mut skipped = Skipped::of(data.refused());
    let cases = loaded.into_iter().filter_map(|r| r.map_err(|e| skipped.push(e)).ok()).collect();
    Ok((cases, skipped))
}

fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// The accuracy table (text) of a set of results.
pub fn table(results: &[CaseResult]) -> String {
    let mut labels: Vec<&str> = results.iter().map(|r| r.truth.label.as_str()).collect();
    labels.sort_by_key(|l| FaultClass::from_label(l).map_or(99, |c| c as u8));
    labels.dedup();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<16} {:<13} {:>4} | {:>9} {:>9} {:>6} | {:>9} {:>9} | {:>7} {:>7} {:>6}",
        "class",
        "parameter",
        "n",
        "rls_med",
        "rls_p90",
        "none",
        "batch_med",
        "batch_p90",
        "set_med",
        "set_p90",
        "unset"
    );
    for label in labels {
        let rs: Vec<&CaseResult> = results.iter().filter(|r| r.truth.label == label).collect();
        for (i, p) in Param::ALL.into_iter().enumerate() {
            let mut rls: Vec<f64> = rs.iter().filter_map(|r| r.rls(p).map(|v| (v - r.truth.value(p)).abs())).collect();
            let none = rs.len() - rls.len();
            let mut batch: Vec<f64> =
                rs.iter().filter_map(|r| r.batch.map(|b| (b[i] - r.truth.value(p)).abs())).collect();
            let mut settle: Vec<f64> = rs.iter().filter_map(|r| r.settle_s[i]).collect();
            let unset = rs.len() - settle.len();
            let _ = writeln!(
                s,
                "{:<16} {:<13} {:>4} | {:>9.4} {:>9.4} {:>6} | {:>9.4} {:>9.4} | {:>7.1} {:>7.1} {:>6}",
                label,
                p.name(),
                rs.len(),
                quantile(&mut rls, 0.5),
                quantile(&mut rls, 0.9),
                none,
                quantile(&mut batch, 0.5),
                quantile(&mut batch, 0.9),
                quantile(&mut settle, 0.5),
                quantile(&mut settle, 0.9),
                unset
            );
        }
    }
    s.push_str(
        "errors: |estimate − truth| (mm for diameters, bar for supply; diameters vs the effective truth);\n\
         none: no RLS estimate at the end; set_*: settling time within 10 % (s); unset: never settled\n",
    );
    s
}

/// Per-trace CSV of the results.
pub fn write_results_csv(path: &Path, results: &[CaseResult]) -> Result<()> {
    let mut f = CsvFile::create(path)?;
    f.record([
        "file",
        "label",
        "truth_orifice_mm",
        "truth_leak_mm",
        "truth_supply_bar_g",
        "eff_orifice_mm",
        "eff_leak_mm",
        "rls_orifice_mm",
        "rls_leak_mm",
        "rls_supply_bar_g",
        "rls_inflow_bar_s",
        "rls_plateau_bar_g",
        "batch_orifice_mm",
        "batch_leak_mm",
        "batch_supply_bar_g",
        "batch_nmse_pct",
        "settle_orifice_s",
        "settle_leak_s",
        "settle_supply_s",
    ])?;
    let o = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.4}"));
    for r in results {
        let t = &r.truth;
        let e = &r.last;
        let b = r.batch.map(|b| b.map(Some)).unwrap_or([None; 3]);
        f.record([
            t.file.clone(),
            t.label.clone(),
            format!("{:.4}", t.orifice_mm),
            format!("{:.4}", t.leak_mm),
            format!("{:.4}", t.supply_bar_g),
            format!("{:.4}", t.value(Param::Orifice)),
            format!("{:.4}", t.value(Param::Leak)),
            o(Param::Orifice.of(e)),
            o(Param::Leak.of(e)),
            o(Param::Supply.of(e)),
            o(e.inflow_rate_bar_s.map(f64::from)),
            o(e.plateau_bar_g.map(f64::from)),
            o(b[0]),
            o(b[1]),
            o(b[2]),
            o(r.batch_nmse_pct),
            o(r.settle_s[0]),
            o(r.settle_s[1]),
            o(r.settle_s[2]),
        ])?;
    }
    f.finish()
}

/// One colour per class in [`FaultClass`] order, then "other": the Okabe–Ito palette, so that
/// the five classes stay distinct for colour-blind readers and in print (the former palette
/// drew normal and low supply in two near-identical greens).
const CLASS_COLOURS: [plotters::style::RGBColor; 6] = [
    pbm_report::chart::OKABE_ITO[0],
    pbm_report::chart::OKABE_ITO[1],
    pbm_report::chart::OKABE_ITO[2],
    pbm_report::chart::OKABE_ITO[4],
    pbm_report::chart::OKABE_ITO[3],
    pbm_report::chart::OKABE_ITO[7],
];

/// Writes one scatter plot (SVG) of the final RLS estimates of `x` against `y`, by class.
pub fn scatter_svg(path: &Path, results: &[CaseResult], x: Param, y: Param) -> Result<usize> {
    use plotters::prelude::*;
    let points: Vec<(f64, f64, usize)> = results
        .iter()
        .filter_map(|r| {
            let c = FaultClass::from_label(&r.truth.label).map_or(5, |c| c as usize).min(5);
            Some((r.rls(x)?, r.rls(y)?, c))
        })
        .collect();
    let range = |v: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
        if lo.is_finite() && hi.is_finite() {
            let pad = ((hi - lo) * 0.05).max(0.05);
            (lo - pad)..(hi + pad)
        } else {
            0.0..1.0
        }
    };
    let xr = range(&mut points.iter().map(|p| p.0));
    let yr = range(&mut points.iter().map(|p| p.1));
    let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plotting {}: {e}", path.display());
    let root = SVGBackend::new(path, (720, 540)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let present: Vec<(usize, &FaultClass)> =
        FaultClass::ALL.iter().enumerate().filter(|(ci, _)| points.iter().any(|p| p.2 == *ci)).collect();
    let legend: Vec<pbm_report::chart::LegendEntry<'_>> = present
        .iter()
        .map(|&(ci, class)| pbm_report::chart::LegendEntry {
            label: class.label(),
            color: CLASS_COLOURS[ci],
            swatch: pbm_report::chart::Swatch::Dot,
        })
        .collect();
    let title = format!("RLS estimates: {} vs {}", y.name(), x.name());
    let plot_area = pbm_report::chart::title_and_legend(&root, &title, &legend)?;
    let mut chart = ChartBuilder::on(&plot_area)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(xr, yr)
        .map_err(|e| err(&e))?;
    chart.configure_mesh().x_desc(x.name()).y_desc(y.name()).draw().map_err(|e| err(&e))?;
    for &(ci, _) in &present {
        let colour = CLASS_COLOURS[ci];
        let pts = points.iter().filter(|p| p.2 == ci).map(|p| Circle::new((p.0, p.1), 3, colour.filled()));
        chart.draw_series(pts).map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(points.len())
}

/// Scores the online estimator (and the batch fit) against the truth: the table on stdout,
/// plots and CSV when asked; returns the traces skipped.
pub fn run(a: &EstimateOptions) -> Result<Skipped> {
    let (cases, skipped) = match (&a.dataset, a.synthetic) {
        (Some(dir), None) => load_dataset(dir, &a.split, a.per_class)?,
        (None, Some(n)) => (synthetic_cases(&FaultClass::PAPER, n, a.seed)?, Skipped::none()),
        _ => bail!("give either a data set directory or a number of synthetic traces per class"),
    };
    if cases.is_empty() {
        bail!("no traces selected");
    }
    let results: Vec<CaseResult> =
        cases.into_par_iter().map(|(t, adc)| evaluate(t, &adc, a.batch_iters)).collect::<Result<_>>()?;
    print!("{}", table(&results));
    if let Some(dir) = &a.plot {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        write_results_csv(&dir.join("estimates.csv"), &results)?;
        for (x, y) in [(Param::Orifice, Param::Leak), (Param::Orifice, Param::Supply), (Param::Leak, Param::Supply)] {
            let path = dir.join(format!("scatter_{}_{}.svg", x.name(), y.name()));
            let n = scatter_svg(&path, &results, x, y)?;
            eprintln!("wrote {} ({n} points)", path.display());
        }
        eprintln!("wrote {}", dir.join("estimates.csv").display());
    }
    Ok(skipped)
}
