#!/usr/bin/env bash
# rustfmt and clippy (warnings denied) for the firmware crate, which is its own workspace and
# so is not covered by `cargo fmt --all` / `cargo clippy --workspace` in the repository root.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo fmt --manifest-path firmware/Cargo.toml -- --check
cargo clippy --manifest-path firmware/Cargo.toml --target thumbv7em-none-eabihf --all-targets -- -D warnings
cargo clippy --manifest-path firmware/Cargo.toml --target thumbv7em-none-eabihf --all-targets --all-features -- -D warnings
echo "firmware-lint: OK"
