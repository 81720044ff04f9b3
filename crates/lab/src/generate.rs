//! The fleet data generator: a synthetic data set in the SPEC §7 layout.
//!
//! # What is drawn, and from what
//!
//! - **Fleet** (SPEC §5): `locomotives` locomotives named `loco-01`, `loco-02`, …; each draws
//!   once V0, F0, K, Cf, Fc and Fs as nominal × U(0.95, 1.05) and its regulator setting as
//!   U(7.67, 7.73) bar g, from its own random stream (seed, locomotive index).
//! - **Faults** (SPEC §4): per trace, uniformly and exactly inside the SPEC ranges: `air_leak`
//!   d_leak U(0.5, 1.2) mm; `orifice_block` d_orifice U(0.35, 1.0) mm; `leak_and_block` both;
//!   `low_supply` Ps U(3.5, 7.2) bar g instead of the regulator; `orifice_missing` d_orifice
//!   U(2.5, 4.0) mm. Everything not drawn is the locomotive's (healthy orifice 1.25 mm, no leak,
//!   supply = its regulator).
//! - **Plant**: the f64 [`ReferenceTwin`] (not the fixed-point core twin, so the monitor is not
//!   tested against itself), integrated with [`GENERATE_STEP_S`] (see there for the accuracy).
//! - **Sensor** (SPEC §5): white noise σ = 0.01 bar added to the gauge pressure, then the 12-bit
//!   map [`adc_from_bar`] (rounding, clamping to 0..=4095); 100 Hz, t = 0.00 … 59.99 s.
//!
//! # Locomotives and splits
//!
//! Classifiers are judged on locomotives they were not trained on (SPEC §5). With the default
//! held-out split, the last `test_locomotives` locomotives (default 2 of 6: `loco-05`,
//! `loco-06`) supply only test traces and the others only training traces; traces are dealt to
//! the locomotives of their split round-robin, so every locomotive has the same number of
//! traces of every class. The shared split deals both splits round-robin over all locomotives
//! (a random split, for comparison with the paper).
//!
//! # Determinism
//!
//! Every random number comes from ChaCha8 streams keyed by (seed, what, index): locomotive `i`
//! from (seed, 1, i), trace `k` of class `c` in split `s` from (seed, 2, c, s, k). Traces are
//! computed in parallel but each from its own stream, so the bytes do not depend on the thread
//! count, and a trace does not depend on which other classes or counts were asked for.
//!
//! # Files
//!
//! `manifest.csv` (`file,label,locomotive,split`), `truth.csv` (ground truth of every trace,
//! columns in [`TRUTH_COLUMNS`]) and `traces/{split}/{label}_{k:04}.csv` (`t_s,adc`).

use crate::random::{normal_pair, unit};
use crate::reference::ReferenceTwin;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use pbm::mechanism::Extensions;
use pbm::sensor::adc_from_bar;
use pbm::twin::SAMPLE_PERIOD_S;
use pbm::{BarG, FaultClass, Meters, TwinParams};
use pbm_io::dataset::{write_manifest, ManifestRow, MANIFEST, TRUTH};
use pbm_io::table::CsvFile;
use pbm_io::trace::write_adc_trace;
use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Integration step of the f64 plant when generating, s.
///
/// Chosen with `host-sim bench` (step study): the coarsest step whose worst-case NMSE against
/// the 20 µs reference, over the extreme parameters of every class, stays below 0.05 %. At
/// 1 ms (also the coarsest step `ReferenceTwin::with_step` allows) the worst case measured was
/// 0.0023 % (1.2 mm leak), 20× faster than the 20 µs reference.
pub const GENERATE_STEP_S: f64 = 1e-3;
/// Samples per trace: 60 s at 100 Hz.
pub const TRACE_SAMPLES: usize = 6000;
/// Sensor noise before the ADC, bar (SPEC §5).
pub const NOISE_SIGMA_BAR: f64 = 0.01;
/// Relative manufacturing spread of V0, F0, K, Cf, Fc, Fs (SPEC §5).
pub const SPREAD_REL: f64 = 0.05;
/// Regulator setting range, bar g (SPEC §5).
pub const REGULATOR_BAR_G: (f64, f64) = (7.67, 7.73);
/// Leak diameter range, mm (SPEC §4).
pub const LEAK_MM: (f64, f64) = (0.5, 1.2);
/// Blocked orifice diameter range, mm (SPEC §4).
pub const BLOCK_MM: (f64, f64) = (0.35, 1.0);
/// Low supply range, bar g (SPEC §4).
pub const LOW_SUPPLY_BAR_G: (f64, f64) = (3.5, 7.2);
/// Missing orifice (port-limited) diameter range, mm (SPEC §4).
pub const MISSING_MM: (f64, f64) = (2.5, 4.0);
/// Columns of `truth.csv` (a set with sensor faults adds `sensor_fault`: the faults applied,
/// `;`-joined).
pub const TRUTH_COLUMNS: [&str; 16] = [
    "file",
    "label",
    "locomotive",
    "split",
    "supply_bar_g",
    "orifice_mm",
    "leak_mm",
    "v0_l",
    "f0_n",
    "k_n_per_m",
    "cf",
    "fc_n",
    "fs_n",
    "regulator_bar_g",
    "final_bar_g",
    "final_travel_mm",
];

