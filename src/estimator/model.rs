//! Regression models of the release, behind one trait, and the orifice flow shapes they use.
//!
//! A model turns one [`BlockObservation`] (block-averaged pressure and its rate) into a
//! [`Regression`] `y = φᵀθ` for an [`super::Rls`] of the same size. Which blocks a model sees
//! (its phase) is decided by [`super::ReleaseEstimator`], not by the model.

use crate::twin::flow_norm_q16;

/// Pressure ratio at and below which an orifice is choked (SPEC §2).
pub const CRITICAL_RATIO: f32 = 0.528;

/// What the estimator knows about one block of samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockObservation {
    /// Mean chamber pressure of this block, bar absolute.
    pub pressure: f32,
    /// Mean of this and the previous block's pressure, bar absolute (where `rate` applies).
    pub mid_pressure: f32,
    /// Pressure rate between the previous block and this one, bar/s.
    pub rate: f32,
}

/// One linear regression `y = φᵀθ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Regression<const N: usize> {
    /// Regressor φ.
    pub phi: [f32; N],
    /// Observation y.
    pub y: f32,
}

/// A model linear in its `N` parameters.
pub trait RegressionModel<const N: usize> {
    /// Names of the parameters, in θ order (for reports).
    const PARAMETERS: [&'static str; N];
    /// The regression of one block.
    fn regress(&self, obs: &BlockObservation) -> Regression<N>;
}

/// Filling at rest with the inlet orifice choked (see the module docs of [`super`]):
/// `dp/dt = a − g_leak · ψ(p)`, θ = `[a, g_leak]`, φ = `[1, −ψ(p)]`, y = `dp/dt`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ChokedFillModel;

impl RegressionModel<2> for ChokedFillModel {
    const PARAMETERS: [&'static str; 2] = ["choked_inflow_rate_bar_per_s", "leak_conductance_per_s"];
    fn regress(&self, obs: &BlockObservation) -> Regression<2> {
        Regression { phi: [1.0, -leak_shape(obs.mid_pressure)], y: obs.rate }
    }
}

/// Plateau level: `p = P∞`, θ = `[P∞]`, φ = `[1]`, y = block pressure (an exponentially
/// weighted mean).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PlateauModel;

impl RegressionModel<1> for PlateauModel {
    const PARAMETERS: [&'static str; 1] = ["plateau_bar_abs"];
    fn regress(&self, obs: &BlockObservation) -> Regression<1> {
        Regression { phi: [1.0], y: obs.pressure }
    }
}

/// Normalised orifice flow φ(r) = flow / choked flow for a downstream/upstream pressure ratio
/// `r`: 1 for `r ≤ 0.528`, falling to 0 at `r = 1`. Uses the twin's integer table, so it is the
/// same function the twin integrates, bit for bit on every target.
pub fn flow_shape(ratio: f32) -> f32 {
    // `as` saturates and maps NaN to 0 (which reads as choked: harmless, inputs are checked).
    let r_q16 = (ratio.clamp(0.0, 1.0) * 65_536.0) as u32;
    // 0..=65536: exact through i32, whose conversion is one FPU instruction (i64 → f32 is a
    // soft-float call on the Cortex-M4F).
    flow_norm_q16(r_q16) as i32 as f32 * (1.0 / 65_536.0)
}

/// Leak flow shape ψ(p) = p · φ(P0/p) for chamber pressure `p` (bar abs, P0 = 1 bar): the leak's
/// pressure decay rate per unit leak conductance, bar/s · s. 0 at atmosphere, = p once choked
/// (p ≥ 1/0.528 ≈ 1.89 bar abs), negative below atmosphere (inflow through the leak).
pub fn leak_shape(pressure: f32) -> f32 {
    if pressure > 1.0 {
        pressure * flow_shape(1.0 / pressure)
    } else if pressure < 1.0 && pressure > 0.0 {
        -flow_shape(pressure)
    } else {
        0.0
    }
}

/// The ratio `r ∈ [0.528, 1]` with `flow_shape(r) = target`, by bisection (φ is monotone
/// decreasing there). `target ≤ 0` gives 1, `target ≥ 1` gives 0.528.
pub fn inverse_flow_shape(target: f32) -> f32 {
    let mut search = InverseFlowShape::new(target);
    while search.step() {}
    search.ratio()
}

/// [`inverse_flow_shape`] one bisection step at a time (the estimator spreads it over samples).
/// Stepping it to the end gives the same bits as [`inverse_flow_shape`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseFlowShape {
    target: f32,
    lo: f32,
    hi: f32,
    steps_left: u8,
}

impl InverseFlowShape {
    /// Bisection steps of a full search (interval 0.472 · 2⁻¹⁸ ≈ 2e-6).
    pub const STEPS: u8 = 18;

    /// A search for `target` (trivial cases are solved here, with no step left).
    pub fn new(target: f32) -> Self {
        // NaN lands in the first case too (not > 0): no leak information, r = 1.
        let (lo, hi, steps_left) = if target.is_nan() || target <= 0.0 {
            (1.0, 1.0, 0)
        } else if target >= 1.0 {
            (CRITICAL_RATIO, CRITICAL_RATIO, 0)
        } else {
            (CRITICAL_RATIO, 1.0, Self::STEPS)
        };
        Self { target, lo, hi, steps_left }
    }

    /// One bisection step; `false` (and nothing done) once the search is complete.
    pub fn step(&mut self) -> bool {
        if self.steps_left == 0 {
            return false;
        }
        self.steps_left -= 1;
        let mid = 0.5 * (self.lo + self.hi);
        if flow_shape(mid) > self.target {
            self.lo = mid;
        } else {
            self.hi = mid;
        }
        true
    }

    /// True when no step is left.
    pub fn done(&self) -> bool {
        self.steps_left == 0
    }

    /// The ratio found (the midpoint of the current interval; exact for the trivial cases).
    pub fn ratio(&self) -> f32 {
        0.5 * (self.lo + self.hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flow_shape_limits() {
        assert_eq!(flow_shape(0.0), 1.0);
        assert_eq!(flow_shape(0.5), 1.0);
        assert_eq!(flow_shape(1.0), 0.0);
        assert!(flow_shape(0.9) > 0.3 && flow_shape(0.9) < 0.9);
        assert_eq!(flow_shape(f32::NAN), 1.0);
    }

    #[test]
    fn leak_shape_is_choked_above_critical() {
        assert_eq!(leak_shape(1.0), 0.0);
        assert!((leak_shape(3.0) - 3.0).abs() < 1e-6);
        assert!(leak_shape(1.2) > 0.0 && leak_shape(1.2) < 1.2);
        assert!(leak_shape(0.9) < 0.0);
    }

    #[test]
    fn inverse_flow_shape_round_trips() {
        for r in [0.55f32, 0.7, 0.85, 0.95, 0.99] {
            let back = inverse_flow_shape(flow_shape(r));
            assert!((back - r).abs() < 2e-3, "{r} -> {back}");
        }
        assert_eq!(inverse_flow_shape(0.0), 1.0);
        assert_eq!(inverse_flow_shape(2.0), CRITICAL_RATIO);
    }
}
