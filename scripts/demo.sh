#!/usr/bin/env bash
# The project's main job in one command (README's first command): generates the paper-size
# fleet data set into data/demo-fleet (or reuses it), trains the paper's three classifiers and
# ours, quantizes ours, evaluates them, replays test traces through the core pipeline with CAN
# logging and decodes the log, scores the online estimator, audits a data set with a hidden
# effect drawn from the seed, and writes report/index.html (self-contained). Arguments are
# passed on to `host-sim demo` (see `host-sim demo --help`: --seed, --out, --data, --quick).
set -euo pipefail
cd "$(dirname "$0")/.."

# Toolchain (Rust targets/components, QEMU for the firmware checks); idempotent.
if [ -f scripts/setup.sh ]; then
    bash scripts/setup.sh
fi
cargo build --release -q -p host-sim
exec cargo run --release -q -p host-sim -- demo "$@"
