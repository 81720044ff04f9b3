#!/usr/bin/env bash
# Cost of the firmware on the Cortex-M4F, measured in QEMU (mps2-an386, -icount shift=0: one
# instruction = 1 ns of virtual time, deterministic):
#   - instructions per sample of the core's per-sample path pbm::pipeline::Pipeline::step (twin,
#     residual, online estimator, release features, diagnosis policy, CAN schedule and frame
#     encoding: all the monitor task does per sample), of the twin alone and of the release
#     features alone; the sample that closes a diagnosis (it also runs the classifier) and one
#     classification, from the `bench` binary (SysTick brackets around each call, calibrated on
#     a loop of known length);
#   - flash and static RAM of the `monitor` application from its linked ELF (llvm-size or
#     arm-none-eabi-size), the ADC test trace compiled into flash counted separately, and flash
#     by component (nm);
#   - peak stack of the `monitor` application by stack painting (its own end-of-run report).
#
#   bash scripts/firmware-bench.sh           prints the figures and writes bench/firmware.md
#   bash scripts/firmware-bench.sh --check   prints them and fails if one regresses past the bounds
#                                            recorded in bench/firmware-bounds.env (writes nothing)
# Needs what scripts/firmware-qemu.sh needs, plus llvm-size/llvm-nm (apt: llvm) or
# arm-none-eabi-size/nm (apt: binutils-arm-none-eabi).
set -euo pipefail
cd "$(dirname "$0")/.."

CHECK=0
case "${1:-}" in
    --check) CHECK=1 ;;
    "") ;;
    *) echo "usage: $0 [--check]" >&2; exit 2 ;;
esac

TARGET=thumbv7em-none-eabihf
ELF_DIR=firmware/target/$TARGET/release
BOUNDS=bench/firmware-bounds.env
# Targets of issue 7.
TARGET_INSTR=5000
TARGET_FLASH=$((32 * 1024))
TARGET_RAM=$((8 * 1024))

die() { echo "firmware-bench: $*" >&2; exit 1; }
command -v qemu-system-arm >/dev/null || die "qemu-system-arm not found (apt-get install -y qemu-system-arm)"
if command -v llvm-size >/dev/null; then SIZE=llvm-size; NM=llvm-nm
elif command -v arm-none-eabi-size >/dev/null; then SIZE=arm-none-eabi-size; NM=arm-none-eabi-nm
else die "no ELF size tool: apt-get install -y llvm (or binutils-arm-none-eabi)"; fi

# The default build: the compiled-in trace is the core twin's nominal release (PBM_FW_TRACE unset).
unset PBM_FW_TRACE
cargo build --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bins

echo "== bench binary in QEMU (-icount shift=0)"
BENCH_OUT=$(cargo run --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bin bench) \
    || die "bench run failed: $BENCH_OUT"
echo "$BENCH_OUT"
get() {
    local v
    v=$(echo "$BENCH_OUT" | sed -n "s/^$1=//p")
    [ -n "$v" ] || die "bench printed no $1"
    echo "$v"
}

echo "== monitor application in QEMU (peak stack)"
MON_ERR=$(cargo run --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bin monitor 2>&1 >/dev/null) \
    || die "monitor run failed: $MON_ERR"
echo "$MON_ERR"
PEAK_STACK=$(echo "$MON_ERR" | sed -n 's/.*peak stack \([0-9]*\) bytes.*/\1/p')
[ -n "$PEAK_STACK" ] || die "monitor reported no peak stack"
VERDICT=$(echo "$MON_ERR" | sed -n 's/^monitor: diagnosis closed //p' | tail -n 1)

# The same bench on recorded (noisy) traces: the estimator's block updates and the twin's
# piston substeps make the worst sample trace dependent. Rebuilt per trace (PBM_FW_TRACE).
RECORDED=(tests/data/small/traces/test/low_supply_0000.csv tests/data/small/traces/test/orifice_missing_0000.csv
    tests/data/small/traces/test/leak_and_block_0000.csv tests/data/sensor_fault/normal_open_circuit.csv)
