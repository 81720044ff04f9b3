//! Integration tests of the online estimator: windup guard under a simulated 24 h without
//! excitation, RLS against closed-form least squares, and no panic on any ADC sequence.

use pbm::estimator::model::{leak_shape, ChokedFillModel, RegressionModel};
use pbm::estimator::{
    BlockObservation, EstimatorConfig, Phase, ReleaseEstimator, Rls, RlsConfig, FILL_CUTOFFS_BAR_ABS,
};
use pbm::monitor::Monitor;
use pbm::report::EstimatorState;
use pbm::{AdcCounts, PressureQ24, Twin, TwinParams};
use proptest::prelude::*;

/// 24 h at 100 Hz.
const DAY_SAMPLES: u64 = 8_640_000;

#[test]
fn rls_windup_guard_holds_for_24h_without_excitation() {
    let cfg = EstimatorConfig::default().fill_rls;
    let mut rls = Rls::<2>::new(cfg, [0.0; 2]).unwrap();
    // A short excited stretch, then a day of the same regressor (parked at a 7.7 bar plateau).
    for i in 0..50 {
        let p = 1.0 + 0.07 * i as f32;
        rls.update(&[1.0, -leak_shape(p)], 0.8 - 0.01 * leak_shape(p)).unwrap();
    }
    let before = *rls.theta();
    let phi = [1.0, -leak_shape(8.7)];
    let y = rls.predict(&phi);
    for _ in 0..DAY_SAMPLES {
        rls.update(&phi, y).unwrap();
    }
    let p = rls.covariance();
    assert!(rls.guard_active());
    assert!(rls.trace() <= cfg.trace_max, "trace {}", rls.trace());
    assert!(p.iter().flatten().all(|v| v.is_finite()));
    assert!(p[0][0] > 0.0 && p[1][1] > 0.0 && p[0][0] * p[1][1] >= p[0][1] * p[1][0]);
    for (a, b) in rls.theta().iter().zip(&before) {
        assert!((a - b).abs() < 1e-3, "{:?} vs {before:?}", rls.theta());
    }
}

#[test]
fn rls_without_guard_would_overflow() {
    // The same scenario with the bound lifted shows what the guard prevents.
    let cfg = RlsConfig { forgetting: 0.999, initial_covariance: 100.0, trace_max: f32::MAX };
    let mut rls = Rls::<2>::new(cfg, [0.0; 2]).unwrap();
    let phi = [1.0, -8.7];
    let mut failed = false;
    for _ in 0..DAY_SAMPLES {
        if rls.update(&phi, 0.0).is_err() {
            failed = true;
            break;
        }
    }
    assert!(failed, "unbounded forgetting should blow up the covariance");
}

/// A release by the core twin, then 24 h parked at the final pressure, through the estimator.
#[test]
fn estimator_survives_24h_parked_at_plateau() {
    let params = TwinParams::nominal();
    let mut twin = Twin::new(&params).unwrap();
    let mut est = ReleaseEstimator::new(&params, EstimatorConfig::default()).unwrap();
    let mut p = PressureQ24::ATMOSPHERE;
    for _ in 0..6000 {
        est.update(Some(p), true).unwrap();
        p = twin.update(true).pressure;
    }
    let after_release = est.estimates();
    for _ in 0..DAY_SAMPLES {
        est.update(Some(p), true).unwrap();
    }
    let e = est.estimates();
    assert_eq!(est.last_error(), None);
    assert_eq!(e.phase, Phase::Plateau);
    assert!(matches!(e.state, EstimatorState::Settled | EstimatorState::Frozen), "{:?}", e.state);
    let supply = e.supply_bar_g.unwrap();
    assert!((supply - 7.7).abs() < 0.01, "supply {supply}");
    assert_eq!(e.orifice_mm, after_release.orifice_mm);
    for i in 0..FILL_CUTOFFS_BAR_ABS.len() {
        let r = est.fill_rls(i).unwrap();
        assert!(r.theta().iter().all(|v| v.is_finite()));
    }
    assert!(est.plateau_rls().trace().is_finite());
}

