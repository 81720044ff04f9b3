//! `host-sim generate`: a synthetic fleet data set in the SPEC §7 layout.
//!
//! # What is drawn, and from what
//!
//! - **Fleet** (SPEC §5): `--locomotives` locomotives named `loco-01`, `loco-02`, …; each draws
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
//! `--split held-out`, the last `--test-locomotives` locomotives (default 2 of 6: `loco-05`,
//! `loco-06`) supply only test traces and the others only training traces; traces are dealt to
//! the locomotives of their split round-robin, so every locomotive has the same number of
//! traces of every class. `--split shared` deals both splits round-robin over all locomotives
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
//! columns in [`TRUTH_HEADER`]) and `traces/{split}/{label}_{k:04}.csv` (`t_s,adc`).

use crate::random::{normal_pair, unit};
use crate::reference::ReferenceTwin;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use pbm::sensor::adc_from_bar;
use pbm::twin::SAMPLE_PERIOD_S;
use pbm::{BarG, FaultClass, Meters, TwinParams};
use pbm_io::dataset::{write_manifest, ManifestRow, MANIFEST, TRUTH};
use pbm_io::trace::write_adc_trace;
use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use rayon::prelude::*;
use std::io::Write;
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
/// Columns of `truth.csv`.
pub const TRUTH_HEADER: &str = "file,label,locomotive,split,supply_bar_g,orifice_mm,leak_mm,v0_l,f0_n,k_n_per_m,cf,\
fc_n,fs_n,regulator_bar_g,final_bar_g,final_travel_mm";

/// How traces are split between training and test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SplitMode {
    /// Test traces come only from held-out locomotives (the last `--test-locomotives`).
    HeldOut,
    /// Both splits use every locomotive (random split).
    Shared,
}

/// Options of `host-sim generate`.
#[derive(Debug, Clone, clap::Args)]
pub struct GenerateArgs {
    /// Output directory (created; must be empty or absent unless --force).
    #[arg(long)]
    pub out: PathBuf,
    /// Number of locomotives in the fleet.
    #[arg(long, default_value_t = 6)]
    pub locomotives: usize,
    /// Training traces per class.
    #[arg(long, default_value_t = 1100)]
    pub per_class: usize,
    /// Test traces per class.
    #[arg(long, default_value_t = 50)]
    pub test_per_class: usize,
    /// Random seed: the same seed gives the same bytes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Classes to generate (comma-separated labels; `orifice_missing` allowed).
    #[arg(long, value_delimiter = ',', default_values_t = FaultClass::PAPER.map(|c| c.label().to_owned()))]
    pub classes: Vec<String>,
    /// How locomotives are assigned to the splits.
    #[arg(long, value_enum, default_value_t = SplitMode::HeldOut)]
    pub split: SplitMode,
    /// Held-out locomotives for the test split (with --split held-out).
    #[arg(long, default_value_t = 2)]
    pub test_locomotives: usize,
    /// Worker threads (0 = all cores). The output does not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Overwrite a non-empty output directory.
    #[arg(long)]
    pub force: bool,
    /// Plant effect NAME=VALUE (repeatable), e.g. `transport_delay=0.1` (s: the valve opens late);
    /// the names, units and ranges are those of the audit's mechanisms.
    #[arg(long = "effect", value_parser = parse_effect_arg)]
    pub effects: Vec<(String, f64)>,
    /// Sensor or ADC fault KIND[=VALUE][@ONSET_S|@random] on every trace (repeatable, applied in
    /// order): frozen, dead[=BAR], noisy[=SIGMA_BAR], spikes[=FRACTION], dropouts[=P],
    /// lost_resolution[=BITS], clipped[=BAR], impossible_rate[=STEP_BAR],
    /// implausible_level[=GAIN], offset[=BAR], open_circuit, short_circuit. The manifest label
    /// stays the release's true class; the fault is in the trace's `# sensor_fault:` metadata
    /// and truth.csv's `sensor_fault` column. Without @ONSET the onset is drawn per trace in
    /// 1..50 s.
    #[arg(long = "sensor-fault", value_parser = crate::sensor_faults::parse_spec)]
    pub sensor_faults: Vec<crate::sensor_faults::FaultSpec>,
    /// Transducer noise before the ADC, σ in bar (SPEC §5: 0.01).
    #[arg(long, default_value_t = NOISE_SIGMA_BAR)]
    pub noise_bar: f64,
    /// Relative manufacturing spread of V0, F0, K, Cf, Fc and Fs per locomotive (SPEC §5: 0.05).
    #[arg(long, default_value_t = SPREAD_REL)]
    pub spread: f64,
    /// Range of the locomotives' regulator settings, LO,HI in bar g (SPEC §5: 7.67,7.73).
    #[arg(long, value_delimiter = ',', default_values_t = [REGULATOR_BAR_G.0, REGULATOR_BAR_G.1])]
    pub regulator_bar: Vec<f64>,
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