TRACE_ROWS=""
WORST=0
for t in "${RECORDED[@]}"; do
    echo "== bench on $t"
    out=$(PBM_FW_TRACE="$PWD/$t" cargo run --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bin bench) \
        || die "bench run on $t failed: $out"
    tget() { echo "$out" | sed -n "s/^$1=//p"; }
    mean=$(tget pipeline_instr_per_sample_mean); max=$(tget pipeline_instr_per_sample_max)
    over=$(tget pipeline_samples_over_budget); est=$(tget estimator_instr_per_sample_max)
    echo "mean=$mean max=$max over_budget=$over estimator_max=$est"
    TRACE_ROWS+="| \`${t#tests/data/}\` | $mean | $max | $over | $est | $(tget classify_instr) |"$'\n'
    [ "$max" -le "$WORST" ] || WORST=$max
done
# Leave the default build (compiled-in nominal trace) as the current artefact.
cargo build --quiet --manifest-path firmware/Cargo.toml --target "$TARGET" --release --bins

ELF="$ELF_DIR/monitor"
# Berkeley format: text (incl. .vector_table, .rodata) data bss.
read -r TEXT DATA BSS _ < <($SIZE "$ELF" | tail -n 1)
TRACE_BYTES=$($NM --print-size --radix=d "$ELF" | awk '/ADC_TRACE/ && !n {n = $2 + 0} END {print n + 0}')
FLASH_TOTAL=$((TEXT + DATA))
FLASH=$((FLASH_TOTAL - TRACE_BYTES))
STATIC_RAM=$((DATA + BSS))
RAM=$((STATIC_RAM + PEAK_STACK))