/// Exponentially weighted least squares in closed form (f64), with the RLS prior as a
/// regularisation term: θ = (λⁿ P0⁻¹ + Σ λ^{n−k} φφᵀ)⁻¹ (λⁿ P0⁻¹ θ0 + Σ λ^{n−k} φ y).
fn weighted_ls(rows: &[([f32; 2], f32)], lambda: f64, p0: f64) -> [f64; 2] {
    let n = rows.len() as i32;
    let prior = lambda.powi(n) / p0;
    let (mut a, mut b) = ([[prior, 0.0], [0.0, prior]], [0.0; 2]);
    for (k, (phi, y)) in rows.iter().enumerate() {
        let w = lambda.powi(n - 1 - k as i32);
        let f = [f64::from(phi[0]), f64::from(phi[1])];
        for i in 0..2 {
            for j in 0..2 {
                a[i][j] += w * f[i] * f[j];
            }
            b[i] += w * f[i] * f64::from(*y);
        }
    }
    let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    [(a[1][1] * b[0] - a[0][1] * b[1]) / det, (a[0][0] * b[1] - a[1][0] * b[0]) / det]
}

#[test]
fn rls_equals_closed_form_least_squares_on_fill_regressors() {
    // Choked-fill regressions of a leaky fill with deterministic pseudo-noise on the rate.
    let (a_true, g_true) = (0.79f32, 0.05f32);
    let mut rows = Vec::new();
    let mut seed = 12345u32;
    for k in 0..300 {
        let p = 1.0 + 3.5 * k as f32 / 300.0;
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        let noise = ((seed >> 8) as f32 / 16_777_216.0 - 0.5) * 0.1;
        let obs = BlockObservation { pressure: p, mid_pressure: p, rate: a_true - g_true * leak_shape(p) + noise };
        let r = ChokedFillModel.regress(&obs);
        rows.push((r.phi, r.y));
    }
    for lambda in [1.0f32, 0.999, 0.99] {
        let cfg = RlsConfig { forgetting: lambda, initial_covariance: 100.0, trace_max: 1e6 };
        let mut rls = Rls::<2>::new(cfg, [0.0; 2]).unwrap();
        for (phi, y) in &rows {
            rls.update(phi, *y).unwrap();
        }
        let ls = weighted_ls(&rows, f64::from(lambda), 100.0);
        for (r, l) in rls.theta().iter().zip(ls) {
            assert!((f64::from(*r) - l).abs() < 1e-4 * l.abs().max(1.0), "λ={lambda}: {:?} vs {ls:?}", rls.theta());
        }
        assert!((rls.theta()[0] - a_true).abs() < 0.03 && (rls.theta()[1] - g_true).abs() < 0.02);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Any ADC stream and any valve pattern: no panic, finite estimates, consistent reports.
    #[test]
    fn monitor_never_panics_on_any_adc_stream(
        adc in prop::collection::vec(any::<u16>(), 0..2500),
        valve in prop::collection::vec(any::<bool>(), 1..8),
    ) {
        let mut m = Monitor::new(&TwinParams::nominal()).unwrap();
        for (i, &c) in adc.iter().enumerate() {
            // Valve pattern held for 300 samples at a time.
            let open = valve[(i / 300) % valve.len()];
            let step = m.update(AdcCounts(c), open);
            let e = step.estimates;
            for v in [e.inflow_rate_bar_s, e.leak_mm, e.orifice_mm, e.supply_bar_g, e.plateau_bar_g].into_iter().flatten() {
                prop_assert!(v.is_finite());
            }
            let _ = m.status();
            let _ = pbm::pipeline::fault_report(&m, pbm::report::Verdict::CannotDiagnose(pbm::report::NoDiagnosis::TooShort));
        }
    }

    /// Long valid-range streams with the valve open (the estimator's phases all get exercised).
    #[test]
    fn monitor_handles_valid_range_streams(
        start in 205u16..3890, steps in prop::collection::vec(-40i16..40, 100..3000),
    ) {
        let mut m = Monitor::new(&TwinParams::nominal()).unwrap();
        let mut c = i32::from(start);
        for s in steps {
            c = (c + i32::from(s)).clamp(0, 4095);
            let step = m.update(AdcCounts(c as u16), true);
            let e = step.estimates;
            // Valve open: a release is in progress, whatever the pressure does.
            prop_assert_ne!(e.state, EstimatorState::Idle);
            prop_assert_ne!(e.phase, Phase::Idle);
            if let Some(s) = e.supply_bar_g {
                prop_assert!(s.is_finite());
                prop_assert_eq!(e.supply_mbar(), (s * 1000.0 + 0.5).clamp(0.0, 65_535.0) as u16);
            }
        }
        prop_assert_eq!(m.status().estimator, m.estimator().state());
    }
}