    /// From the command line, checked.
    pub fn from_args(a: &GenerateArgs) -> Result<Self> {
        let (lo, hi) = match a.regulator_bar[..] {
            [lo, hi] => (lo, hi),
            _ => bail!("--regulator-bar takes LO,HI"),
        };
        if !(a.noise_bar.is_finite() && (0.0..=1.0).contains(&a.noise_bar)) {
            bail!("--noise-bar must be within 0..=1 bar (got {})", a.noise_bar);
        }
        if !(a.spread.is_finite() && (0.0..0.5).contains(&a.spread)) {
            bail!("--spread must be within 0..0.5 (got {})", a.spread);
        }
        if !(lo.is_finite() && hi.is_finite() && 0.5 <= lo && lo <= hi && hi <= 10.0) {
            bail!("--regulator-bar needs 0.5 ≤ LO ≤ HI ≤ 10 bar g (got {lo},{hi})");
        }
        Ok(Self { noise_bar: a.noise_bar, spread: a.spread, regulator_bar_g: (lo, hi) })
    }
}

impl GenerateArgs {
    /// The command-line defaults with output directory `out` (for tests and other tools).
    pub fn with_defaults(out: PathBuf) -> Self {
        #[derive(clap::Parser)]
        struct Wrapper {
            #[command(flatten)]
            args: GenerateArgs,
        }
        let mut out_arg = std::ffi::OsString::from("--out=");
        out_arg.push(out.as_os_str());
        match <Wrapper as clap::Parser>::try_parse_from([std::ffi::OsString::from("generate"), out_arg]) {
            Ok(w) => w.args,
            // Only a change that breaks the defaults themselves can get here.
            Err(e) => unreachable!("GenerateArgs defaults do not parse: {e}"),
        }
    }
}

fn parse_effect_arg(s: &str) -> Result<(String, f64), String> {
    let (name, value) = s.split_once('=').ok_or_else(|| format!("expected NAME=VALUE, got `{s}`"))?;
    let value: f64 = value.trim().parse().map_err(|_| format!("effect `{name}`: `{value}` is not a number"))?;
    if !value.is_finite() {
        return Err(format!("effect `{name}`: value must be finite"));
    }
    Ok((name.trim().to_owned(), value))
}

/// Plant effects beyond SPEC §2 applied while generating (the hook for `--effect`), from the
/// library of [`crate::plant`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[non_exhaustive]
pub struct PlantEffects {
    /// Mechanisms applied to every trace's plant.
    pub ext: pbm::mechanism::Extensions,
}

