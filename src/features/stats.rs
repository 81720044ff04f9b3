//! The paper's 21 signal statistics, computed online (one sample at a time, no buffer).
//!
//! The paper lists "mean, variance, maximum, kurtosis, standard deviation, skewness, absolute
//! sum, etc." without naming all 21. This module fixes the list (see [`STAT_NAMES`]): the usual
//! condition-monitoring time-domain statistics, every one of them computable in one pass.
//!
//! Central moments use the one-pass update of Welford extended to the third and fourth moments
//! (Terriberry 2007), so a long plateau (6000 samples near 7.7 bar) does not lose the variance to
//! cancellation. Arithmetic is `f64` with `+ − × ÷ sqrt` only (IEEE-754 correctly rounded, no
//! fused multiply-add is ever formed by rustc), so x86 and the soft-float f64 of thumbv7em give
//! the same bits.

/// Number of statistics.
pub const N_STATS: usize = 21;

/// Names of the statistics, in the order of [`SignalStats::values`].
pub const STAT_NAMES: [&str; N_STATS] = [
    "mean",
    "variance",
    "std",
    "max",
    "min",
    "peak_to_peak",
    "rms",
    "abs_mean",
    "abs_sum",
    "energy",
    "skewness",
    "kurtosis",
    "crest_factor",
    "shape_factor",
    "impulse_factor",
    "clearance_factor",
    "sqrt_amplitude",
    "abs_max",
    "abs_sum_of_changes",
    "mean_abs_change",
    "last",
];

/// Running accumulator of the 21 statistics of one signal.
///
/// Definitions (population moments over the `n` samples seen so far, `x̄` the mean):
/// mean; variance `Σ(x−x̄)²/n`; std; max; min; peak-to-peak `max − min`; RMS `sqrt(Σx²/n)`;
/// absolute mean `Σ|x|/n`; absolute sum `Σ|x|`; energy `Σx²`; skewness `m3/m2^1.5`; kurtosis
/// `m4/m2²` (not excess); crest factor `max|x|/RMS`; shape factor `RMS/abs mean`; impulse factor
/// `max|x|/abs mean`; clearance factor `max|x|/sqrt amplitude`; sqrt amplitude
/// `(Σ sqrt|x| / n)²`; `max|x|`; absolute sum of changes `Σ|x_i − x_(i−1)|`; mean absolute change
/// (that sum over `n − 1`); last value. A ratio with a zero denominator is 0.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SignalStats {
    n: u32,
    mean: f64,
    m2: f64,
    m3: f64,
    m4: f64,
    max: f64,
    min: f64,
    abs_sum: f64,
    energy: f64,
    sqrt_abs_sum: f64,
    abs_max: f64,
    abs_changes: f64,
    last: f64,
}

