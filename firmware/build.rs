//! Link arguments for the firmware binaries (never in .cargo/config.toml, which the host
//! workspace shares), and the memory map from the repository root.

use std::path::PathBuf;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let root = manifest.parent().expect("firmware/ sits in the repository root");
    // cortex-m-rt's link.x INCLUDEs memory.x from the linker search path.
    println!("cargo:rustc-link-search={}", root.display());
    println!("cargo:rerun-if-changed={}", root.join("memory.x").display());
    println!("cargo:rerun-if-changed={}", root.join("tests/golden/nominal_checkpoints.csv").display());
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
}
