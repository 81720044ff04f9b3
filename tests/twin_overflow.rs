//! The extended twin is free of integer overflow over the whole valid parameter box (issue 17,
//! item 4): every base parameter anywhere in the range `TwinParams::validate` accepts, each
//! mechanism off or anywhere in its `brake.valid` range, alone or in any combination.
//!
//! The test profile builds with `overflow-checks = true` (Cargo.toml `[profile.test]`), so an
//! overflow in the fixed-point arithmetic panics here instead of wrapping silently as it would in
//! a release build.

use pbm::mechanism::{Extensions, Mechanism};
use pbm::twin::{Twin, TwinSample};
use pbm::units::{BarG, Meters};
use pbm::TwinParams;
use proptest::prelude::*;

/// Samples with the valve open (60 s), then with it closed (30 s).
const OPEN_SAMPLES: usize = 6000;
const CLOSED_SAMPLES: usize = 3000;

/// Cases per property: 256, or `PROPTEST_CASES` for a longer search.
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
}

/// A uniform draw in `lo..=hi` from `u` in 0..=1.
fn lerp((lo, hi): (f64, f64), u: f64) -> f64 {
    (lo + (hi - lo) * u).clamp(lo, hi)
}

/// Base parameters from 16 uniform numbers: each anywhere in its valid range.
fn base_params(u: &[f64; 16]) -> TwinParams {
    let coulomb = lerp((1.0, 1e4), u[13]);
    TwinParams {
        supply: BarG(lerp((0.0, 15.0), u[0])),
        orifice: Meters(lerp((0.0, 10e-3), u[1])),
        leak: Meters(lerp((0.0, 5e-3), u[2])),
        discharge_coeff: lerp((0.05, 1.0), u[3]),
        dead_volume_m3: lerp((0.2e-3, 50e-3), u[4]),
        piston_area_m2: lerp((1e-4, 0.1), u[5]),
        stroke: Meters(lerp((1e-3, 0.4), u[6])),
        mass_kg: lerp((0.5, 500.0), u[7]),
        preload_n: lerp((0.0, 60e3), u[8]),
        spring_rate_n_per_m: lerp((0.0, 4e6), u[9]),
        sigma0_n_per_m: lerp((1e3, 4e6), u[10]),
        sigma1_n_s_per_m: lerp((0.0, 1e5), u[11]),
        viscous_n_s_per_m: lerp((0.0, 1e5), u[12]),
        coulomb_n: coulomb,
        static_n: lerp((coulomb, 1e4), u[14]),
        stribeck_m_per_s: lerp((1e-4, 1.0), u[15]),
        ext: Extensions::NONE,
    }
}

/// A unit coordinate at 0 or 1, within 1e-6 of either, or uniform in 0..=1.
fn corner_biased() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.0), Just(1.0), 0.0..=1e-6, (1.0 - 1e-6)..=1.0, 0.0..=1.0]
}

/// Mechanism `m` at the unit coordinate `u` of its valid range.
fn mechanism_value(m: Mechanism, u: f64) -> f64 {
    lerp(m.descriptor().brake.valid, u)
}

/// The mechanisms switched on: none (`mode` 0), one (`mode` 1: `pick`), or the subset `mask`.
fn extensions(mode: u8, pick: usize, mask: u16, u: &[f64; Mechanism::COUNT]) -> Extensions {
    let mut e = Extensions::NONE;
    for (i, m) in Mechanism::ALL.into_iter().enumerate() {
        let on = match mode {
            0 => false,
            1 => i == pick % Mechanism::COUNT,
            _ => mask & (1 << i) != 0,
        };
        if on {
            e[m] = mechanism_value(m, u[i]);
        }
    }
    e
}

