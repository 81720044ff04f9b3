#!/usr/bin/env bash
# Off-the-shelf DBC tool check (issue 8): every frame host-sim emits decodes with Python
# cantools against can/brake_monitor.dbc, unchanged, to the same values as host-sim's own
# decoder (`host-sim can decode --format csv`), with an independently computed E2E CRC.
#
# Logs checked:
#   demo    `host-sim can demo-log`: simulated releases through the monitor and the CAN
#           reporter (every diagnosis and reason code, sensor faults);
#   sweep   `host-sim can demo-log --sweep`: every code, field values at and beyond the edges;
#   small   `host-sim replay tests/data/small --can-log`: the pipeline the firmware runs, over
#           the committed small data set (one restarted monitor per trace).
#
# Python: a venv under target/ with cantools from PyPI (pinned below). If `python3 -m venv`
# does not work (Debian without python3-venv), installs python3-venv with apt (as root or
# through sudo) and tries again.
set -euo pipefail
cd "$(dirname "$0")/.."

CANTOOLS_VERSION="${CANTOOLS_VERSION:-45.1.0}"
target_dir="${CARGO_TARGET_DIR:-target}"
venv="$target_dir/can-venv"
work="$target_dir/can-check"
mkdir -p "$work"

apt_install() {
    local sudo=""
    if [ "$(id -u)" != 0 ]; then sudo="sudo"; fi
    echo "can-cantools-check: installing $* (apt)"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "$@" >/dev/null
}

make_venv() {
    rm -rf "$venv"
    "$1" -m venv "$venv" >/dev/null 2>&1 && "$venv/bin/python" -m pip --version >/dev/null 2>&1
}

if ! "$venv/bin/python" -c "import cantools, sys; sys.exit(cantools.__version__ != '$CANTOOLS_VERSION')" 2>/dev/null
then
    command -v python3 >/dev/null 2>&1 || apt_install python3
    if ! make_venv python3; then
        # Debian's python3 needs python3-venv for `-m venv` (ensurepip); pyenv's does not.
        apt_install python3-venv
        make_venv python3 || make_venv /usr/bin/python3 || {
            echo "can-cantools-check: cannot create a Python venv in $venv" >&2
            exit 1
        }
    fi
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "cantools==$CANTOOLS_VERSION"
fi

# The `test` profile: the same artifacts `cargo test --workspace` builds, so CI compiles once.
cargo build --quiet --profile test -p host-sim
hs="$target_dir/debug/host-sim"

"$hs" can demo-log --out "$work/demo.log"
"$hs" can demo-log --sweep --out "$work/sweep.log"
"$hs" replay tests/data/small --can-log "$work/small.log" >/dev/null

status=0
for log in demo sweep small; do
    echo "--- $log.log"
    "$hs" can decode --format csv "$work/$log.log" >"$work/$log.decoded.csv"
    extra=()
    [ "$log" = sweep ] && extra=(--require-all-labels)
    "$venv/bin/python" scripts/can_cantools_check.py can/brake_monitor.dbc "$work/$log.log" \
        "$work/$log.decoded.csv" "${extra[@]}" || status=1
done
if [ "$status" = 0 ]; then
    echo "can-cantools-check: every frame decodes with cantools $CANTOOLS_VERSION to host-sim's values"
fi
exit $status
