//! Random draws shared by the generator, the sensor-fault models and the audit sweeps.

use rand_core::Rng;

/// Uniform in [0, 1) with 53 random bits.
pub fn unit(rng: &mut impl Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Standard normal pair (Box–Muller; `1 − u` keeps the logarithm finite).
pub fn normal_pair(rng: &mut impl Rng) -> (f64, f64) {
    let r = (-2.0 * (1.0 - unit(rng)).ln()).sqrt();
    let (s, c) = (std::f64::consts::TAU * unit(rng)).sin_cos();
    (r * c, r * s)
}