/// Runs the release and the vent, checking that every sample is physically bounded. Overflow
/// panics come from the arithmetic itself (overflow checks on).
fn run(params: &TwinParams) -> Result<(), TestCaseError> {
    let Ok(mut twin) = Twin::new(params) else {
        // Inside the validate() box but beyond the orifice gain the fixed-point step supports:
        // rejected at construction, nothing to run.
        return Ok(());
    };
    let supply = twin.coeffs().supply().q().to_f64();
    // The stroke as the twin stores it (Q32 rounding of the parameter): an upper bound.
    let stroke = params.stroke.0 + 1e-9;
    // The state's pressure is clamped to 0..=30 bar abs; physically it stays between vacuum
    // and the supply (plus compression by the returning piston and gas heating: margin).
    let p_hi = supply.max(1.0) * 1.5 + 1.0;
    for i in 0..OPEN_SAMPLES + CLOSED_SAMPLES {
        let TwinSample { travel, .. } = twin.update(i < OPEN_SAMPLES);
        let p = twin.state().p.q().to_f64();
        prop_assert!(p >= 0.0 && p <= p_hi, "sample {i}: pressure {p} bar abs outside 0..={p_hi}");
        let x = travel.to_m().0;
        prop_assert!((0.0..=stroke).contains(&x), "sample {i}: travel {x} m outside 0..={stroke}");
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    /// Random parameter sets over the whole valid box, with no mechanism, one mechanism or a
    /// random combination.
    #[test]
    fn extended_twin_never_overflows(
        base in prop::array::uniform16(0.0..=1.0f64),
        mode in 0u8..3,
        pick in 0usize..Mechanism::COUNT,
        mask in 0u16..(1 << Mechanism::COUNT),
        mech in prop::array::uniform10(0.0..=1.0f64),
    ) {
        let mut params = base_params(&base);
        params.ext = extensions(mode, pick, mask, &mech);
        prop_assert!(params.validate().is_ok(), "drawn outside the valid box: {params:?}");
        run(&params)?;
    }

    /// As above with every coordinate (base parameters and mechanism magnitudes) at an end of
    /// its range, just inside it, or anywhere: the corners of the box, where the products are
    /// largest (smallest volume, largest orifice, leak, temperature, shortest time constants).
    #[test]
    fn extended_twin_never_overflows_at_the_corners(
        base in prop::array::uniform16(corner_biased()),
        mode in 0u8..3,
        pick in 0usize..Mechanism::COUNT,
        mask in 0u16..(1 << Mechanism::COUNT),
        mech in prop::array::uniform10(corner_biased()),
    ) {
        let mut params = base_params(&base);
        params.ext = extensions(mode, pick, mask, &mech);
        prop_assert!(params.validate().is_ok(), "drawn outside the valid box: {params:?}");
        run(&params)?;
    }

    /// The reported corner: a large release orifice (2.8 mm and more) on the nominal brake with
    /// one mechanism anywhere in its valid range.
    #[test]
    fn large_orifice_with_one_mechanism_never_overflows(
        orifice_mm in 2.8..=10.0f64,
        pick in 0usize..Mechanism::COUNT,
        u in 0.0..=1.0f64,
    ) {
        let mut params = TwinParams::nominal().with_orifice_mm(orifice_mm);
        let m = Mechanism::ALL[pick];
        params.ext[m] = mechanism_value(m, u);
        run(&params)?;
    }
}

/// Every mechanism at both ends of its valid range (and just inside the lower end), alone, on the nominal brake with orifices
/// from 0.5 to 10 mm, and with a large leak (a deterministic grid of the reported failures).
#[test]
fn mechanism_range_ends_with_large_orifices() {
    for orifice_mm in [0.5, 1.25, 2.8, 3.5, 5.0, 7.0, 10.0] {
        for leak_mm in [0.0, 5.0] {
            for m in Mechanism::ALL {
                let (lo, hi) = m.descriptor().brake.valid;
                // Both ends, and just above the lower one (the shortest time constants).
                for value in [lo, hi, lo + 1e-12, lo + 1e-6 * (hi - lo), lo + 1e-3 * (hi - lo)] {
                    let mut params = TwinParams::nominal().with_orifice_mm(orifice_mm).with_leak_mm(leak_mm);
                    params.ext[m] = value;
                    if let Err(e) = run(&params) {
                        panic!("{orifice_mm} mm orifice, {leak_mm} mm leak, {m} = {value}: {e}");
                    }
                }
            }
        }
    }
}