/// How traces are split between training and test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SplitMode {
    /// Test traces come only from held-out locomotives (the last `test_locomotives`).
    HeldOut,
    /// Both splits use every locomotive (random split).
    Shared,
}

/// What a generated data set holds and how it is drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct GenerateOptions {
    /// Output directory (created; must be empty or absent unless `force`).
    pub out: PathBuf,
    /// Number of locomotives in the fleet.
    pub locomotives: usize,
    /// Training traces per class.
    pub per_class: usize,
    /// Test traces per class.
    pub test_per_class: usize,
    /// Random seed: the same seed gives the same bytes.
    pub seed: u64,
    /// Classes to generate (in any order; duplicates are ignored).
    pub classes: Vec<FaultClass>,
    /// How locomotives are assigned to the splits.
    pub split: SplitMode,
    /// Held-out locomotives for the test split (with [`SplitMode::HeldOut`]).
    pub test_locomotives: usize,
    /// Worker threads (0 = all cores). The output does not depend on it.
    pub threads: usize,
    /// Overwrite a non-empty output directory.
    pub force: bool,
    /// Mechanisms beyond SPEC §2 in every trace's plant ([`pbm::mechanism`]).
    pub effects: Extensions,
    /// Sensor or ADC faults applied to every trace, in order
    /// ([`crate::sensor_faults::FaultSpec`]).
    pub sensor_faults: Vec<crate::sensor_faults::FaultSpec>,
    /// Transducer noise, locomotive spread and regulator range.
    pub conditions: Conditions,
}

impl GenerateOptions {
    /// The paper's data set (SPEC §6) into `out`: six locomotives, 1100 training and 50 test
    /// traces per class of the paper's five, two held-out test locomotives, seed 1.
    pub fn new(out: PathBuf) -> Self {
        Self {
            out,
            locomotives: 6,
            per_class: 1100,
            test_per_class: 50,
            seed: 1,
            classes: FaultClass::PAPER.to_vec(),
            split: SplitMode::HeldOut,
            test_locomotives: 2,
            threads: 0,
            force: false,
            effects: Extensions::NONE,
            sensor_faults: Vec::new(),
            conditions: Conditions::SPEC,
        }
    }
}

/// The nuisance conditions of a data set: transducer noise, locomotive spread, regulator range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditions {
    /// Noise σ, bar.
    pub noise_bar: f64,
    /// Relative spread.
    pub spread: f64,
    /// Regulator range, bar g.
    pub regulator_bar_g: (f64, f64),
}

impl Conditions {
    /// SPEC §5.
    pub const SPEC: Self = Self { noise_bar: NOISE_SIGMA_BAR, spread: SPREAD_REL, regulator_bar_g: REGULATOR_BAR_G };

    /// Checks the conditions are ones the generator can draw from.
    pub fn validate(&self) -> Result<()> {
        let (lo, hi) = self.regulator_bar_g;
        if !(self.noise_bar.is_finite() && (0.0..=1.0).contains(&self.noise_bar)) {
            bail!("transducer noise must be within 0..=1 bar (got {})", self.noise_bar);
        }
        if !(self.spread.is_finite() && (0.0..0.5).contains(&self.spread)) {
            bail!("locomotive spread must be within 0..0.5 (got {})", self.spread);
        }
        if !(lo.is_finite() && hi.is_finite() && 0.5 <= lo && lo <= hi && hi <= 10.0) {
            bail!("the regulator range needs 0.5 ≤ low ≤ high ≤ 10 bar g (got {lo},{hi})");
        }
        Ok(())
    }
}

