//! Sensor and ADC faults injected by `host-sim generate --sensor-fault KIND[=VALUE][@ONSET_S]`,
//! so that every plausibility check of the monitor (`pbm::plausibility`) and the *cannot
//! diagnose: sensor fault* verdict can be tested on valid releases of every class.
//!
//! The release itself is simulated as usual; a fault changes only what the transducer and the
//! ADC report, from its onset (seconds since the release command) on:
//!
//! | kind | value (default) | what a technician would find |
//! |---|---|---|
//! | `frozen` | – | amplifier, ADC or driver buffer stuck: the code read at the onset repeats exactly |
//! | `dead` | bar g (0) | channel dead at a plausible constant: the code of that pressure, no noise |
//! | `noisy` | σ bar (0.1) | loose contact or failing supply: extra white noise before the ADC |
//! | `spikes` | fraction of samples (0.03) | EMI: a sample jumps by ±0.5…3 bar |
//! | `dropouts` | burst start probability per sample (0.005) | intermittent wire: bursts of 1…10 samples reading 0 |
//! | `lost_resolution` | bits (6) | converter lost its low bits: they read 0 |
//! | `clipped` | bar g (5.0) | amplifier saturates: the noisy pressure is clipped at that level |
//! | `impossible_rate` | bar (1.5) | a step offset (connector, reference jump) |
//! | `implausible_level` | gain (1.15) | gain error of the transducer |
//! | `offset` | bar (0.3) | zero offset of the transducer |
//! | `open_circuit`, `short_circuit` | – | the ADC reads 0 / 4095 |
//!
//! The onset is given as `@SECONDS`, or drawn per trace uniformly in [`RANDOM_ONSET_S`] when
//! omitted (`@random`). The fault's randomness (onset, spikes, bursts, extra noise) comes from a
//! stream of its own, so the release and the transducer's normal noise are the same bytes as
//! without the fault.

use anyhow::{bail, Result};
use pbm::sensor::adc_from_bar;
use pbm::twin::SAMPLE_PERIOD_S;
use pbm::BarG;
use rand_core::Rng;

/// Range of a random onset, s since the release command.
pub const RANDOM_ONSET_S: (f64, f64) = (1.0, 50.0);

/// What breaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// The code read at the onset repeats.
    Frozen,
    /// A constant code, no noise.
    Dead,
    /// Extra white noise.
    Noisy,
    /// Isolated outliers.
    Spikes,
    /// Bursts of zero readings.
    Dropouts,
    /// Low bits read 0.
    LostResolution,
    /// Clipped at a level.
    Clipped,
    /// A step offset.
    ImpossibleRate,
    /// A gain error.
    ImplausibleLevel,
    /// A zero offset.
    Offset,
    /// Reads 0.
    OpenCircuit,
    /// Reads 4095.
    ShortCircuit,
}

impl FaultKind {
    /// Every kind with its name and default value (`NaN` where the kind takes none).
    pub const ALL: [(Self, &'static str, f64); 12] = [
        (Self::Frozen, "frozen", f64::NAN),
        (Self::Dead, "dead", 0.0),
        (Self::Noisy, "noisy", 0.1),
        (Self::Spikes, "spikes", 0.03),
        (Self::Dropouts, "dropouts", 0.005),
        (Self::LostResolution, "lost_resolution", 6.0),
        (Self::Clipped, "clipped", 5.0),
        (Self::ImpossibleRate, "impossible_rate", 1.5),
        (Self::ImplausibleLevel, "implausible_level", 1.15),
        (Self::Offset, "offset", 0.3),
        (Self::OpenCircuit, "open_circuit", f64::NAN),
        (Self::ShortCircuit, "short_circuit", f64::NAN),
    ];

    /// Its name on the command line and in metadata.
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(k, ..)| *k == self).map_or("?", |(_, n, _)| n)
    }
}

/// When a fault starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Onset {
    /// At this time, s since the release command.
    At(f64),
    /// Drawn per trace in [`RANDOM_ONSET_S`].
    Random,
}

/// One `--sensor-fault` argument.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultSpec {
    /// What breaks.
    pub kind: FaultKind,
    /// Its magnitude (the kind's unit; `NaN` for kinds without one).
    pub value: f64,
    /// When.
    pub onset: Onset,
}

