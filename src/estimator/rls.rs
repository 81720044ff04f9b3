//! Recursive least squares with exponential forgetting and a covariance windup guard, in `f32`.
//!
//! Standard RLS for `y = φᵀθ + e`:
//!
//! ```text
//! e = y − φᵀθ          (a-priori innovation)
//! k = Pφ / (λ + φᵀPφ)
//! θ ← θ + k e
//! P ← (P − k (Pφ)ᵀ) / λ      only while trace(P) < trace_max; otherwise λ = 1 for this step
//! ```
//!
//! # Windup guard
//!
//! With forgetting (λ < 1) and no excitation in some direction of φ (for example 24 h parked at a
//! constant pressure, where φ is the same vector at every step), classic RLS divides that part of
//! `P` by λ at every step: `P` grows as λ⁻ⁿ, overflows to infinity and then turns θ into NaN. Here
//! the division by λ is applied only while `trace(P)` is below `trace_max`, so `P` never exceeds
//! it (the subtraction of `k (Pφ)ᵀ` only shrinks `P`). `P` is re-symmetrised after every step and,
//! should it ever lose positive definiteness (a non-positive or non-finite diagonal) it is reset
//! to its initial value: the estimate θ is kept, the update reports [`RlsError::CovarianceReset`].
//! Non-finite inputs are refused before they touch the state.
//!
//! Only `+ − × ÷` on `f32` are used: IEEE-754 rounds them correctly on x86-64 (SSE) and on the
//! Cortex-M4F FPU alike, and Rust never contracts them to fused multiply-adds, so host and
//! target produce the same bits.

/// Tuning of one RLS instance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsConfig {
    /// Forgetting factor λ, in (0, 1]. Memory ≈ 1/(1 − λ) updates.
    pub forgetting: f32,
    /// Initial covariance `P = p0 · I` (large: little confidence in the initial θ).
    pub initial_covariance: f32,
    /// Windup guard: forgetting is suspended while `trace(P) ≥ trace_max`.
    pub trace_max: f32,
}

impl RlsConfig {
    /// Checks the ranges (`0 < λ ≤ 1`, `0 < p0`, `N·p0 ≤ trace_max`, all finite).
    pub fn validate(&self, n: usize) -> Result<(), RlsError> {
        let ok = self.forgetting > 0.0
            && self.forgetting <= 1.0
            && self.initial_covariance > 0.0
            && self.initial_covariance.is_finite()
            && self.trace_max.is_finite()
            && self.trace_max >= self.initial_covariance * n as f32;
        if ok {
            Ok(())
        } else {
            Err(RlsError::Config)
        }
    }
}

/// Why an RLS update was refused or corrected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RlsError {
    /// Forgetting, initial covariance or trace bound out of range.
    Config,
    /// The regressor or the observation is NaN or infinite; the state is unchanged.
    NonFinite,
    /// The covariance lost positive definiteness and was reset (θ kept).
    CovarianceReset,
}

impl core::fmt::Display for RlsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Config => "RLS configuration out of range",
            Self::NonFinite => "non-finite regressor or observation refused",
            Self::CovarianceReset => "RLS covariance lost definiteness and was reset",
        })
    }
}

#[cfg(feature = "std")]
impl std::error::Error for RlsError {}

/// Recursive least squares estimator of `N` parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rls<const N: usize> {
    config: RlsConfig,
    initial_theta: [f32; N],
    theta: [f32; N],
    covariance: [[f32; N]; N],
    updates: u32,
    guard_active: bool,
}

impl<const N: usize> Rls<N> {
    /// A fresh estimator starting from `theta0` with covariance `p0 · I`.
    pub fn new(config: RlsConfig, theta0: [f32; N]) -> Result<Self, RlsError> {
        config.validate(N)?;
        if theta0.iter().any(|t| !t.is_finite()) {
            return Err(RlsError::NonFinite);
        }
        Ok(Self {
            config,
            initial_theta: theta0,
            theta: theta0,
            covariance: Self::initial_covariance(config.initial_covariance),
            updates: 0,
            guard_active: false,
        })
    }

    fn initial_covariance(p0: f32) -> [[f32; N]; N] {
        let mut p = [[0.0; N]; N];
        for (i, row) in p.iter_mut().enumerate() {
            row[i] = p0;
        }
        p
    }

    /// Back to the initial estimate and covariance.
    pub fn reset(&mut self) {
        self.theta = self.initial_theta;
        self.covariance = Self::initial_covariance(self.config.initial_covariance);
        self.updates = 0;
        self.guard_active = false;
    }

    /// Current parameter estimate.
    pub fn theta(&self) -> &[f32; N] {
        &self.theta
    }

    /// Current covariance (scaled: the noise variance is not included).
    pub fn covariance(&self) -> &[[f32; N]; N] {
        &self.covariance
    }

    /// Trace of the covariance.
    pub fn trace(&self) -> f32 {
        let mut t = 0.0;
        for i in 0..N {
            t += self.covariance[i][i];
        }
        t
    }

    /// Number of accepted updates since the last reset (saturating).
    pub fn updates(&self) -> u32 {
        self.updates
    }

    /// True when the last update found `trace(P)` at its bound and skipped the forgetting.
    pub fn guard_active(&self) -> bool {
        self.guard_active
    }

