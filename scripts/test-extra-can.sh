#!/usr/bin/env bash
# CAN checks that `cargo test --workspace` does not cover (issue 8); scripts/test-all.sh (CI)
# runs every scripts/test-extra-*.sh. The CAN unit, property and integration tests themselves
# run in `cargo test --workspace` (tests/can_dbc.rs, tests/can_codec.rs, host-sim/tests/can.rs).
#
#   1. host-sim with the `socketcan` feature (off by default, so the workspace build never
#      compiles it): cargo check, and clippy with -D warnings.
#   2. Python cantools decodes every frame host-sim emits, unchanged, to host-sim's values
#      (scripts/can-cantools-check.sh).
#   3. With CAN_FUZZ=1, the decoder's fuzz target (fuzz/fuzz_targets/can_decode.rs) builds and
#      runs for a few seconds where cargo-fuzz and a nightly toolchain are installed. Off by
#      default (CI time); CAN_FUZZ_SECONDS sets the run time (default 10). Cost: a fresh
#      build (its own workspace, fuzz/target) took 7 min wall / 4.2 min CPU on the shared 2-core
#      machine under load; incremental builds about 2 min.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n--- can: %s\n' "$*"; }

step "host-sim --features socketcan: check + clippy"
cargo check --quiet -p host-sim --features socketcan
cargo clippy --quiet -p host-sim --features socketcan --all-targets -- -D warnings

step "cantools decodes every frame host-sim emits"
bash scripts/can-cantools-check.sh

step "fuzz target can_decode"
if [ "${CAN_FUZZ:-0}" = 0 ]; then
    echo "skipped (CAN_FUZZ=1 runs it)"
elif command -v cargo-fuzz >/dev/null 2>&1 && rustup toolchain list 2>/dev/null | grep -q '^nightly'; then
    (
        cd fuzz
        cargo +nightly fuzz build can_decode
        mkdir -p corpus/can_decode
        log="target/can_decode-run.log"
        rc=0
        cargo +nightly fuzz run can_decode -- -max_total_time="${CAN_FUZZ_SECONDS:-10}" >"$log" 2>&1 || rc=$?
        grep -E '^Done [0-9]+ runs' "$log" || true
        if [ "$rc" != 0 ]; then
            tail -n 40 "$log"
            echo "fuzz target can_decode failed (exit $rc); the input is in fuzz/artifacts/can_decode/" >&2
            exit "$rc"
        fi
    )
else
    echo "skipped: cargo-fuzz or a nightly toolchain is not installed (not required;"
    echo "  to run it: cargo install cargo-fuzz && rustup toolchain install nightly,"
    echo "  then: cd fuzz && cargo +nightly fuzz run can_decode)"
fi
echo "test-extra-can: done"