/// Parses `KIND[=VALUE][@ONSET_S|@random]`.
pub fn parse_spec(s: &str) -> Result<FaultSpec, String> {
    let (head, onset) = match s.split_once('@') {
        Some((h, o)) if o.trim() == "random" => (h, Onset::Random),
        Some((h, o)) => {
            let t: f64 = o.trim().parse().map_err(|_| format!("`{o}` is not an onset in seconds"))?;
            if !(t.is_finite() && t >= 0.0) {
                return Err(format!("onset `{o}` must be ≥ 0 s"));
            }
            (h, Onset::At(t))
        }
        None => (s, Onset::Random),
    };
    let (name, value) = match head.split_once('=') {
        Some((n, v)) => (n.trim(), Some(v.trim())),
        None => (head.trim(), None),
    };
    let names: Vec<&str> = FaultKind::ALL.iter().map(|(_, n, _)| *n).collect();
    let Some(&(kind, _, default)) = FaultKind::ALL.iter().find(|(_, n, _)| *n == name) else {
        return Err(format!("unknown sensor fault `{name}` (known: {})", names.join(", ")));
    };
    let value = match value {
        None => default,
        Some(_) if default.is_nan() => return Err(format!("sensor fault `{name}` takes no value")),
        Some(v) => {
            let x: f64 = v.parse().map_err(|_| format!("sensor fault `{name}`: `{v}` is not a number"))?;
            let ok = match kind {
                FaultKind::Spikes | FaultKind::Dropouts => (0.0..=1.0).contains(&x),
                FaultKind::LostResolution => (1.0..=11.0).contains(&x) && x.fract() == 0.0,
                FaultKind::Noisy => x > 0.0 && x <= 10.0,
                FaultKind::ImplausibleLevel => x > 0.0 && x <= 10.0,
                _ => x.is_finite() && x.abs() <= 20.0,
            };
            if !ok {
                return Err(format!("sensor fault `{name}`: value {x} out of range"));
            }
            x
        }
    };
    Ok(FaultSpec { kind, value, onset })
}

/// A spec with its onset resolved for one trace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Applied {
    /// The spec.
    pub spec: FaultSpec,
    /// Onset, s.
    pub onset_s: f64,
}

impl Applied {
    /// `KIND=VALUE@ONSET` as written to metadata and truth.
    pub fn describe(&self) -> String {
        let v = if self.spec.value.is_nan() { String::new() } else { format!("={}", self.spec.value) };
        format!("{}{v}@{:.2}", self.spec.kind.name(), self.onset_s)
    }
}

/// Uniform in [0, 1).
fn unit(rng: &mut impl Rng) -> f64 {
    crate::random::unit(rng)
}

