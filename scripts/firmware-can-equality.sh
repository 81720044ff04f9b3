#!/usr/bin/env bash
# Issue 7 item 3: for each recorded trace, the CAN frames the firmware sends in QEMU must equal,
# byte for byte, the candump log `host-sim replay TRACE --can-log FILE` writes (same frames,
# same time stamps: both stamp sample n at n x 10 ms with pbm::pipeline::candump).
#
# Traces: the 6 test and 6 `_0000` training traces of tests/data/small (all six classes), the
# sensor-fault traces of tests/data/sensor_fault (open circuit, frozen, spikes, lost bits,
# noisy, clipped: every kind of plausibility check that closes a diagnosis), the releases
# outside the five classes of tests/data/independent, and one release cut at 15 s (made here from a small-set trace), so that the end of the input, not
# the 60 s window, closes the diagnosis (Pipeline::close).
#
# The firmware plays a trace compiled into flash (firmware/build.rs, PBM_FW_TRACE), so the
# `monitor` binary is rebuilt per trace (build script + relink, a few seconds each), then run
# in QEMU (runner of .cargo/config.toml: `timeout 120 qemu-system-arm ... -icount shift=0`).
# Exit status non-zero on any difference, on a firmware run that fails, or if a trace produces
# no fault report. The default firmware build is restored at the end.
# Needs what scripts/firmware-qemu.sh needs. Runs in about a minute (2 cores, warm caches).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
TARGET=thumbv7em-none-eabihf
FAULT_ID=18FF5080

die() { echo "firmware-can-equality: $*" >&2; exit 1; }
command -v qemu-system-arm >/dev/null || die "qemu-system-arm not found (apt-get install -y qemu-system-arm)"
command -v timeout >/dev/null || die "timeout (coreutils) not found"

WORK=$(mktemp -d)
restore() {
    rm -rf "$WORK"
    # Leave the default firmware (compiled-in nominal trace) as the current artefact.
    env -u PBM_FW_TRACE cargo build --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bins \
        || echo "firmware-can-equality: warning: could not rebuild the default firmware" >&2
}
trap restore EXIT

TRACES=()
for class in normal air_leak orifice_block leak_and_block low_supply orifice_missing; do
    TRACES+=("tests/data/small/traces/test/${class}_0000.csv" "tests/data/small/traces/train/${class}_0000.csv")
done
TRACES+=(tests/data/sensor_fault/*.csv)
# Releases outside the five classes from the independent plant: the class-region and steady-supply
# rules of the out-of-distribution guard, in f32 on both targets.
TRACES+=(tests/data/independent/unfamiliar_*.csv)
# A release cut short: metadata, header and the first 1500 samples (15 s) of a small-set trace.
SHORT="$WORK/orifice_block_cut_15s.csv"
awk '/^#/ || /^t_s/ {print; next} {if (++n > 1500) exit; print}' \
    tests/data/small/traces/test/orifice_block_0000.csv >"$SHORT"
TRACES+=("$SHORT")
for t in "${TRACES[@]}"; do [ -f "$t" ] || die "missing trace $t"; done

# The `test` profile: the same host-sim artifacts `cargo test --workspace` builds.
cargo build --quiet --profile test -p host-sim
HOST_SIM=target/debug/host-sim

fail=0
n=0
declare -A seen_logs=()
for t in "${TRACES[@]}"; do
    n=$((n + 1))
    abs=$(cd "$(dirname "$t")" && pwd)/$(basename "$t")
    case "$t" in
        "$WORK"/*) name="(made here) $(basename "$t")" ;;
        *) name=${t#tests/data/} ;;
    esac
    host_log="$WORK/$n-host.log"
    fw_log="$WORK/$n-fw.log"
    fw_err="$WORK/$n-fw.err"
    "$HOST_SIM" replay "$abs" --can-log "$host_log" >/dev/null 2>"$WORK/$n-host.err" \
        || { cat "$WORK/$n-host.err" >&2; die "host-sim replay failed on $t"; }
    set +e
    PBM_FW_TRACE="$abs" timeout 300 cargo run --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" \
        --release --bin monitor >"$fw_log" 2>"$fw_err"
    status=$?
    set -e
    verdict=$(sed -n 's/^monitor: diagnosis closed //p' "$fw_err" | tail -n 1)
    frames=$(wc -l <"$fw_log")
    if [ "$status" -ne 0 ]; then
        echo "FAIL  $name: firmware exit status $status (124 = timeout)"
        sed 's/^/      /' "$fw_err"
        fail=1
    elif ! cmp -s "$host_log" "$fw_log"; then
        echo "FAIL  $name: QEMU and host logs differ ($frames firmware lines, $(wc -l <"$host_log") host lines)"
        diff "$host_log" "$fw_log" | head -n 10 | sed 's/^/      /'
        fail=1
    elif ! grep -q " can0 $FAULT_ID#" "$fw_log"; then
        echo "FAIL  $name: no fault report frame ($FAULT_ID) sent"
        fail=1
    else
        echo "ok    $name: $frames frames identical; $verdict"
    fi
    seen_logs[$(sha256sum <"$fw_log" | cut -c1-16)]=1
done

# The check must be able to see a difference: different traces give different logs.
[ "${#seen_logs[@]}" -gt 1 ] || die "all firmware logs are identical: the trace is not reaching the firmware"
[ "$fail" = 0 ] || die "QEMU and host-sim CAN logs differ (see above)"
echo "firmware-can-equality: $n traces, firmware CAN frames identical to host-sim replay --can-log"
