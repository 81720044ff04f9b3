//! `cargo xtask fw-board`: the NUCLEO-F446RE board image (`firmware/board/`, its own Cargo
//! workspace) built from this clone, linted (rustfmt, clippy -D warnings) and sized against the
//! controller's budget. QEMU has no bxCAN and no STM32 clock tree, so this is a build + size +
//! static check; the behaviour is proven on the QEMU image, which runs the same application
//! (`firmware/src/app.rs`) with other drivers.

use crate::util::{cargo, require, stdout_of, Result};
use std::process::Command;

const MANIFEST: &str = "firmware/board/Cargo.toml";
const ELF: &str = "firmware/board/target/thumbv7em-none-eabihf/release/pbm-board";
/// The monitor's budget (issue 7), which the QEMU image meets; the board image adds the HAL's
/// drivers (clock tree, ADC + DMA, bxCAN, EXTI, IWDG, TIM2 time driver) and is reported beside it.
const BUDGET_FLASH: u64 = 32 * 1024;
const BUDGET_RAM: u64 = 8 * 1024;
/// Regression bounds of the board image (`BOUND_BOARD_*`).
const BOUNDS: &str = "bench/firmware-bounds.env";

fn bound(key: &str) -> Result<u64> {
    let text = std::fs::read_to_string(BOUNDS).map_err(|e| format!("cannot read {BOUNDS}: {e}"))?;
    text.lines()
        .filter(|l| !l.trim_start().starts_with('#'))
        .filter_map(|l| l.split_once('='))
        .find(|(k, _)| k.trim() == key)
        .and_then(|(_, v)| v.trim().parse().ok())
        .ok_or_else(|| format!("{BOUNDS} has no {key}"))
}

/// (text, data, bss) of an ELF (Berkeley format of `llvm-size`).
pub fn sizes(elf: &str) -> Result<(u64, u64, u64)> {
    let out = stdout_of(Command::new("llvm-size").arg(elf))?;
    let last = out.lines().last().unwrap_or("");
    let v: Vec<u64> = last.split_whitespace().take(3).filter_map(|x| x.parse().ok()).collect();
    match v.as_slice() {
        [t, d, b] => Ok((*t, *d, *b)),
        _ => Err(format!("cannot read llvm-size output: {out}")),
    }
}

/// The board image's flash (text + data) and static RAM (data + bss), bytes.
pub fn board_size() -> Result<(u64, u64)> {
    let (text, data, bss) = sizes(ELF)?;
    Ok((text + data, data + bss))
}

/// Builds the board image (release).
pub fn build() -> Result<()> {
    cargo(&["build", "--manifest-path", MANIFEST, "--target", crate::firmware::TARGET, "--release"])
}

/// Builds the board image (release), lints it, reports its size; fails past the budget.
pub fn check() -> Result<()> {
    require("llvm-size")?;
    let target = crate::firmware::TARGET;
    cargo(&["fmt", "--manifest-path", MANIFEST, "--", "--check"])?;
    cargo(&["clippy", "--manifest-path", MANIFEST, "--target", target, "--release", "--", "-D", "warnings"])?;
    build()?;
    let (flash, ram) = board_size()?;
    let (bound_flash, bound_ram) = (bound("BOUND_BOARD_FLASH")?, bound("BOUND_BOARD_STATIC_RAM")?);
    let versus = |v: u64, budget: u64| {
        if v <= budget {
            format!("{} B under", budget - v)
        } else {
            format!("{} B over", v - budget)
        }
    };
    println!(
        "fw-board: NUCLEO-F446RE image: flash {flash} B ({} the monitor's {BUDGET_FLASH} B budget; bound {bound_flash} B), \
         static RAM {ram} B ({} the {BUDGET_RAM} B budget; bound {bound_ram} B; the stack comes on top)",
        versus(flash, BUDGET_FLASH),
        versus(ram, BUDGET_RAM),
    );
    if flash > bound_flash || ram > bound_ram {
        return Err(format!(
            "the board image is past its bounds in {BOUNDS}: flash {flash} / {bound_flash} B, static RAM {ram} / {bound_ram} B"
        ));
    }
    Ok(())
}
