//! The paper's batch fit (SPEC §6, classifier 3): per trace, least squares of the measured
//! pressure against the twin over the whole release, with the twin simulated inside the loop.
//!
//! - **Twin**: the fixed-point core [`pbm::Twin`], rebuilt from each candidate [`TwinParams`]
//!   (one 60 s simulation ≈ 1 ms), started at the release command like the monitor's twin.
//! - **Optimiser**: Nelder–Mead from `argmin` on a scaled parameter vector.
//! - **Cost**: sum of squared pressure errors (bar²) over the valid samples (sensor-fault codes are
//!   left out); candidates the twin refuses (out of range) cost [`INVALID_COST`].
//! - **Goodness of fit**: [`pbm::metrics::nmse_pct`] of the best candidate.
//!
//! Two parameter sets can be fitted ([`FitParams`]): the paper's θ = (K, B, sigma0, sigma1), in
//! log scale around the nominal brake (the reproduction row), and the physical fault
//! parameters (inlet orifice, leak, supply) that the online estimator tracks, for comparing
//! the RLS with a batch fit on the same quantities.

use anyhow::{bail, Result};
use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use pbm::sensor::{bar_from_adc, pressure_from_adc};
use pbm::{AdcCounts, BarG, Meters, Twin, TwinParams};
use pbm_io::dataset::{select, Selection};
use pbm_io::error::{FileError, Skipped};
use std::path::Path;

/// Cost of a candidate the twin refuses.
pub const INVALID_COST: f64 = 1e9;

/// Which parameters the fit frees (the others stay at the base brake's values).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum FitParams {
    /// The paper's θ = (K, B, sigma0, sigma1), log-scaled around the base values.
    Paper,
    /// The fault parameters: inlet orifice (mm), leak (mm), supply (bar g).
    Physical,
}

impl FitParams {
    /// Column names of the fitted parameters.
    pub fn names(self) -> [&'static str; 4] {
        match self {
            Self::Paper => ["k_n_per_m", "b_n_s_per_m", "sigma0_n_per_m", "sigma1_n_s_per_m"],
            Self::Physical => ["orifice_mm", "leak_mm", "supply_bar_g", "-"],
        }
    }

    fn dims(self) -> usize {
        match self {
            Self::Paper => 4,
            Self::Physical => 3,
        }
    }

    /// The brake described by the optimiser's vector `x`.
    fn apply(self, base: &TwinParams, x: &[f64]) -> TwinParams {
        let mut p = *base;
        let get = |i: usize| x.get(i).copied().unwrap_or(0.0);
        match self {
            Self::Paper => {
                p.spring_rate_n_per_m = base.spring_rate_n_per_m * get(0).exp();
                p.viscous_n_s_per_m = base.viscous_n_s_per_m * get(1).exp();
                p.sigma0_n_per_m = base.sigma0_n_per_m * get(2).exp();
                p.sigma1_n_s_per_m = base.sigma1_n_s_per_m * get(3).exp();
            }
            Self::Physical => {
                // |·| folds the simplex back into the physical half-space (a leak of −0.2 mm is
                // the same brake as one of 0.2 mm); the orifice keeps a tiny floor.
                p.orifice = Meters::from_mm(get(0).abs().max(0.01));
                p.leak = Meters::from_mm(get(1).abs());
                p.supply = BarG(get(2));
            }
        }
        p
    }

    /// The fitted values as reported (physical units).
    fn values(self, p: &TwinParams) -> [f64; 4] {
        match self {
            Self::Paper => [p.spring_rate_n_per_m, p.viscous_n_s_per_m, p.sigma0_n_per_m, p.sigma1_n_s_per_m],
            Self::Physical => [p.orifice.mm(), p.leak.mm(), p.supply.0, f64::NAN],
        }
    }

    /// Initial simplex around the base brake.
    fn simplex(self, base: &TwinParams) -> Vec<Vec<f64>> {
        let (x0, steps): (Vec<f64>, Vec<f64>) = match self {
            Self::Paper => (vec![0.0; 4], vec![0.4; 4]),
            Self::Physical => (vec![base.orifice.mm(), base.leak.mm().max(0.3), base.supply.0], vec![-0.4, 0.4, -1.5]),
        };
        let mut s = vec![x0.clone()];
        for (i, step) in steps.iter().enumerate() {
            let mut v = x0.clone();
            v[i] += step;
            s.push(v);
        }
        s
    }
}

