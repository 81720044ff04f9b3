#!/usr/bin/env bash
# Issue 15: the README's table of releases the model was not trained on. Generates each set with
# its own fresh seed, replays it through the core pipeline and prints one line per set: right
# class, refused, wrong class. For kinds outside the five classes (any=1) every named class
# counts as wrong; an effect on top of a class (heat transfer) is right when the class is. Takes about 2 minutes.
#   bash scripts/shifted-sets.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --quiet --release -p host-sim
HS=target/release/host-sim
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
# name | seed | per-class | any-class-is-wrong | generate options
sets=(
  "clean, 6 locomotives|99|50|0|"
  "clean, 4 new locomotives|4242|100|0|--locomotives 8 --test-locomotives 4"
  "twice the noise|611|40|0|--noise-bar 0.02"
  "spread 8 %|612|40|0|--spread 0.08"
  "spread 10 %|618|40|0|--spread 0.10"
  "regulator 7.7 ± 0.1 bar|613|40|0|--regulator-bar 7.6,7.8"
  "transport delay 0.1 s|614|40|0|--effect transport_delay=0.1"
  "transport delay 0.3 s|615|40|0|--effect transport_delay=0.3"
  "all four shifts|616|40|0|--noise-bar 0.02 --spread 0.08 --regulator-bar 7.6,7.8 --effect transport_delay=0.1"
  "three times the noise|617|40|0|--noise-bar 0.03"
  "orifice missing|701|30|1|--classes orifice_missing"
  "supply 2.5-3.2 bar|702|30|1|--classes normal --regulator-bar 2.5,3.2"
  "supply 8.5-9.5 bar|703|30|1|--classes normal --regulator-bar 8.5,9.5"
  "wall heat transfer|705|30|0|--classes normal,low_supply --effect heat_transfer=5"
)
printf '%-28s %6s %6s %8s %6s\n' set n right refused wrong
for s in "${sets[@]}"; do
    IFS='|' read -r name seed per any opts <<<"$s"
    d=$OUT/$seed
    # shellcheck disable=SC2086
    $HS generate --out "$d" --per-class 0 --test-per-class "$per" --seed "$seed" $opts >/dev/null 2>&1
    $HS replay "$d" --split test --out "$d/out" >/dev/null 2>&1
    awk -F, -v name="$name" -v any="$any" 'NR > 1 { n++; split($12, v, " ")
            if ($12 ~ /^cannot/) ref++; else if (any == 0 && v[1] == $2) right++; else wrong++ }
        END { printf "%-28s %6d %6d %8d %6d\n", name, n, right, ref, wrong }' "$d/out/summary.csv"
done