    /// The prediction `φᵀθ`.
    pub fn predict(&self, phi: &[f32; N]) -> f32 {
        dot(phi, &self.theta)
    }

    /// One RLS step with regressor `phi` and observation `y`; returns the a-priori innovation
    /// `y − φᵀθ`.
    pub fn update(&mut self, phi: &[f32; N], y: f32) -> Result<f32, RlsError> {
        if !y.is_finite() || phi.iter().any(|v| !v.is_finite()) {
            return Err(RlsError::NonFinite);
        }
        let mut p_phi = [0.0f32; N];
        for (i, out) in p_phi.iter_mut().enumerate() {
            *out = dot(&self.covariance[i], phi);
        }
        let lambda = self.config.forgetting;
        let denom = lambda + dot(phi, &p_phi);
        // Products of huge finite regressors can still overflow: refuse, keep the state.
        if !(denom.is_finite() && denom > 0.0) {
            return Err(RlsError::NonFinite);
        }
        let innovation = y - dot(phi, &self.theta);
        let mut gain = [0.0f32; N];
        for (g, &pp) in gain.iter_mut().zip(&p_phi) {
            *g = pp / denom;
        }
        let mut theta = self.theta;
        for (t, &g) in theta.iter_mut().zip(&gain) {
            *t += g * innovation;
        }
        if theta.iter().any(|t| !t.is_finite()) {
            return Err(RlsError::NonFinite);
        }
        self.theta = theta;

        // P − k (Pφ)ᵀ, symmetrised (the exact update is symmetric; rounding is not).
        let mut p = self.covariance;
        for i in 0..N {
            for j in 0..N {
                p[i][j] -= gain[i] * p_phi[j];
            }
        }
        #[allow(clippy::needless_range_loop)] // (i, j) and (j, i) of the same matrix
        for i in 0..N {
            for j in (i + 1)..N {
                let m = 0.5 * (p[i][j] + p[j][i]);
                p[i][j] = m;
                p[j][i] = m;
            }
        }
        let mut trace = 0.0;
        for (i, row) in p.iter().enumerate() {
            trace += row[i];
        }
        self.guard_active = trace >= self.config.trace_max;
        if !self.guard_active && lambda < 1.0 {
            let inv = 1.0 / lambda;
            // Never divide past the bound: scale by at most trace_max / trace.
            let scale = if trace * inv > self.config.trace_max { self.config.trace_max / trace } else { inv };
            for row in p.iter_mut() {
                for v in row.iter_mut() {
                    *v *= scale;
                }
            }
        }
        self.updates = self.updates.saturating_add(1);
        let healthy = p.iter().enumerate().all(|(i, row)| row[i] > 0.0 && row.iter().all(|v| v.is_finite()));
        if healthy {
            self.covariance = p;
            Ok(innovation)
        } else {
            self.covariance = Self::initial_covariance(self.config.initial_covariance);
            Err(RlsError::CovarianceReset)
        }
    }
}

#[inline]
fn dot<const N: usize>(a: &[f32; N], b: &[f32; N]) -> f32 {
    let mut s = 0.0;
    for i in 0..N {
        s += a[i] * b[i];
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const CFG: RlsConfig = RlsConfig { forgetting: 0.99, initial_covariance: 100.0, trace_max: 1e4 };

    #[test]
    fn recovers_line_exactly() {
        let mut r = Rls::<2>::new(CFG, [0.0; 2]).unwrap();
        for i in 0..200 {
            let x = (i % 17) as f32 * 0.3;
            r.update(&[1.0, x], 0.7 - 0.2 * x).unwrap();
        }
        assert!((r.theta()[0] - 0.7).abs() < 1e-4, "{:?}", r.theta());
        assert!((r.theta()[1] + 0.2).abs() < 1e-4, "{:?}", r.theta());
    }

    #[test]
    fn refuses_non_finite_and_bad_config() {
        let mut r = Rls::<2>::new(CFG, [1.0, 2.0]).unwrap();
        assert_eq!(r.update(&[f32::NAN, 1.0], 0.0), Err(RlsError::NonFinite));
        assert_eq!(r.update(&[1.0, 1.0], f32::INFINITY), Err(RlsError::NonFinite));
        assert_eq!(r.update(&[3e38, 3e38], 1.0), Err(RlsError::NonFinite));
        assert_eq!(r.theta(), &[1.0, 2.0]);
        assert_eq!(r.updates(), 0);
        let bad = RlsConfig { forgetting: 1.5, ..CFG };
        assert_eq!(Rls::<2>::new(bad, [0.0; 2]).err(), Some(RlsError::Config));
        let bad = RlsConfig { trace_max: 1.0, ..CFG };
        assert_eq!(Rls::<2>::new(bad, [0.0; 2]).err(), Some(RlsError::Config));
    }

    #[test]
    fn reset_restores_initial_state() {
        let mut r = Rls::<2>::new(CFG, [0.5, 0.0]).unwrap();
        r.update(&[1.0, 2.0], 3.0).unwrap();
        r.reset();
        assert_eq!(r.theta(), &[0.5, 0.0]);
        assert_eq!(r.trace(), 200.0);
        assert_eq!(r.updates(), 0);
    }
}