/// One locomotive of the fleet: its name and healthy parameters (supply = its regulator).
#[derive(Debug, Clone, PartialEq)]
pub struct Locomotive {
    /// Name, `loco-01` …
    pub name: String,
    /// Healthy brake of this locomotive.
    pub params: TwinParams,
}

fn stream(seed: u64, what: u64, a: u64, b: u64) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    for (chunk, word) in key.chunks_exact_mut(8).zip([seed, what, a, b]) {
        chunk.copy_from_slice(&word.to_le_bytes());
    }
    ChaCha8Rng::from_seed(key)
}

fn uniform(rng: &mut impl Rng, (lo, hi): (f64, f64)) -> f64 {
    lo + (hi - lo) * unit(rng)
}

/// The fleet of `n` locomotives for `seed` (SPEC §5 spread).
pub fn fleet(seed: u64, n: usize) -> Vec<Locomotive> {
    fleet_with(seed, n, &Conditions::SPEC)
}

/// The fleet of `n` locomotives for `seed` with the given spread and regulator range.
pub fn fleet_with(seed: u64, n: usize, c: &Conditions) -> Vec<Locomotive> {
    (0..n)
        .map(|i| {
            let mut rng = stream(seed, 1, i as u64, 0);
            let spread = (1.0 - c.spread, 1.0 + c.spread);
            let mut p = TwinParams::nominal();
            p.dead_volume_m3 *= uniform(&mut rng, spread);
            p.preload_n *= uniform(&mut rng, spread);
            p.spring_rate_n_per_m *= uniform(&mut rng, spread);
            p.discharge_coeff *= uniform(&mut rng, spread);
            p.coulomb_n *= uniform(&mut rng, spread);
            p.static_n *= uniform(&mut rng, spread);
            p.supply = BarG(uniform(&mut rng, c.regulator_bar_g));
            Locomotive { name: format!("loco-{:02}", i + 1), params: p }
        })
        .collect()
}

/// The brake of one trace: the locomotive's parameters with the class's fault drawn from `rng`.
pub fn draw_fault(loco: &TwinParams, class: FaultClass, rng: &mut impl Rng) -> TwinParams {
    let mut p = *loco;
    match class {
        FaultClass::Normal => {}
        FaultClass::AirLeak => p.leak = Meters::from_mm(uniform(rng, LEAK_MM)),
        FaultClass::OrificeBlock => p.orifice = Meters::from_mm(uniform(rng, BLOCK_MM)),
        FaultClass::LeakAndBlock => {
            p.leak = Meters::from_mm(uniform(rng, LEAK_MM));
            p.orifice = Meters::from_mm(uniform(rng, BLOCK_MM));
        }
        FaultClass::LowSupply => p.supply = BarG(uniform(rng, LOW_SUPPLY_BAR_G)),
        FaultClass::OrificeMissing => p.orifice = Meters::from_mm(uniform(rng, MISSING_MM)),
    }
    p
}

/// A noise-free simulated release: gauge pressure (bar) and travel (mm) at 100 Hz, sample `i`
/// at `t = i · 10 ms` (sample 0 is the vented chamber at the release command).
pub fn simulate_plant(params: &TwinParams, step_s: f64, samples: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    simulate_plant_with(params, step_s, samples, |_, _| {})
}

/// [`simulate_plant`] with `condition(twin, t_s)` called before each sample: the time-varying
/// conditions of the open-world cases ([`crate::open_world`], through
/// [`ReferenceTwin::retune`]).
pub fn simulate_plant_with(
    params: &TwinParams,
    step_s: f64,
    samples: usize,
    mut condition: impl FnMut(&mut ReferenceTwin, f64),
) -> Result<(Vec<f64>, Vec<f64>)> {
    let mut twin =
        ReferenceTwin::new(params).map_err(|e| anyhow::anyhow!("invalid plant parameters: {e}"))?.with_step(step_s);
    let mut p = Vec::with_capacity(samples);
    let mut x = Vec::with_capacity(samples);
    for i in 0..samples {
        condition(&mut twin, i as f64 * SAMPLE_PERIOD_S);
        p.push(twin.sensor_bar_g());
        x.push(twin.state.x * 1e3);
        twin.advance(SAMPLE_PERIOD_S, true);
    }
    Ok((p, x))
}

