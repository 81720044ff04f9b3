#!/usr/bin/env bash
# Builds the firmware (release) and runs `twin-check` in QEMU (mps2-an386, Cortex-M4F): the
# fixed-point twin must reproduce the host's golden checkpoints bit for bit (exit status 0).
# Then builds the self-test variant with one golden value perturbed and checks that its run
# FAILS (non-zero exit), so a passing run cannot be a check that never fails.
#
# Needs (installed by scripts/setup.sh): `rustup target add thumbv7em-none-eabihf` and
# `apt-get install -y qemu-system-arm`. This script installs nothing.
set -euo pipefail
cd "$(dirname "$0")/.."

TARGET=thumbv7em-none-eabihf
die() { echo "firmware-qemu: $*" >&2; exit 1; }

command -v qemu-system-arm >/dev/null \
    || die "qemu-system-arm not found: install it with 'apt-get install -y qemu-system-arm' (scripts/setup.sh does)"
qemu-system-arm -machine help | grep -q '^mps2-an386' \
    || die "this qemu-system-arm has no mps2-an386 machine (need QEMU >= 5.2)"
command -v timeout >/dev/null || die "timeout (coreutils) not found"
if command -v rustup >/dev/null; then
    rustup target list --installed | grep -qx "$TARGET" \
        || die "Rust target $TARGET missing: run 'rustup target add $TARGET' (scripts/setup.sh does)"
fi

# Every `cargo run` below goes through the runner of .cargo/config.toml:
# timeout 120 qemu-system-arm ... -icount shift=0,sleep=off -kernel <elf>
run_fw() {
    cargo run --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bin twin-check "$@"
}

echo "== firmware: twin-check in QEMU (expect exit 0)"
set +e
run_fw
status=$?
set -e
[ "$status" -eq 0 ] || die "twin-check failed in QEMU (exit status $status; 124 = timeout)"
echo "== firmware: twin-check passed (exit 0)"

echo "== firmware: self-test with a corrupted golden value (expect a non-zero exit)"
set +e
run_fw --features selftest-corrupt-golden
status=$?
set -e
[ "$status" -ne 0 ] || die "the corrupted-golden self-test exited 0: the QEMU check cannot detect a mismatch"
[ "$status" -ne 124 ] || die "the corrupted-golden self-test timed out instead of failing"
echo "== firmware: self-test failed as it must (exit $status)"

echo "== firmware: monitor application (embassy tasks) in QEMU on the compiled-in trace"
CANLOG=$(mktemp)
trap 'rm -f "$CANLOG"' EXIT
set +e
cargo run --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bin monitor >"$CANLOG"
status=$?
set -e
[ "$status" -eq 0 ] || die "monitor failed in QEMU (exit status $status; 124 = timeout)"
frames=$(wc -l <"$CANLOG")
[ "$frames" -gt 0 ] || die "monitor sent no CAN frame"
if grep -vEq '^\([0-9]{10}\.[0-9]{6}\) can0 ([0-9A-F]{3}|[0-9A-F]{8})#([0-9A-F]{2}){0,8}$' "$CANLOG"; then
    die "monitor wrote a line that is not a candump log line: $(grep -vEm1 '^\(' "$CANLOG")"
fi
# The diagnosis runs on the target: the 60 s window closes it and the fault report goes out.
grep -q ' can0 18FF5080#' "$CANLOG" || die "monitor sent no fault report frame (18FF5080)"
echo "== firmware: monitor passed (exit 0, $frames candump lines, fault report sent)"

# Leave the normal build as the current artefact.
cargo build --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bins
echo "firmware-qemu: OK"