impl PlantEffects {
    /// Validates `--effect NAME=VALUE` pairs.
    pub fn from_args(effects: &[(String, f64)]) -> Result<Self> {
        Ok(Self { ext: crate::plant::extensions_from_pairs(effects)? })
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
    let mut twin =
        ReferenceTwin::new(params).map_err(|e| anyhow::anyhow!("invalid plant parameters: {e}"))?.with_step(step_s);
    let mut p = Vec::with_capacity(samples);
    let mut x = Vec::with_capacity(samples);
    for _ in 0..samples {
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

/// Parses and canonicalises `--classes` (sorted by class code, duplicates removed).
pub fn parse_classes(labels: &[String]) -> Result<Vec<FaultClass>> {
    let mut classes = Vec::new();
    for l in labels {
        let Some(c) = FaultClass::from_label(l.trim()) else {
            let known: Vec<_> = FaultClass::ALL.iter().map(|c| c.label()).collect();
            bail!("unknown class `{l}` (known: {})", known.join(", "));
        };
        classes.push(c);
    }
    classes.sort();
    classes.dedup();
    if classes.is_empty() {
        bail!("--classes is empty");
    }
    Ok(classes)
}

/// The jobs of a data set in manifest order: class by class, training then test.
pub fn plan(a: &GenerateArgs, classes: &[FaultClass]) -> Result<Vec<TraceJob>> {
    if a.locomotives == 0 {
        bail!("--locomotives must be at least 1");
    }
    let (train_locos, test_locos): (Vec<usize>, Vec<usize>) = match a.split {
        SplitMode::Shared => ((0..a.locomotives).collect(), (0..a.locomotives).collect()),
        SplitMode::HeldOut => {
            if a.test_locomotives == 0 || a.test_locomotives >= a.locomotives {
                bail!(
                    "--split held-out needs 1 ≤ --test-locomotives < --locomotives (got {} of {})",
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
    effects: &PlantEffects,
) -> Result<(Vec<u16>, TraceTruth)> {
    run_job_with(job, fleet, seed, effects, NOISE_SIGMA_BAR, &[])
}

/// [`run_job`] with a transducer noise of `noise_bar` and sensor faults.
pub fn run_job_with(
    job: &TraceJob,
    fleet: &[Locomotive],
    seed: u64,
    effects: &PlantEffects,
    noise_bar: f64,
    faults: &[crate::sensor_faults::FaultSpec],
) -> Result<(Vec<u16>, TraceTruth)> {
    let loco = fleet.get(job.locomotive).context("locomotive index out of range")?;
    let mut rng = job.rng(seed);
    let mut params = draw_fault(&loco.params, job.class, &mut rng);
    params.ext = effects.ext;
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

/// A `truth.csv` row (without newline).
pub fn truth_row(row: &ManifestRow, t: &TraceTruth) -> String {
    let p = &t.params;
    format!(
        "{},{},{},{},{:.6},{:.6},{:.6},{:.6},{:.4},{:.3},{:.6},{:.4},{:.4},{:.6},{:.6},{:.4}",
        row.file,
        row.label,
        row.locomotive,
        row.split,
        p.supply.0,
        p.orifice.mm(),
        p.leak.mm(),
        p.dead_volume_m3 * 1e3,
        p.preload_n,
        p.spring_rate_n_per_m,
        p.discharge_coeff,
        p.coulomb_n,
        p.static_n,
        t.regulator_bar_g,
        t.final_bar_g,
        t.final_travel_mm
    )
}

/// A `truth.csv` row with the `sensor_fault` column (`;`-joined, empty when none).
pub fn truth_row_with_faults(row: &ManifestRow, t: &TraceTruth) -> String {
    format!("{},{}", truth_row(row, t), t.sensor_faults.join(";"))
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
pub fn generate(a: &GenerateArgs, progress: bool) -> Result<GenerateSummary> {
    generate_with(a, progress, |_, _| Ok(())).map(|(summary, _)| summary)
}

/// [`generate`], calling `per_trace` with each trace's manifest row and ADC samples in the same
/// pass (e.g. to compute features without reading 370 MB back); its results come back in
/// manifest order.
pub fn generate_with<T: Send>(
    a: &GenerateArgs,
    progress: bool,
    per_trace: impl Fn(&ManifestRow, &[u16]) -> Result<T> + Sync,
) -> Result<(GenerateSummary, Vec<T>)> {
    let start = Instant::now();
    let effects = PlantEffects::from_args(&a.effects)?;
    let conditions = Conditions::from_args(a)?;
    crate::sensor_faults::check_specs(&a.sensor_faults)?;
    let classes = parse_classes(&a.classes)?;
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
                meta.extend(truth.sensor_faults.iter().map(|f| ("sensor_fault", f.clone())));
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
    let mut truth = String::from(TRUTH_HEADER);
    if with_faults {
        truth.push_str(",sensor_fault");
    }
    truth.push('\n');
    let mut bytes = 0;
    let mut extras = Vec::with_capacity(results.len());
    for r in results {
        let (row, t, n, extra) = r?;
        extras.push(extra);
        truth.push_str(&if with_faults { truth_row_with_faults(&row, &t) } else { truth_row(&row, &t) });
        truth.push('\n');
        bytes += n;
        rows.push(row);
    }
    let mut manifest = Vec::new();
    write_manifest(&mut manifest, &rows)?;
    write_file(&a.out.join(MANIFEST), &manifest)?;
    write_file(&a.out.join(TRUTH), truth.as_bytes())?;
    Ok((GenerateSummary { traces: rows.len(), bytes, elapsed: start.elapsed(), threads }, extras))
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut f = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    f.write_all(bytes).with_context(|| format!("cannot write {}", path.display()))
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

/// `host-sim generate`.
pub fn run(a: &GenerateArgs) -> Result<()> {
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
