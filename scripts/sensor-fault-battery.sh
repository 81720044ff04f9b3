#!/usr/bin/env bash
# Issue 15: the sensor-fault battery. Every kind of `host-sim generate --sensor-fault` x the five
# release classes x four onsets (0, 3, 15, 40 s) x 2 releases per class (480 traces, fresh seeds
# from SEED on), each replayed through the core pipeline; prints how many were refused and every
# release reported as a wrong brake class (there must be none: exit 1 otherwise).
#   bash scripts/sensor-fault-battery.sh [SEED]
set -euo pipefail
cd "$(dirname "$0")/.."
SEED=${1:-101}
cargo build --quiet --release -p host-sim
HS=target/release/host-sim
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
kinds="frozen dead noisy spikes dropouts lost_resolution clipped impossible_rate implausible_level offset open_circuit short_circuit"
for k in $kinds; do
    for on in 0 3 15 40; do
        d=$OUT/$k-$on
        $HS generate --out "$d" --locomotives 3 --test-locomotives 1 --per-class 0 --test-per-class 2 \
            --seed "$SEED" --sensor-fault "$k@$on" >/dev/null 2>&1
        $HS replay "$d" 2>/dev/null | awk -v k="$k" -v on="$on" 'NR > 1 && $1 ~ /csv/ {print k, on, $0}' >>"$OUT/all.txt"
        SEED=$((SEED + 1))
    done
done
awk '{n++; lab = $4; d = $(NF - 1)
      if ($0 ~ /cannot diagnose/) { ref++; r[$1]++ } else if (d == lab) same++; else { wrong++; print "WRONG", $1 "@" $2, lab, "->", d, $NF } }
     END { printf "sensor-fault battery: %d releases, %d refused, %d named their true class, %d wrong brake classes\n", n, ref, same, wrong
           for (k in r) printf "  %-18s refused %d\n", k, r[k]
           exit wrong > 0 }' "$OUT/all.txt"
