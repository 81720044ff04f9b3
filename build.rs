//! Generates the lookup tables of the fixed-point twin from the float formulas of SPEC §2.
//!
//! The tables live in flash as `const` arrays; the step code only interpolates them, so no
//! transcendental function (powf, sqrt, exp) is evaluated per sample on the controller.

use std::fmt::Write as _;
use std::path::PathBuf;

/// Specific heat ratio of air (SPEC §2).
const KAPPA: f64 = 1.4;
/// Critical pressure ratio (SPEC §2).
const P_CR: f64 = 0.528;
/// First grid point of the unchoked table, Q16 pressure ratio.
/// 65536 − 967·32: the grid ends exactly at r = 1 and starts just below P_cr (0.52783).
const FLOW_R0_Q16: u32 = 34_592;
/// Grid step of the flow table in Q16 pressure-ratio units (1/2048 of the ratio).
const FLOW_STEP_Q16: u32 = 32;
/// Grid step of the Stribeck table: u = |v|/vs in Q16, step 1/64.
const STRIBECK_STEP_Q16: u32 = 1024;
/// Stribeck table spans u in [0, 4): exp(-16) is below one Q16 LSB.
const STRIBECK_LEN: u32 = 4 * 64 + 1;

/// Normalised orifice flow phi(r)/C1: 1 when choked, the Sanville form above P_cr.
fn flow_norm(r: f64) -> f64 {
    let c1 = (KAPPA / 287.0 * (2.0 / (KAPPA + 1.0)).powf((KAPPA + 1.0) / (KAPPA - 1.0))).sqrt();
    let c2 = (2.0 * KAPPA / (287.0 * (KAPPA - 1.0))).sqrt();
    if r <= P_CR {
        1.0
    } else if r >= 1.0 {
        0.0
    } else {
        c2 * r.powf(1.0 / KAPPA) * (1.0 - r.powf((KAPPA - 1.0) / KAPPA)).sqrt() / c1
    }
}

/// The mechanisms' cargo features (`pbm::mechanism` names; Cargo.toml).
const MECHANISM_FEATURES: [&str; 10] = [
    "transport_delay",
    "valve_lag",
    "heat_transfer",
    "sensor_lag",
    "sensor_offset",
    "sensor_gain",
    "regulator_droop",
    "progressive_spring",
    "laminar_leak",
    "gas_temperature",
];

fn main() {
    // `mechanism_image`: some mechanism's feature on without `extensions` (a firmware image of
    // the mechanism an audit named), where the twin trades a little speed for flash.
    println!("cargo::rustc-check-cfg=cfg(mechanism_image)");
    let feature = |f: &str| std::env::var_os(format!("CARGO_FEATURE_{}", f.to_uppercase())).is_some();
    if !feature("extensions") && MECHANISM_FEATURES.iter().any(|f| feature(f)) {
        println!("cargo:rustc-cfg=mechanism_image");
    }
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let mut s = String::new();

    let flow_len = (65_536 - FLOW_R0_Q16).div_ceil(FLOW_STEP_Q16) + 1;
    writeln!(s, "/// First grid point (Q16 ratio) of [`FLOW_NORM_Q16`].").unwrap();
    writeln!(s, "pub const FLOW_R0_Q16: u32 = {FLOW_R0_Q16};").unwrap();
    writeln!(s, "/// log2 of the grid step of [`FLOW_NORM_Q16`] in Q16 ratio units.").unwrap();
    writeln!(s, "pub const FLOW_STEP_SHIFT: u32 = {};", FLOW_STEP_Q16.trailing_zeros()).unwrap();
    writeln!(s, "/// phi(r)/C1 in Q16 (saturated at 65535) on r = FLOW_R0 + i*step, i = 0..{flow_len}.").unwrap();
    writeln!(s, "pub static FLOW_NORM_Q16: [u16; {flow_len}] = [").unwrap();
    for i in 0..flow_len {
        let r = f64::from(FLOW_R0_Q16 + i * FLOW_STEP_Q16) / 65_536.0;
        let v = (flow_norm(r.min(1.0)) * 65_536.0).round().clamp(0.0, 65_535.0) as u16;
        write!(s, "{v},").unwrap();
        if i % 16 == 15 {
            s.push('\n');
        }
    }
    writeln!(s, "];").unwrap();

    // exp(-u^2) in Q16 on the grid; the table stops at its first zero (every later entry is 0
    // too, and the lookup reads a segment past the end as 0: the same values), and is u16 with
    // entry 0 (exactly 65536) stored as 65535 (the lookup uses 1 << 16 there).
    let exp_q16 = |i: u32| {
        let u = f64::from(i * STRIBECK_STEP_Q16) / 65_536.0;
        ((-u * u).exp() * 65_536.0).round() as u32
    };
    let stribeck_len = (0..STRIBECK_LEN).find(|&i| exp_q16(i) == 0).map_or(STRIBECK_LEN, |z| z + 1);
    writeln!(s, "/// log2 of the grid step of [`STRIBECK_EXP_Q16`] in Q16 units of |v|/vs.").unwrap();
    writeln!(s, "pub const STRIBECK_STEP_SHIFT: u32 = {};", STRIBECK_STEP_Q16.trailing_zeros()).unwrap();
    writeln!(
        s,
        "/// exp(-u^2) in Q16 on u = i/64, i = 0..{stribeck_len} (up to its first zero; entry 0 is 65536, stored as 65535)."
    )
    .unwrap();
    writeln!(s, "pub static STRIBECK_EXP_Q16: [u16; {stribeck_len}] = [").unwrap();
    for i in 0..stribeck_len {
        let v = exp_q16(i).min(65_535);
        write!(s, "{v},").unwrap();
        if i % 16 == 15 {
            s.push('\n');
        }
    }
    writeln!(s, "];").unwrap();

    std::fs::write(out.join("luts.rs"), s).expect("write luts.rs");
    println!("cargo:rerun-if-changed=build.rs");
}