/// The sensor of SPEC §5: N(0, σ) noise, then the 12-bit ADC map with clamping.
pub fn sense(pressure_bar_g: &[f64], rng: &mut impl Rng) -> Vec<u16> {
    let noise = transducer_noise(pressure_bar_g.len(), NOISE_SIGMA_BAR, rng);
    pressure_bar_g.iter().zip(noise).map(|(&p, n)| adc_from_bar(BarG(p + n)).0).collect()
}

/// `n` samples of the transducer's white noise of σ `sigma_bar` (pairs of normals from `rng`).
pub fn transducer_noise(n: usize, sigma_bar: f64, rng: &mut impl Rng) -> Vec<f64> {
    let mut out = Vec::with_capacity(n + 1);
    while out.len() < n {
        let (n0, n1) = normal_pair(rng);
        out.extend([sigma_bar * n0, sigma_bar * n1]);
    }
    out.truncate(n);
    out
}

/// One trace to generate.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceJob {
    /// Fault class.
    pub class: FaultClass,
    /// `true` for the test split.
    pub test: bool,
    /// Index within (class, split).
    pub k: usize,
    /// Index into the fleet.
    pub locomotive: usize,
}

impl TraceJob {
    /// Split name.
    pub fn split(&self) -> &'static str {
        if self.test {
            "test"
        } else {
            "train"
        }
    }
    /// Path relative to the data set directory.
    pub fn file(&self) -> String {
        format!("traces/{}/{}_{:04}.csv", self.split(), self.class.label(), self.k)
    }
    /// Random stream of this trace: depends only on (seed, class, split, k).
    pub fn rng(&self, seed: u64) -> ChaCha8Rng {
        stream(seed, 2, self.class as u64, (u64::from(self.test) << 32) | self.k as u64)
    }
    /// Random stream of this trace's sensor faults (separate, so the release is unchanged).
    pub fn fault_rng(&self, seed: u64) -> ChaCha8Rng {
        stream(seed, 3, self.class as u64, (u64::from(self.test) << 32) | self.k as u64)
    }
}

/// Parses class labels (as given on a command line) and canonicalises them
/// ([`canonical_classes`]).
pub fn parse_classes(labels: &[String]) -> Result<Vec<FaultClass>> {
    let mut classes = Vec::new();
    for l in labels {
        let Some(c) = FaultClass::from_label(l.trim()) else {
            let known: Vec<_> = FaultClass::ALL.iter().map(|c| c.label()).collect();
            bail!("unknown class `{l}` (known: {})", known.join(", "));
        };
        classes.push(c);
    }
    canonical_classes(&classes)
}

/// Classes sorted by class code, duplicates removed; at least one.
pub fn canonical_classes(classes: &[FaultClass]) -> Result<Vec<FaultClass>> {
    let mut classes = classes.to_vec();
    classes.sort();
    classes.dedup();
    if classes.is_empty() {
        bail!("no class to generate");
    }
    Ok(classes)
}

/// The jobs of a data set in manifest order: class by class, training then test.
pub fn plan(a: &GenerateOptions, classes: &[FaultClass]) -> Result<Vec<TraceJob>> {
    if a.locomotives == 0 {
        bail!("--locomotives: a fleet needs at least 1 locomotive");
    }
    let (train_locos, test_locos): (Vec<usize>, Vec<usize>) = match a.split {
        SplitMode::Shared => ((0..a.locomotives).collect(), (0..a.locomotives).collect()),
        SplitMode::HeldOut => {
            if a.test_locomotives == 0 || a.test_locomotives >= a.locomotives {
                bail!(
                    "--test-locomotives: held-out test locomotives must be at least 1 and fewer than the fleet (got {} of {})",
                    a.test_locomotives,
                    a.locomotives
                );
            }
            let first_test = a.locomotives - a.test_locomotives;
            ((0..first_test).collect(), (first_test..a.locomotives).collect())
        }
    };
    let mut jobs = Vec::new();
    for &class in classes {
        for (test, count, locos) in [(false, a.per_class, &train_locos), (true, a.test_per_class, &test_locos)] {
            for k in 0..count {
                jobs.push(TraceJob { class, test, k, locomotive: locos[k % locos.len()] });
            }
        }
    }
    Ok(jobs)
}

