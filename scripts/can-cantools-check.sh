#!/usr/bin/env bash
# Off-the-shelf DBC tool check (issue 8): every frame host-sim emits decodes with Python
# cantools against can/brake_monitor.dbc, to the same values as host-sim's own decoder, with an
# independently computed E2E CRC. Creates a venv under target/ (PyPI: cantools).
set -euo pipefail
cd "$(dirname "$0")/.."

target_dir="${CARGO_TARGET_DIR:-target}"
venv="$target_dir/can-venv"
work="$target_dir/can-check"
mkdir -p "$work"

if ! "$venv/bin/python" -c 'import cantools' 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check cantools
fi

cargo build --quiet -p host-sim
hs="$target_dir/debug/host-sim"

# 1. The demonstration log: simulated releases through the monitor and the CAN reporter
#    (every diagnosis and reason code, sensor faults).
"$hs" can demo-log --out "$work/demo.log"
#    The codec sweep: every code and field values at and beyond the range edges.
"$hs" can demo-log --sweep --out "$work/sweep.log"
# 2. What `replay --can-log` writes for a simulated leaking release.
"$hs" simulate --leak-mm 0.8 --out "$work/leak.csv"
"$hs" replay "$work/leak.csv" --can-log "$work/replay.log" >/dev/null

status=0
for log in demo sweep replay; do
    "$hs" can decode --format csv "$work/$log.log" >"$work/$log.decoded.csv"
    extra=()
    [ "$log" = sweep ] && extra=(--require-all-labels)
    echo "--- $log.log"
    "$venv/bin/python" scripts/can_cantools_check.py can/brake_monitor.dbc "$work/$log.log" \
        "$work/$log.decoded.csv" "${extra[@]}" || status=1
done
exit $status
