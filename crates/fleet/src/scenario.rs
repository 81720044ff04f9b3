//! The slow-degradation scenario: a fleet whose brakes wear over many releases, to measure how
//! early the trend warning comes.
//!
//! Each locomotive is drawn exactly as `host-sim generate` draws one (SPEC §5 manufacturing
//! spread and regulator setting, [`pbm_lab::generate::fleet`]) and then released `releases`
//! times. A *healthy* locomotive stays at its own parameters; a *leaking* one grows a leak to
//! atmosphere linearly from 0 at release `onset` to `leak_end_mm` at the last release; a
//! *clogging* one has its release orifice shrink linearly from 1.25 mm at `onset` to
//! `orifice_end_mm`; a *failing-transducer* one keeps a healthy brake and its pressure
//! transducer shows the generator's sensor fault ([`DEFAULT_SENSOR_FAULT`]) from `onset` on. The
//! plant is the f64 reference twin and the sensor is SPEC §5's (σ =
//! 0.01 bar noise, 12-bit ADC), through the generator's own functions, so a degraded release is
//! drawn like any generated release.
//!
//! Ground-truth labels follow the SPEC §4 class edges ([`LEAK_MM`]`.0` = 0.5 mm for a leak,
//! [`BLOCK_MM`]`.1` = 1.0 mm for a blocked orifice): a release is labelled with the fault once
//! its parameter has crossed the edge.
//!
//! Determinism: release `k` of locomotive `i` draws its noise from a ChaCha8 stream keyed by
//! (seed, 10, i, k), so the bytes depend on neither thread count nor fleet size.

use anyhow::{bail, Context, Result};
use pbm::sensor::adc_from_bar;
use pbm::BarG;
use pbm::{FaultClass, Meters, TwinParams};
use pbm_io::dataset::{write_manifest, ManifestRow, MANIFEST};
use pbm_io::trace::write_adc_trace;
use pbm_lab::generate::{fleet, simulate_plant, transducer_noise, GENERATE_STEP_S, NOISE_SIGMA_BAR, TRACE_SAMPLES};
pub use pbm_lab::generate::{BLOCK_MM, LEAK_MM};
use pbm_lab::sensor_faults::{sense_with_faults, FaultKind, FaultSpec, Onset};
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rayon::prelude::*;
use std::path::PathBuf;

/// How a locomotive of the scenario wears.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wear {
    /// Stays at its own healthy parameters.
    Healthy,
    /// A leak to atmosphere grows.
    Leak,
    /// The release orifice clogs.
    Clog,
    /// The brake stays healthy; the pressure transducer fails from the onset on
    /// ([`DegradationOptions::sensor_fault`] on every release from then).
    Sensor,
}

/// What a degradation data set holds.
#[derive(Debug, Clone, PartialEq)]
pub struct DegradationOptions {
    /// Random seed of the fleet and the noise.
    pub seed: u64,
    /// How each locomotive wears, in fleet order (`loco-01` first).
    pub wear: Vec<Wear>,
    /// Releases per locomotive.
    pub releases: usize,
    /// Release (0-based) at which the wear starts.
    pub onset: usize,
    /// Leak diameter at the last release, mm.
    pub leak_end_mm: f64,
    /// Release orifice diameter at the last release, mm.
    pub orifice_end_mm: f64,
    /// The transducer fault of a [`Wear::Sensor`] locomotive (the generator's `--sensor-fault`
    /// faults), applied to every release from the onset on.
    pub sensor_fault: FaultSpec,
}

/// The transducer fault of a [`Wear::Sensor`] locomotive by default: spikes (isolated readings
/// 0.5–3 bar off, e.g. a loose connector) on 1 % of the samples from a moment drawn per release
/// in its first 50 s. The monitor flags them as a sensor fault and declines to diagnose. (A gain
/// error of −25 % is not flagged: it reads as a low supply, the monitor cannot tell them apart.)
pub const DEFAULT_SENSOR_FAULT: FaultSpec = FaultSpec { kind: FaultKind::Spikes, value: 0.01, onset: Onset::Random };