/// Ground truth of one generated trace (a `truth.csv` row).
#[derive(Debug, Clone, PartialEq)]
pub struct TraceTruth {
    /// The plant's parameters.
    pub params: TwinParams,
    /// The locomotive's regulator setting, bar g.
    pub regulator_bar_g: f64,
    /// Noise-free pressure at the last sample, bar g.
    pub final_bar_g: f64,
    /// Travel at the last sample, mm.
    pub final_travel_mm: f64,
    /// Sensor faults applied (`KIND=VALUE@ONSET`), none for a healthy transducer.
    pub sensor_faults: Vec<String>,
}

/// Simulates one job: its ADC samples and ground truth (SPEC §5 transducer, no sensor fault).
pub fn run_job(
    job: &TraceJob,
    fleet: &[Locomotive],
    seed: u64,
    effects: &Extensions,
) -> Result<(Vec<u16>, TraceTruth)> {
    run_job_with(job, fleet, seed, effects, NOISE_SIGMA_BAR, &[])
}

/// [`run_job`] with a transducer noise of `noise_bar` and sensor faults.
pub fn run_job_with(
    job: &TraceJob,
    fleet: &[Locomotive],
    seed: u64,
    effects: &Extensions,
    noise_bar: f64,
    faults: &[crate::sensor_faults::FaultSpec],
) -> Result<(Vec<u16>, TraceTruth)> {
    let loco = fleet.get(job.locomotive).context("locomotive index out of range")?;
    let mut rng = job.rng(seed);
    let mut params = draw_fault(&loco.params, job.class, &mut rng);
    params.ext = *effects;
    let (p, x) = simulate_plant(&params, GENERATE_STEP_S, TRACE_SAMPLES)?;
    let noise = transducer_noise(p.len(), noise_bar, &mut rng);
    let (adc, applied) = crate::sensor_faults::sense_with_faults(&p, &noise, faults, &mut job.fault_rng(seed));
    let truth = TraceTruth {
        params,
        regulator_bar_g: loco.params.supply.0,
        final_bar_g: p.last().copied().unwrap_or(0.0),
        final_travel_mm: x.last().copied().unwrap_or(0.0),
        sensor_faults: applied.iter().map(|a| a.describe()).collect(),
    };
    Ok((adc, truth))
}

/// The fields of a `truth.csv` row ([`TRUTH_COLUMNS`]), formatted.
pub fn truth_fields(row: &ManifestRow, t: &TraceTruth) -> [String; 16] {
    let p = &t.params;
    [
        row.file.clone(),
        row.label.clone(),
        row.locomotive.clone(),
        row.split.clone(),
        format!("{:.6}", p.supply.0),
        format!("{:.6}", p.orifice.mm()),
        format!("{:.6}", p.leak.mm()),
        format!("{:.6}", p.dead_volume_m3 * 1e3),
        format!("{:.4}", p.preload_n),
        format!("{:.3}", p.spring_rate_n_per_m),
        format!("{:.6}", p.discharge_coeff),
        format!("{:.4}", p.coulomb_n),
        format!("{:.4}", p.static_n),
        format!("{:.6}", t.regulator_bar_g),
        format!("{:.6}", t.final_bar_g),
        format!("{:.4}", t.final_travel_mm),
    ]
}

/// What `generate` produced.
#[derive(Debug, Clone, PartialEq)]
pub struct GenerateSummary {
    /// Traces written.
    pub traces: usize,
    /// Bytes of trace files written.
    pub bytes: u64,
    /// Wall-clock time.
    pub elapsed: Duration,
    /// Worker threads used.
    pub threads: usize,
}

/// Generates a data set; `progress` shows a progress bar on stderr (when it is a terminal).
pub fn generate(a: &GenerateOptions, progress: bool) -> Result<GenerateSummary> {
    generate_with(a, progress, |_, _| Ok(())).map(|(summary, _)| summary)
}