# Flash by component: every text/rodata symbol of the ELF, by name (inlined code counts where it
# was inlined: the embassy task bodies include the inlined parts of Pipeline::step).
COMPONENTS=$($NM --print-size --radix=d --demangle "$ELF" | awk '
    NF >= 4 && $3 ~ /^[tTrR]$/ {
        name = $4; for (i = 5; i <= NF; i++) name = name " " $i
        size = $2 + 0
        if (name ~ /ADC_TRACE/) next
        if (name ~ /^pbm::(twin|params|fixed|sensor|units)/) c = "core: twin, parameters, sensor map"
        else if (name ~ /^pbm::classifier/) c = "core: classifier (code + int8 model)"
        else if (name ~ /^pbm::(estimator|features|monitor)/) c = "core: estimator, features, monitor"
        else if (name ~ /^pbm::(can|pipeline)/) c = "core: CAN codec, schedule, pipeline, candump"
        else if (name ~ /^pbm::/) c = "core: other"
        else if (name ~ /__aeabi_(d|f2d|l2d|ul2d)|df3|dfsi|dfdi|unorddf/) c = "soft-float f64"
        else if (name ~ /^libm::/) c = "libm (software sqrtf of the estimator and features)"
        else if (name ~ /^(embassy|_embassy|monitor::|pbm_firmware|cortex_m|__INTERRUPTS|__EXCEPTIONS|Reset|SysTick|DefaultHandler|HardFault|__pre_init|main$|_\$LT\$embassy|<embassy)/) c = "runtime: embassy executor + sync, tasks, vectors, console"
        else if (name ~ /compiler_builtins|__aeabi|__udiv|__divmod|__umod|memcpy|memmove|memset|memclr/) c = "compiler builtins: mem*, 64-bit division, f32 helpers"
        else if (name ~ /^(core::|<core|_\$LT\$core|<&|<usize|<u32|<u64|<.*as core::fmt|__rustc)/) c = "core::fmt and panic paths (bounds checks)"
        else c = "other (anonymous constants, ...)"
        s[c] += size; total += size
    }
    END { for (c in s) printf "| %s | %d |\n", c, s[c]; printf "| **sum of symbols** | %d |\n", total }' | sort -t'|' -k3 -rn)

PIPE=$(get pipeline_instr_per_sample_mean); PIPE_MAX=$(get pipeline_instr_per_sample_max)
CLOSING=$(get closing_sample_instr)
TWIN=$(get twin_instr_per_sample_mean); TWIN_MAX=$(get twin_instr_per_sample_max)
FEAT=$(get features_instr_per_sample_mean); FEAT_MAX=$(get features_instr_per_sample_max)
CLASSIFY=$(get classify_instr); CAL=$(get calibration_measured_instr); SAMPLES=$(get samples)
OVER=$(get pipeline_samples_over_budget); EST_MAX=$(get estimator_instr_per_sample_max)
[ "$PIPE_MAX" -le "$WORST" ] || WORST=$PIPE_MAX
verdict() { if [ "$1" -le "$2" ]; then echo "ok"; else echo "**OVER**"; fi; }

REPORT=$(cat <<MD
# Firmware cost (Cortex-M4F, QEMU mps2-an386)

Measured by \`bash scripts/firmware-bench.sh\` ($(date -u +%Y-%m-%d), $(qemu-system-arm --version | head -n1)).
Instructions are counted with \`qemu-system-arm -icount shift=0\` (1 instruction = 1 ns of virtual
time, read through SysTick at 25 MHz = 40 instructions per count; calibration loop of 300000
instructions measured as $CAL). Over the $SAMPLES samples of the compiled-in trace (the core
twin's nominal release with σ = 0.01 bar of transducer noise, 60 s). Profile \`release\` of \`firmware/Cargo.toml\`: opt-level "z", the
core (\`parking-brake-monitor\`) at "s" (at "z" the worst sample exceeds the budget), fat LTO,
codegen-units 1, panic = abort.

| figure | value | target | |
|---|---|---|---|
| **per-sample pipeline** \`Pipeline::step\` (twin, estimator, release features, diagnosis policy, CAN schedule), nominal release, mean / worst sample | $PIPE / $PIPE_MAX instr | ≤ $TARGET_INSTR | $(verdict "$PIPE_MAX" $TARGET_INSTR) |
| worst sample over all measured traces (table below) | $WORST instr | ≤ $TARGET_INSTR | $(verdict "$WORST" $TARGET_INSTR) |
| of which twin (\`Twin::update\`), mean / worst | $TWIN / $TWIN_MAX instr | | |
| of which online estimator (\`ReleaseEstimator::update\`, f32 RLS), mean / worst | $(get estimator_instr_per_sample_mean) / $EST_MAX instr | | |
| of which release features (\`ReleaseFeatures::update\`, f32), mean / worst | $FEAT / $FEAT_MAX instr | | |
| **per classification** (\`classifier::diagnose\`, int8 network, once per release) | $CLASSIFY instr | | |
| MetroPT-3 reservoir model (\`reservoir::Reservoir::update\` with heat transfer + transport delay, one 0.5 s substep; bench binary only), mean / worst | $(get reservoir_instr_per_substep_mean) / $(get reservoir_instr_per_substep_max) instr | | |
| the sample that closes a diagnosis (step + classification + report frame) | $CLOSING instr | < 250000 (10 ms at 25 MHz) | $(verdict "$CLOSING" 250000) |
| **flash**, \`monitor\` app (text + rodata + data, without the $TRACE_BYTES-byte test trace) | $FLASH B | ≤ $TARGET_FLASH | $(verdict "$FLASH" $TARGET_FLASH) |
| flash including the test trace | $FLASH_TOTAL B | | |
| static RAM (data + bss; the pipeline lives in the monitor task's static storage) | $STATIC_RAM B | | |
| peak stack (painted, \`monitor\` app, whole run incl. the classification) | $PEAK_STACK B | | |
| **RAM** = static + peak stack | $RAM B | ≤ $TARGET_RAM | $(verdict "$RAM" $TARGET_RAM) |

The \`monitor\` run on this trace: diagnosis closed $VERDICT.

## Per-sample cost by trace

\`Pipeline::step\` per sample (instructions) over a whole 60 s release; "over" = samples above
the $TARGET_INSTR-instruction budget. The estimator spreads its block work over the samples
(\`src/estimator/mod.rs\`, "Per-sample cost"): one RLS window update per sample, the reported
window first, and the plateau's supply solution a few bisection steps per sample. The worst
samples are block samples (block sum, rate, CUSUM, the reported window's update, plateau level)
coinciding with twin substeps while the nominal twin's piston moves.

| trace | mean | worst | over | estimator worst | classification |
|---|---|---|---|---|---|
| nominal twin release (compiled-in default, with transducer noise) | $PIPE | $PIPE_MAX | $OVER | $EST_MAX | $CLASSIFY |
${TRACE_ROWS%$'\n'}

## Flash by component (\`monitor\` app, bytes of text + rodata symbols)

| component | bytes |
|---|---|
$COMPONENTS

## Flash against the 32 KiB target

What was cut (2026-11-23, from 48008 B, nothing the monitor does removed):

- the twin's optional mechanisms (\`params::Extensions\`, ≈ 4.4 KiB): the core's cargo feature
  \`extensions\` (default, host tools) is off in the firmware, which runs only the nominal twin;
  \`Twin::update\` then never takes the extended path and \`TwinCoeffs::new\` rejects parameters
  that use a mechanism;
- \`f64\` soft-float and \`libm\` set-up: \`Pipeline::nominal\` builds the twin and the estimator
  from precomputed constants (\`TwinCoeffs::NOMINAL\`, the estimator's nominal design constants),
  each checked by a test against the \`f64\` computation from \`TwinParams::nominal()\`;
- the classifier's input map in \`f32\` (the same int8 inputs on every golden vector, and the
  same verdicts on the fleet data set) and its softmax table without the zero tail;
- the Stribeck table as \`u16\` up to its first zero (same values);
- the vector table: the AN386's 32 device interrupts instead of 240 (\`firmware/src/vectors.rs\`);
- \`memmove\` (1.5 KiB), pulled in by embassy's generic timer queue and by a send future holding a
  frame: a fixed-slot timer queue, and a send that builds the message once there is room.

Still in the image and candidates if the budget tightens: \`libm::sqrtf\` in software (≈ 0.5 KiB;
the FPU's \`VSQRT\` needs an \`unsafe\` asm block, which the core forbids); the core at opt-level
"z" (≈ 0.8 KiB, but the worst sample then exceeds $TARGET_INSTR instructions).

Regression bounds (\`bash scripts/firmware-bench.sh --check\`, run in CI by
\`scripts/test-extra-firmware-can.sh\`) are in \`bench/firmware-bounds.env\`.

Reproduce: \`bash scripts/firmware-bench.sh\` (or \`cargo fw-bench\` for the raw figures).
MD
)
echo
echo "$REPORT"

if [ "$CHECK" = 0 ]; then
    mkdir -p bench
    echo "$REPORT" > bench/firmware.md
    echo
    echo "firmware-bench: wrote bench/firmware.md"
    exit 0
fi

[ -f "$BOUNDS" ] || die "no $BOUNDS"
# shellcheck source=/dev/null
. "$BOUNDS"
fail=0
bound() { # name value bound
    if [ "$2" -le "$3" ]; then echo "  $1: $2 <= $3"; else echo "REGRESSION: $1 $2 > bound $3 ($BOUNDS)"; fail=1; fi
}
echo
echo "== bounds ($BOUNDS)"
bound "pipeline instr/sample mean" "$PIPE" "$BOUND_PIPELINE_INSTR_MEAN"
bound "pipeline instr/sample worst (nominal trace)" "$PIPE_MAX" "$BOUND_PIPELINE_INSTR_MAX"
bound "pipeline instr/sample worst (all traces)" "$WORST" "$BOUND_PIPELINE_INSTR_WORST"
bound "classification instr" "$CLASSIFY" "$BOUND_CLASSIFY_INSTR"
bound "closing sample instr" "$CLOSING" "$BOUND_CLOSING_SAMPLE_INSTR"
bound "flash bytes" "$FLASH" "$BOUND_FLASH"
bound "RAM bytes" "$RAM" "$BOUND_RAM"
[ "$fail" = 0 ] || exit 1
echo "firmware-bench: within recorded bounds"