impl DegradationOptions {
    /// The default scenario of `wear`: 150 releases, wear from release 30, a leak reaching
    /// 1.0 mm or an orifice reaching 0.6 mm (both well inside the SPEC §4 fault ranges) at the end.
    pub fn new(seed: u64, wear: Vec<Wear>) -> Self {
        Self {
            seed,
            wear,
            releases: 150,
            onset: 30,
            leak_end_mm: 1.0,
            orifice_end_mm: 0.6,
            sensor_fault: DEFAULT_SENSOR_FAULT,
        }
    }

    fn validate(&self) -> Result<()> {
        if self.wear.is_empty() || self.releases < 2 || self.onset + 1 >= self.releases {
            bail!("a degradation scenario needs a locomotive, at least 2 releases and an onset before the last one");
        }
        if !(LEAK_MM.0..=3.0).contains(&self.leak_end_mm) {
            bail!("the final leak must be a fault (≥ {} mm) and at most 3 mm", LEAK_MM.0);
        }
        if !(0.2..=BLOCK_MM.1).contains(&self.orifice_end_mm) {
            bail!("the final orifice must be blocked (≤ {} mm) and at least 0.2 mm", BLOCK_MM.1);
        }
        Ok(())
    }
}

/// One release of the scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct DegradedRelease {
    /// Locomotive name.
    pub locomotive: String,
    /// Index of the locomotive in the fleet.
    pub loco_index: usize,
    /// Release number, 0-based.
    pub release: usize,
    /// The brake of this release.
    pub params: TwinParams,
    /// SPEC §4 label of those parameters.
    pub label: FaultClass,
    /// The transducer fault of this release, if the transducer is failing.
    pub sensor_fault: Option<FaultSpec>,
}

/// The wear fraction at release `k`: 0 until `onset`, 1 at the last release.
fn fraction(o: &DegradationOptions, k: usize) -> f64 {
    if k <= o.onset {
        0.0
    } else {
        (k - o.onset) as f64 / (o.releases - 1 - o.onset) as f64
    }
}

/// The SPEC §4 class of a brake that differs from its locomotive's only by leak and orifice.
pub fn label_of(params: &TwinParams) -> FaultClass {
    let leak = params.leak.mm() >= LEAK_MM.0;
    let block = params.orifice.mm() <= BLOCK_MM.1;
    match (leak, block) {
        (false, false) => FaultClass::Normal,
        (true, false) => FaultClass::AirLeak,
        (false, true) => FaultClass::OrificeBlock,
        (true, true) => FaultClass::LeakAndBlock,
    }
}

/// Every release of the scenario, locomotive by locomotive.
pub fn plan(o: &DegradationOptions) -> Result<Vec<DegradedRelease>> {
    o.validate()?;
    let locos = fleet(o.seed, o.wear.len());
    let mut out = Vec::with_capacity(o.wear.len() * o.releases);
    for (i, (loco, wear)) in locos.iter().zip(&o.wear).enumerate() {
        for k in 0..o.releases {
            let f = fraction(o, k);
            let mut p = loco.params;
            match wear {
                Wear::Healthy | Wear::Sensor => {}
                // A leak of zero diameter is no leak: the plant then has none.
                Wear::Leak => p.leak = Meters::from_mm(f * o.leak_end_mm),
                Wear::Clog => {
                    let start = TwinParams::NOMINAL_ORIFICE_MM;
                    p.orifice = Meters::from_mm(start + f * (o.orifice_end_mm - start));
                }
            }
            out.push(DegradedRelease {
                locomotive: loco.name.clone(),
                loco_index: i,
                release: k,
                params: p,
                label: label_of(&p),
                sensor_fault: (*wear == Wear::Sensor && k >= o.onset).then_some(o.sensor_fault),
            });
        }
    }
    Ok(out)
}