/// Simulates the fixed-point twin for `samples` samples from the release command (sample `i` is
/// the state after `i` updates, as in the monitor); gauge bar.
pub fn simulate_twin(params: &TwinParams, samples: usize) -> Result<Vec<f64>, pbm::ParamError> {
    let mut twin = Twin::new(params)?;
    let mut out = Vec::with_capacity(samples);
    let mut p = twin.state().p.0;
    for _ in 0..samples {
        out.push(pbm::PressureQ24(p).to_bar_g().0);
        p = twin.update(true).pressure.0;
    }
    Ok(out)
}

struct Problem<'a> {
    measured: &'a [Option<f64>],
    evaluations: &'a std::sync::atomic::AtomicU64,
    base: TwinParams,
    which: FitParams,
}

impl Problem<'_> {
    fn sse(&self, params: &TwinParams) -> f64 {
        let Ok(model) = simulate_twin(params, self.measured.len()) else {
            return INVALID_COST;
        };
        self.measured.iter().zip(&model).filter_map(|(m, q)| m.map(|m| (m - q) * (m - q))).sum()
    }
}

impl CostFunction for Problem<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, x: &Self::Param) -> Result<Self::Output, ArgminError> {
        self.evaluations.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(self.sse(&self.which.apply(&self.base, x)))
    }
}

/// Result of one batch fit.
#[derive(Debug, Clone, PartialEq)]
pub struct FitResult {
    /// Which parameters were fitted.
    pub which: FitParams,
    /// The fitted brake.
    pub params: TwinParams,
    /// The fitted values in the order of [`FitParams::names`] (NaN where unused).
    pub values: [f64; 4],
    /// Sum of squared errors, bar².
    pub sse: f64,
    /// NMSE of SPEC §6 of the fitted twin, %.
    pub nmse_pct: Option<f64>,
    /// Cost evaluations (twin simulations).
    pub evaluations: u64,
}

/// Measured gauge pressures of an ADC trace (`None` for sensor-fault codes).
pub fn pressures_from_adc(adc: &[u16]) -> Vec<Option<f64>> {
    adc.iter().map(|&c| pressure_from_adc(AdcCounts(c)).ok().map(|_| bar_from_adc(AdcCounts(c)).0)).collect()
}

/// Fewest samples of a release the fit accepts (2 s at 100 Hz, as the audit): a shorter trace
/// shows too little of the release for four parameters, and its NMSE is undefined or meaningless.
pub const MIN_FIT_SAMPLES: usize = 200;

/// Fits `which` to a measured release (gauge bar per 100 Hz sample, `None` = no reading),
/// starting from `base`, with at most `max_iters` Nelder–Mead iterations. A trace shorter than
/// [`MIN_FIT_SAMPLES`] is refused, and so is one whose NMSE is undefined (no sample above
/// 0.2 bar g): a fit never reports a NaN NMSE.
pub fn fit_trace(measured: &[Option<f64>], base: &TwinParams, which: FitParams, max_iters: u64) -> Result<FitResult> {
    if measured.len() < MIN_FIT_SAMPLES {
        bail!(
            "too short to fit: {} sample(s); a fit needs ≥ {MIN_FIT_SAMPLES} (2 s of release at 100 Hz)",
            measured.len()
        );
    }
    if measured.iter().all(Option::is_none) {
        bail!("the trace has no valid pressure sample");
    }
    base.validate().map_err(|e| anyhow::anyhow!("invalid base parameters: {e}"))?;
    let evaluations = std::sync::atomic::AtomicU64::new(0);
    let problem = Problem { measured, evaluations: &evaluations, base: *base, which };
    let solver = NelderMead::new(which.simplex(base)).with_sd_tolerance(1e-9)?;
    let res = Executor::new(problem, solver).configure(|s| s.max_iters(max_iters)).run()?;
    let state = res.state();
    let best = state.get_best_param().cloned().unwrap_or_else(|| vec![0.0; which.dims()]);
    let params = which.apply(base, &best);
    let model = simulate_twin(&params, measured.len()).map_err(|e| anyhow::anyhow!("fitted brake invalid: {e}"))?;
    let (m, q): (Vec<f64>, Vec<f64>) = measured.iter().zip(&model).filter_map(|(m, q)| m.map(|m| (m, *q))).unzip();
    let evaluations = evaluations.load(std::sync::atomic::Ordering::Relaxed);
    let nmse_pct = pbm::metrics::nmse_pct(&m, &q).filter(|v| v.is_finite());
    if nmse_pct.is_none() {
        bail!("no NMSE: no valid sample above 0.2 bar g (no pressure rise: is this a release?)");
    }
    Ok(FitResult { which, values: which.values(&params), params, sse: state.get_best_cost(), nmse_pct, evaluations })
}

