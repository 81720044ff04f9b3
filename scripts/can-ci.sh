#!/usr/bin/env bash
# Every CAN check of issue 8 in one command, for working on the CAN code: the CAN tests (DBC vs
# code, codec, E2E, decoder, heartbeat, schedule, pipeline ids, logs, display, mock bus) and
# scripts/test-extra-can.sh (socketcan feature build + clippy, cantools, fuzz target if
# cargo-fuzz is installed). CI runs the same tests in `cargo test --workspace` and the extra
# script through scripts/test-all.sh.
set -euo pipefail
cd "$(dirname "$0")/.."

printf '\n=== CAN tests\n'
cargo test -q -p parking-brake-monitor --test can_dbc --test can_codec
cargo test -q -p parking-brake-monitor --lib can::
cargo test -q -p host-sim --lib can_
cargo test -q -p host-sim --test can

printf '\n=== CAN extra checks\n'
bash scripts/test-extra-can.sh
