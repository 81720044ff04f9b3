#!/usr/bin/env bash
# CAN checks beyond `cargo test --workspace` (issue 8): the SocketCAN build of host-sim
# (feature off by default, so the plain workspace build never compiles it), its lints, the CAN
# tests, and the off-the-shelf DBC tool check with Python cantools.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n=== %s\n' "$*"; }

step "host-sim with --features socketcan (check + clippy)"
cargo check -p host-sim --features socketcan
cargo clippy -p host-sim --features socketcan --all-targets -- -D warnings

step "CAN tests (DBC vs code, codec, E2E, decoder, schedule, logs, mock bus)"
cargo test -q -p parking-brake-monitor --test can_dbc --test can_codec
cargo test -q -p parking-brake-monitor --lib can::
cargo test -q -p host-sim --lib can_
cargo test -q -p host-sim --test can

step "cantools decodes every frame host-sim emits"
bash scripts/can-cantools-check.sh