/// The ADC samples of one release (60 s at 100 Hz, SPEC §5 sensor).
pub fn simulate(seed: u64, r: &DegradedRelease) -> Result<Vec<u16>> {
    let mut key = [0u8; 32];
    for (chunk, word) in key.chunks_exact_mut(8).zip([seed, 10, r.loco_index as u64, r.release as u64]) {
        chunk.copy_from_slice(&word.to_le_bytes());
    }
    let mut rng = ChaCha8Rng::from_seed(key);
    let (p, _) = simulate_plant(&r.params, GENERATE_STEP_S, TRACE_SAMPLES)?;
    let noise = transducer_noise(p.len(), NOISE_SIGMA_BAR, &mut rng);
    match r.sensor_fault {
        None => Ok(p.iter().zip(noise).map(|(&p, n)| adc_from_bar(BarG(p + n)).0).collect()),
        Some(spec) => {
            // The fault's own stream, so the brake's noise is the same with and without it.
            for (chunk, word) in key.chunks_exact_mut(8).zip([seed, 11, r.loco_index as u64, r.release as u64]) {
                chunk.copy_from_slice(&word.to_le_bytes());
            }
            Ok(sense_with_faults(&p, &noise, &[spec], &mut ChaCha8Rng::from_seed(key)).0)
        }
    }
}

/// Writes the scenario as a data set (`manifest.csv`, `truth.csv`, one trace per release with
/// its `locomotive`, `label` and `release` metadata) into `out`, which must be empty or absent.
/// Returns the releases written.
pub fn write(o: &DegradationOptions, out: &std::path::Path) -> Result<Vec<DegradedRelease>> {
    let releases = plan(o)?;
    if out.exists()
        && std::fs::read_dir(out).with_context(|| format!("cannot read {}", out.display()))?.next().is_some()
    {
        bail!("--out {} is not empty", out.display());
    }
    let traces = out.join("traces");
    std::fs::create_dir_all(&traces).with_context(|| format!("cannot create {}", traces.display()))?;
    let rows: Vec<ManifestRow> = releases
        .par_iter()
        .map(|r| {
            let adc = simulate(o.seed, r)?;
            let file = format!("traces/{}_{:04}.csv", r.locomotive, r.release);
            let mut meta = vec![
                ("label", r.label.label().to_owned()),
                ("locomotive", r.locomotive.clone()),
                ("release", r.release.to_string()),
                ("seed", o.seed.to_string()),
                ("source", "host-sim fleet degrade: f64 reference twin, slow wear, 12-bit ADC".to_owned()),
            ];
            if let Some(f) = r.sensor_fault {
                meta.push(("sensor_fault", describe_fault(f)));
            }
            let mut buf = Vec::with_capacity(adc.len() * 10 + 256);
            write_adc_trace(&mut buf, &meta, &adc)?;
            let path: PathBuf = out.join(&file);
            std::fs::write(&path, &buf).with_context(|| format!("cannot write {}", path.display()))?;
            Ok(ManifestRow {
                file,
                label: r.label.label().to_owned(),
                locomotive: r.locomotive.clone(),
                split: "test".to_owned(),
            })
        })
        .collect::<Result<_>>()?;
    write_manifest(&out.join(MANIFEST), &rows)?;
    let mut truth = pbm_io::table::CsvFile::create(&out.join(pbm_io::dataset::TRUTH))?;
    truth.record(["file", "label", "locomotive", "release", "supply_bar_g", "orifice_mm", "leak_mm"])?;
    for (row, r) in rows.iter().zip(&releases) {
        truth.record([
            row.file.clone(),
            row.label.clone(),
            row.locomotive.clone(),
            r.release.to_string(),
            format!("{:.6}", r.params.supply.0),
            format!("{:.6}", r.params.orifice.mm()),
            format!("{:.6}", r.params.leak.mm()),
        ])?;
    }
    truth.finish()?;
    Ok(releases)
}

/// A fault spec as the generator's `--sensor-fault` argument writes it (`KIND[=VALUE]@ONSET`).
pub fn describe_fault(spec: FaultSpec) -> String {
    let v = if spec.value.is_nan() { String::new() } else { format!("={}", spec.value) };
    let onset = match spec.onset {
        Onset::At(t) => format!("@{t}"),
        Onset::Random => "@random".to_owned(),
    };
    format!("{}{v}{onset}", spec.kind.name())
}