/// The ADC codes of a release with the faults applied: `pressure_bar_g` is the noise-free
/// pressure, `noise_bar` the transducer's normal noise sample by sample (already drawn, so a
/// trace without faults is unchanged), `rng` the faults' own stream.
pub fn sense_with_faults(
    pressure_bar_g: &[f64],
    noise_bar: &[f64],
    specs: &[FaultSpec],
    rng: &mut impl Rng,
) -> (Vec<u16>, Vec<Applied>) {
    let applied: Vec<Applied> = specs
        .iter()
        .map(|&spec| {
            let onset_s = match spec.onset {
                Onset::At(t) => t,
                Onset::Random => RANDOM_ONSET_S.0 + (RANDOM_ONSET_S.1 - RANDOM_ONSET_S.0) * unit(rng),
            };
            Applied { spec, onset_s }
        })
        .collect();
    let mut out = Vec::with_capacity(pressure_bar_g.len());
    let mut held: Vec<Option<u16>> = vec![None; applied.len()];
    let mut burst_left = vec![0u32; applied.len()];
    for (i, (&p, &n)) in pressure_bar_g.iter().zip(noise_bar).enumerate() {
        let t = i as f64 * SAMPLE_PERIOD_S;
        let active = |a: &Applied| t + 1e-9 >= a.onset_s;
        // Pressure-domain faults (before the ADC).
        let mut reading = p + n;
        for a in applied.iter().filter(|a| active(a)) {
            let v = a.spec.value;
            match a.spec.kind {
                FaultKind::Noisy => reading += v * crate::random::normal_pair(rng).0,
                FaultKind::Spikes if unit(rng) < v => {
                    let sign = if unit(rng) < 0.5 { -1.0 } else { 1.0 };
                    reading += sign * (0.5 + 2.5 * unit(rng));
                }
                FaultKind::Clipped => reading = reading.min(v),
                FaultKind::ImpossibleRate => reading += v,
                FaultKind::ImplausibleLevel => reading *= v,
                FaultKind::Offset => reading += v,
                _ => {}
            }
        }
        let mut code = adc_from_bar(BarG(reading)).0;
        // Code-domain faults (after the ADC).
        for (k, a) in applied.iter().enumerate() {
            if !active(a) {
                continue;
            }
            match a.spec.kind {
                FaultKind::Frozen => code = *held[k].get_or_insert(code),
                FaultKind::Dead => code = adc_from_bar(BarG(a.spec.value)).0,
                FaultKind::LostResolution => code &= !((1u16 << a.spec.value as u32) - 1),
                FaultKind::Dropouts => {
                    if burst_left[k] == 0 && unit(rng) < a.spec.value {
                        burst_left[k] = 1 + (unit(rng) * 10.0) as u32;
                    }
                    if burst_left[k] > 0 {
                        burst_left[k] -= 1;
                        code = 0;
                    }
                }
                FaultKind::OpenCircuit => code = 0,
                FaultKind::ShortCircuit => code = 4095,
                _ => {}
            }
        }
        out.push(code);
    }
    (out, applied)
}

/// Validates a list of specs (e.g. after parsing): at least nothing contradictory.
pub fn check_specs(specs: &[FaultSpec]) -> Result<()> {
    if specs.len() > 8 {
        bail!("at most 8 --sensor-fault options");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::SeedableRng;

    fn ramp() -> (Vec<f64>, Vec<f64>) {
        let p: Vec<f64> = (0..3000).map(|i| (i as f64 * 0.008).min(7.7)).collect();
        let n: Vec<f64> = (0..3000).map(|i| 0.01 * ((i * 7919 % 13) as f64 - 6.0) / 6.0).collect();
        (p, n)
    }

    fn run(spec: &str) -> Vec<u16> {
        let (p, n) = ramp();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        sense_with_faults(&p, &n, &[parse_spec(spec).unwrap()], &mut rng).0
    }

    #[test]
    fn faults_start_at_their_onset_and_do_what_they_say() {
        let (p, n) = ramp();
        let clean: Vec<u16> = p.iter().zip(&n).map(|(p, n)| adc_from_bar(BarG(p + n)).0).collect();
        for spec in ["frozen@10", "dead=2@10", "noisy=0.2@10", "spikes=0.2@10", "lost_resolution=6@10", "offset@10"] {
            let v = run(spec);
            assert_eq!(v[..1000], clean[..1000], "{spec}: untouched before the onset");
            assert_ne!(v[1000..], clean[1000..], "{spec}: changed after it");
        }
        assert!(run("frozen@10")[1000..].iter().all(|&c| c == clean[1000]));
        assert!(run("lost_resolution=6@0").iter().all(|&c| c % 64 == 0));
        assert!(run("clipped=5@0").iter().all(|&c| c <= adc_from_bar(BarG(5.0)).0));
        assert!(run("dropouts=0.05@0").contains(&0));
        assert!(run("short_circuit@0").iter().all(|&c| c == 4095));
    }

    #[test]
    fn parse_errors_are_clear() {
        assert!(parse_spec("melted").unwrap_err().contains("known: frozen"));
        assert!(parse_spec("frozen=3").unwrap_err().contains("takes no value"));
        assert!(parse_spec("spikes=2").unwrap_err().contains("out of range"));
        assert!(parse_spec("noisy@-1").is_err());
        assert_eq!(parse_spec("noisy").unwrap().onset, Onset::Random);
        assert_eq!(
            parse_spec("noisy=0.05@12.5").unwrap(),
            FaultSpec { kind: FaultKind::Noisy, value: 0.05, onset: Onset::At(12.5) }
        );
    }
}