/// Measured pressures of a trace (`None` where an ADC count is a sensor fault).
pub fn measured_of(trace: &pbm_io::trace::Trace) -> Vec<Option<f64>> {
    match &trace.samples {
        pbm_io::trace::Samples::Adc(adc) => pressures_from_adc(adc),
        pbm_io::trace::Samples::Bar(p) => p.iter().map(|&v| Some(v)).collect(),
    }
}

/// Options of the fit run.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Parameters to fit.
    pub params: FitParams,
    /// Nelder–Mead iteration limit per trace.
    pub max_iters: u64,
    /// With a data set: fit only traces of this split (train/test).
    pub split: Option<String>,
    /// With a data set: at most this many traces per class (0 = all).
    pub per_class: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self { params: FitParams::Paper, max_iters: 300, split: None, per_class: 0 }
    }
}

/// Fits every selected trace under `input` (a trace file or a data set directory): one CSV row
/// per trace on stdout, a summary of the NMSE on stderr; returns the traces skipped (too short,
/// no NMSE, unreadable: see [`fit_trace`]); fails when no selected trace could be fitted.
pub fn run(input: &Path, a: &FitOptions) -> Result<Skipped> {
    use rayon::prelude::*;
    let base = TwinParams::nominal();
    let selection = Selection { split: a.split.clone(), per_label: a.per_class };
    let (items, mut skipped) = select(input, &selection)?;
    let results: Vec<Result<FitResult, FileError>> = items
        .par_iter()
        .map(|item| {
            let trace = pbm_io::trace::read_release_trace(&item.path)?;
            let measured = measured_of(&trace);
            fit_trace(&measured, &base, a.params, a.max_iters)
                .map_err(|e| FileError::new(&item.name, 0, format!("fit: {e:#}")))
        })
        .collect();
    let names = a.params.names();
    let mut out = csv::Writer::from_writer(std::io::stdout().lock());
    out.write_record(["file", "label", names[0], names[1], names[2], names[3], "nmse_pct", "evaluations"])?;
    let mut nmse = Vec::new();
    for (item, r) in items.iter().zip(results) {
        match r {
            Ok(f) => {
                let v = f.values;
                let n = f.nmse_pct.unwrap_or(f64::NAN);
                nmse.push(n);
                out.write_record([
                    item.name.clone(),
                    item.label.clone().unwrap_or_else(|| "-".into()),
                    format!("{:.6}", v[0]),
                    format!("{:.6}", v[1]),
                    format!("{:.6}", v[2]),
                    format!("{:.6}", v[3]),
                    format!("{n:.3}"),
                    f.evaluations.to_string(),
                ])?;
            }
            Err(e) => skipped.push(e),
        }
    }
    out.flush()?;
    if nmse.is_empty() && !items.is_empty() {
        bail!("no trace could be fitted\n{skipped}");
    }
    if !nmse.is_empty() {
        nmse.sort_by(f64::total_cmp);
        let mean = nmse.iter().sum::<f64>() / nmse.len() as f64;
        eprintln!(
            "fitted {} trace(s) ({:?}): NMSE mean {mean:.3} %, median {:.3} %, max {:.3} %",
            nmse.len(),
            a.params,
            nmse[nmse.len() / 2],
            nmse[nmse.len() - 1]
        );
    }
    Ok(skipped)
}
