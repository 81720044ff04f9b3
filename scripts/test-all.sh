#!/usr/bin/env bash
# Runs every check of the project: formatting, lints (host and Cortex-M4F), all tests, the
# firmware build and its QEMU run. This is the command README.md gives and .ci/run calls.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/setup.sh

step() { printf '\n=== %s\n' "$*"; }

step "format"
cargo fmt --all -- --check

step "clippy (host, all targets)"
cargo clippy --workspace --all-targets -- -D warnings

step "clippy (core on thumbv7em-none-eabihf)"
cargo clippy -p parking-brake-monitor --target thumbv7em-none-eabihf -- -D warnings

step "clippy + fmt (firmware)"
bash scripts/firmware-lint.sh

for extra in scripts/test-extra-*.sh; do
    [ -e "$extra" ] || continue
    step "$extra"
    bash "$extra"
done

step "tests (host)"
cargo test --workspace

if [ -x scripts/firmware-qemu.sh ] || [ -f scripts/firmware-qemu.sh ]; then
    step "firmware in QEMU"
    bash scripts/firmware-qemu.sh
fi
echo
echo "test-all: all checks passed"