fn ratio(num: f64, den: f64) -> f64 {
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

impl SignalStats {
    /// An empty accumulator.
    pub const fn new() -> Self {
        Self {
            n: 0,
            mean: 0.0,
            m2: 0.0,
            m3: 0.0,
            m4: 0.0,
            max: 0.0,
            min: 0.0,
            abs_sum: 0.0,
            energy: 0.0,
            sqrt_abs_sum: 0.0,
            abs_max: 0.0,
            abs_changes: 0.0,
            last: 0.0,
        }
    }

    /// Number of samples accumulated.
    pub fn count(&self) -> u32 {
        self.n
    }

    /// Adds one sample. Non-finite samples are ignored (they cannot come from the integer
    /// pipeline; the guard keeps one bad value from poisoning every statistic).
    pub fn push(&mut self, x: f64) {
        if !x.is_finite() {
            return;
        }
        let n1 = f64::from(self.n);
        self.n = self.n.saturating_add(1);
        let n = f64::from(self.n);
        let delta = x - self.mean;
        let delta_n = delta / n;
        let delta_n2 = delta_n * delta_n;
        let term1 = delta * delta_n * n1;
        self.mean += delta_n;
        self.m4 += term1 * delta_n2 * (n * n - 3.0 * n + 3.0) + 6.0 * delta_n2 * self.m2 - 4.0 * delta_n * self.m3;
        self.m3 += term1 * delta_n * (n - 2.0) - 3.0 * delta_n * self.m2;
        self.m2 += term1;
        let a = libm::fabs(x);
        if self.n == 1 {
            self.max = x;
            self.min = x;
        } else {
            self.max = self.max.max(x);
            self.min = self.min.min(x);
            self.abs_changes += libm::fabs(x - self.last);
        }
        self.abs_sum += a;
        self.energy += x * x;
        self.sqrt_abs_sum += libm::sqrt(a);
        self.abs_max = self.abs_max.max(a);
        self.last = x;
    }

    /// The 21 statistics in [`STAT_NAMES`] order (all 0 before the first sample).
    pub fn values(&self) -> [f64; N_STATS] {
        if self.n == 0 {
            return [0.0; N_STATS];
        }
        let n = f64::from(self.n);
        let variance = self.m2 / n;
        let std = libm::sqrt(variance);
        let rms = libm::sqrt(self.energy / n);
        let abs_mean = self.abs_sum / n;
        let sqrt_amp = {
            let m = self.sqrt_abs_sum / n;
            m * m
        };
        let skewness = if self.m2 > 0.0 { libm::sqrt(n) * self.m3 / (self.m2 * libm::sqrt(self.m2)) } else { 0.0 };
        let kurtosis = ratio(n * self.m4, self.m2 * self.m2);
        [
            self.mean,
            variance,
            std,
            self.max,
            self.min,
            self.max - self.min,
            rms,
            abs_mean,
            self.abs_sum,
            self.energy,
            skewness,
            kurtosis,
            ratio(self.abs_max, rms),
            ratio(rms, abs_mean),
            ratio(self.abs_max, abs_mean),
            ratio(self.abs_max, sqrt_amp),
            sqrt_amp,
            self.abs_max,
            self.abs_changes,
            if self.n > 1 { self.abs_changes / (n - 1.0) } else { 0.0 },
            self.last,
        ]
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// Two-pass reference for the moment statistics.
    fn two_pass(xs: &[f64]) -> (f64, f64, f64, f64) {
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let m = |k: i32| xs.iter().map(|x| (x - mean).powi(k)).sum::<f64>() / n;
        let (m2, m3, m4) = (m(2), m(3), m(4));
        (mean, m2, m3 / m2.powf(1.5), m4 / (m2 * m2))
    }

    #[test]
    fn matches_two_pass_definitions() {
        let xs: Vec<f64> = (0..6000)
            .map(|i| 7.7 - 7.0 * (-(i as f64) / 900.0).exp() + 0.01 * ((i * 7919 % 13) as f64 - 6.0))
            .collect();
        let mut s = SignalStats::new();
        xs.iter().for_each(|&x| s.push(x));
        let v = s.values();
        let (mean, var, skew, kurt) = two_pass(&xs);
        assert!((v[0] - mean).abs() < 1e-12);
        assert!((v[1] - var).abs() < 1e-10 * var);
        assert!((v[2] - var.sqrt()).abs() < 1e-10);
        assert!((v[10] - skew).abs() < 1e-9, "{} {}", v[10], skew);
        assert!((v[11] - kurt).abs() < 1e-9, "{} {}", v[11], kurt);
        let max = xs.iter().cloned().fold(f64::MIN, f64::max);
        let min = xs.iter().cloned().fold(f64::MAX, f64::min);
        assert_eq!(v[3], max);
        assert_eq!(v[4], min);
        assert_eq!(v[5], max - min);
        let rms = (xs.iter().map(|x| x * x).sum::<f64>() / 6000.0).sqrt();
        assert!((v[6] - rms).abs() < 1e-12);
        assert!((v[12] - max.abs().max(min.abs()) / rms).abs() < 1e-12);
        let asc: f64 = xs.windows(2).map(|w| (w[1] - w[0]).abs()).sum();
        assert!((v[18] - asc).abs() < 1e-9);
        assert_eq!(v[20], *xs.last().unwrap());
    }

    #[test]
    fn constant_and_empty_signals_give_finite_values() {
        assert_eq!(SignalStats::new().values(), [0.0; N_STATS]);
        let mut s = SignalStats::new();
        for _ in 0..10 {
            s.push(0.0);
        }
        s.push(f64::NAN);
        assert_eq!(s.count(), 10);
        assert!(s.values().iter().all(|v| v.is_finite()));
        assert_eq!(s.values()[10], 0.0);
        assert_eq!(s.values()[11], 0.0);
    }
}
