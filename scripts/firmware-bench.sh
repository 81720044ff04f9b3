#!/usr/bin/env bash
# Cost of the firmware on the Cortex-M4F, measured in QEMU (mps2-an386, -icount shift=0: one
# instruction = 1 ns of virtual time, deterministic):
#   - instructions per sample of the firmware's per-sample pipeline (core Monitor::update and
#     the CAN schedule), of the twin alone, of the feature extractor, and per classification,
#     from the `bench` binary (SysTick brackets around each call; calibrated on a known loop);
#   - flash and static RAM of the `monitor` application from its linked ELF (llvm-size, or
#     arm-none-eabi-size), with the ADC test trace compiled into flash counted separately;
#   - peak stack of the `monitor` application by stack painting (its own end-of-run report).
# Prints the figures and writes bench/firmware.md.
#   --check   also fail if a figure regresses past the bounds recorded below.
# Needs what scripts/firmware-qemu.sh needs, plus llvm-size (apt: llvm) or arm-none-eabi-size
# (apt: binutils-arm-none-eabi).
set -euo pipefail
cd "$(dirname "$0")/.."

CHECK=0
[ "${1:-}" = "--check" ] && CHECK=1

TARGET=thumbv7em-none-eabihf
ELF_DIR=firmware/target/$TARGET/release
# Targets of issue 7.
TARGET_INSTR=5000
TARGET_FLASH=$((32 * 1024))
TARGET_RAM=$((8 * 1024))
# Regression bounds for --check (measured figures + margin; update with the figures).
BOUND_PIPELINE_INSTR=2000
BOUND_FLASH=48000
BOUND_RAM=8192

die() { echo "firmware-bench: $*" >&2; exit 1; }
command -v qemu-system-arm >/dev/null || die "qemu-system-arm not found (apt-get install -y qemu-system-arm)"
if command -v llvm-size >/dev/null; then SIZE=llvm-size; NM=llvm-nm
elif command -v arm-none-eabi-size >/dev/null; then SIZE=arm-none-eabi-size; NM=arm-none-eabi-nm
else die "no ELF size tool: apt-get install -y llvm (or binutils-arm-none-eabi)"; fi

cargo build --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bins

echo "== bench binary in QEMU (-icount shift=0)"
BENCH_OUT=$(cargo run --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bin bench)
echo "$BENCH_OUT"
get() { echo "$BENCH_OUT" | sed -n "s/^$1=//p"; }

echo "== monitor application in QEMU (peak stack)"
MON_ERR=$(cargo run --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bin monitor 2>&1 >/dev/null) \
    || die "monitor run failed: $MON_ERR"
echo "$MON_ERR"
PEAK_STACK=$(echo "$MON_ERR" | sed -n 's/.*peak stack \([0-9]*\) bytes.*/\1/p')

# Berkeley format: text (incl. .vector_table, .rodata) data bss.
read -r TEXT DATA BSS _ < <($SIZE "$ELF_DIR/monitor" | tail -n 1)
TRACE_BYTES=$($NM --print-size --radix=d "$ELF_DIR/monitor" | awk '/ADC_TRACE/ && !n {n = $2 + 0} END {print n + 0}')
TRACE_BYTES=${TRACE_BYTES:-0}
FLASH_TOTAL=$((TEXT + DATA))
FLASH=$((FLASH_TOTAL - TRACE_BYTES))
STATIC_RAM=$((DATA + BSS))
RAM=$((STATIC_RAM + PEAK_STACK))

PIPE=$(get pipeline_instr_per_sample_mean); PIPE_MAX=$(get pipeline_instr_per_sample_max)
TWIN=$(get twin_instr_per_sample_mean); TWIN_MAX=$(get twin_instr_per_sample_max)
FEAT=$(get features_instr_per_sample_mean); FEAT_MAX=$(get features_instr_per_sample_max)
CLASSIFY=$(get classify_instr); CAL=$(get calibration_measured_instr)
FULL=$((PIPE + FEAT))
verdict() { if [ "$1" -le "$2" ]; then echo "ok"; else echo "OVER"; fi; }

REPORT=$(cat <<MD
# Firmware cost (Cortex-M4F, QEMU mps2-an386)

Measured by \`bash scripts/firmware-bench.sh\` ($(date -u +%Y-%m-%d), $(qemu-system-arm --version | head -n1)).
Instructions are counted with \`qemu-system-arm -icount shift=0\` (1 instruction = 1 ns of virtual
time, read through SysTick at 25 MHz = 40 instructions per count; calibration loop of 300000
instructions measured as $CAL). Means over the $(get samples) samples of the compiled-in trace
(\`$(basename "$ELF_DIR")\` profile: opt-level s, fat LTO).

| figure | value | target | |
|---|---|---|---|
| per-sample pipeline (Monitor::update + CAN schedule), mean / max | $PIPE / $PIPE_MAX instr | ≤ $TARGET_INSTR | $(verdict "$PIPE_MAX" $TARGET_INSTR) |
| of which twin (Twin::update), mean / max | $TWIN / $TWIN_MAX instr | | |
| feature extractor (features::FeatureExtractor::update), mean / max | $FEAT / $FEAT_MAX instr | | |
| pipeline + features per sample, mean | $FULL instr | ≤ $TARGET_INSTR | $(verdict "$FULL" $TARGET_INSTR) |
| per classification (classifier::diagnose) | $CLASSIFY instr | | |
| flash, \`monitor\` app (text + data, without the $TRACE_BYTES-byte test trace) | $FLASH B | ≤ $TARGET_FLASH | $(verdict "$FLASH" $TARGET_FLASH) |
| flash including the test trace | $FLASH_TOTAL B | | |
| static RAM (data + bss) | $STATIC_RAM B | | |
| peak stack (painted, \`monitor\` app, full 60 s run) | $PEAK_STACK B | | |
| RAM = static + peak stack | $RAM B | ≤ $TARGET_RAM | $(verdict "$RAM" $TARGET_RAM) |

The \`monitor\` application does not call the feature extractor or the classifier yet (the
core's Monitor does not produce a verdict yet); their costs are measured separately by the
\`bench\` binary on the same trace. The feature extractor computes in software f64 (the
Cortex-M4F FPU is single precision), which is why it dominates.

Reproduce: \`bash scripts/firmware-bench.sh\` (or \`cargo fw-bench\` for the raw figures).
MD
)
echo
echo "$REPORT"
mkdir -p bench
echo "$REPORT" > bench/firmware.md
echo
echo "firmware-bench: wrote bench/firmware.md"

if [ "$CHECK" = 1 ]; then
    fail=0
    [ "$PIPE" -le "$BOUND_PIPELINE_INSTR" ] || { echo "REGRESSION: pipeline $PIPE > $BOUND_PIPELINE_INSTR instr"; fail=1; }
    [ "$FLASH" -le "$BOUND_FLASH" ] || { echo "REGRESSION: flash $FLASH > $BOUND_FLASH B"; fail=1; }
    [ "$RAM" -le "$BOUND_RAM" ] || { echo "REGRESSION: RAM $RAM > $BOUND_RAM B"; fail=1; }
    [ "$fail" = 0 ] || exit 1
    echo "firmware-bench: within recorded bounds"
fi
