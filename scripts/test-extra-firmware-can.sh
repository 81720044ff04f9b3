#!/usr/bin/env bash
# Run by scripts/test-all.sh (every scripts/test-extra-*.sh): firmware CAN frames in QEMU equal
# host-sim replay --can-log, byte for byte, on 14 traces (issue 7 item 3), and the firmware cost
# stays within the bounds recorded in bench/firmware-bounds.env (issue 7 item 4).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/firmware-can-equality.sh
bash scripts/firmware-bench.sh --check
