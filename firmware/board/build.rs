//! Link arguments of the board image: this directory's memory.x (cortex-m-rt's link.x INCLUDEs
//! it from the search path; the PAC brings device.x), defmt's section layout, and the CAN bit
//! rate chosen at build time.

use std::path::PathBuf;

/// CAN bit rates the build accepts (bit/s): the usual CAN 2.0 rates; J1939 uses 250 k and 500 k.
const BITRATES: [u32; 6] = [125_000, 250_000, 500_000, 1_000_000, 100_000, 50_000];

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    println!("cargo:rustc-link-search={}", manifest.display());
    println!("cargo:rerun-if-changed={}", manifest.join("memory.x").display());
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");

    // PBM_CAN_BITRATE (bit/s, default 250000): checked here so that a typo fails the build,
    // not the controller's start.
    println!("cargo:rerun-if-env-changed=PBM_CAN_BITRATE");
    let bitrate = match std::env::var("PBM_CAN_BITRATE") {
        Err(_) => 250_000,
        Ok(s) => match s.trim().parse::<u32>() {
            Ok(b) if BITRATES.contains(&b) => b,
            _ => {
                eprintln!("PBM_CAN_BITRATE={s}: expected one of {BITRATES:?} (bit/s)");
                std::process::exit(1);
            }
        },
    };
    println!("cargo:rustc-env=PBM_CAN_BITRATE={bitrate}");
}