/// [`generate`], calling `per_trace` with each trace's manifest row and ADC samples in the same
/// pass (e.g. to compute features without reading 370 MB back); its results come back in
/// manifest order.
pub fn generate_with<T: Send>(
    a: &GenerateOptions,
    progress: bool,
    per_trace: impl Fn(&ManifestRow, &[u16]) -> Result<T> + Sync,
) -> Result<(GenerateSummary, Vec<T>)> {
    let start = Instant::now();
    let effects = a.effects;
    effects.validate().map_err(|e| anyhow::anyhow!("{e}"))?;
    let conditions = a.conditions;
    conditions.validate()?;
    crate::sensor_faults::check_specs(&a.sensor_faults)?;
    let classes = canonical_classes(&a.classes)?;
    let jobs = plan(a, &classes)?;
    let fleet = fleet_with(a.seed, a.locomotives, &conditions);
    prepare_out_dir(&a.out, a.force)?;
    for split in ["train", "test"] {
        let d = a.out.join("traces").join(split);
        std::fs::create_dir_all(&d).with_context(|| format!("cannot create {}", d.display()))?;
    }

    let bar = if progress { ProgressBar::new(jobs.len() as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} traces {elapsed_precise} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message("generate");
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads).build().context("cannot start worker threads")?;
    let threads = pool.current_num_threads();
    let results: Vec<Result<(ManifestRow, TraceTruth, u64, T)>> = pool.install(|| {
        jobs.par_iter()
            .map(|job| {
                let row = ManifestRow {
                    file: job.file(),
                    label: job.class.label().to_owned(),
                    locomotive: fleet[job.locomotive].name.clone(),
                    split: job.split().to_owned(),
                };
                let (adc, truth) = run_job_with(job, &fleet, a.seed, &effects, conditions.noise_bar, &a.sensor_faults)?;
                let mut meta = vec![
                    ("label", row.label.clone()),
                    ("locomotive", row.locomotive.clone()),
                    ("split", row.split.clone()),
                    ("seed", a.seed.to_string()),
                    ("trace", job.k.to_string()),
                    (
                        "source",
                        format!(
                            "host-sim generate: f64 reference twin (step {} ms), noise {} bar, 12-bit ADC",
                            GENERATE_STEP_S * 1e3,
                            conditions.noise_bar
                        ),
                    ),
                ];
                // One line for all faults, as in truth.csv: a metadata key appears once.
                if !truth.sensor_faults.is_empty() {
                    meta.push(("sensor_fault", truth.sensor_faults.join(";")));
                }
                let mut buf = Vec::with_capacity(adc.len() * 10 + 256);
                write_adc_trace(&mut buf, &meta, &adc)?;
                let path = a.out.join(&row.file);
                std::fs::write(&path, &buf).with_context(|| format!("cannot write {}", path.display()))?;
                let extra = per_trace(&row, &adc)?;
                bar.inc(1);
                Ok((row, truth, buf.len() as u64, extra))
            })
            .collect()
    });
    bar.finish_and_clear();

    let mut rows = Vec::with_capacity(results.len());
    let with_faults = !a.sensor_faults.is_empty();
    let mut truth = CsvFile::create(&a.out.join(TRUTH))?;
    let mut columns = TRUTH_COLUMNS.to_vec();
    if with_faults {
        columns.push("sensor_fault");
    }
    truth.record(columns)?;
    let mut bytes = 0;
    let mut extras = Vec::with_capacity(results.len());
    for r in results {
        let (row, t, n, extra) = r?;
        extras.push(extra);
        let mut fields = truth_fields(&row, &t).to_vec();
        if with_faults {
            fields.push(t.sensor_faults.join(";"));
        }
        truth.record(fields)?;
        bytes += n;
        rows.push(row);
    }
    truth.finish()?;
    write_manifest(&a.out.join(MANIFEST), &rows)?;
    Ok((GenerateSummary { traces: rows.len(), bytes, elapsed: start.elapsed(), threads }, extras))
}

fn prepare_out_dir(out: &Path, force: bool) -> Result<()> {
    if out.exists() {
        if !out.is_dir() {
            bail!("--out {} exists and is not a directory", out.display());
        }
        let non_empty =
            std::fs::read_dir(out).with_context(|| format!("cannot read {}", out.display()))?.next().is_some();
        if non_empty && !force {
            bail!("--out {} is not empty (use --force to overwrite)", out.display());
        }
        let old = out.join("traces");
        if force && old.is_dir() {
            std::fs::remove_dir_all(&old).with_context(|| format!("cannot remove {}", old.display()))?;
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))
}

/// Generates a data set and says what it wrote (stderr).
pub fn run(a: &GenerateOptions) -> Result<()> {
    let s = generate(a, true)?;
    eprintln!(
        "wrote {} traces ({:.1} MB) and {MANIFEST}, {TRUTH} to {} in {:.2} s on {} threads",
        s.traces,
        s.bytes as f64 / 1e6,
        a.out.display(),
        s.elapsed.as_secs_f64(),
        s.threads
    );
    Ok(())
}
