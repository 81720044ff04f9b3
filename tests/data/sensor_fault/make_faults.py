#!/usr/bin/env python3
"""Makes the sensor-fault traces of this directory from the clean test traces of
tests/data/small (standard library only, fixed seeds: the output is byte-identical on every run).

Each fault is applied to the raw ADC codes of a release whose true class is in the file name;
see README.md for what each one models. Run from the repository root:

    python3 tests/data/sensor_fault/make_faults.py
"""
import math
import random
from pathlib import Path

SRC = Path("tests/data/small/traces/test")
OUT = Path("tests/data/sensor_fault")
ZERO = 409.5  # ADC code of 0 bar g (SPEC 5): counts = 4095 (0.1 + 0.08 p)
PER_BAR = 327.6


def read(name):
    meta, rows = [], []
    for line in (SRC / name).read_text().splitlines():
        if line.startswith("#"):
            meta.append(line)
        elif line.startswith("t_s"):
            continue
        else:
            t, c = line.split(",")
            rows.append((t, int(c)))
    return meta, rows


def frozen(rows, rng, onset_s):
    held = None
    out = []
    for t, c in rows:
        if float(t) >= onset_s - 1e-9:
            held = c if held is None else held
            c = held
        out.append((t, c))
    return out


def spikes(rows, rng, onset_s, fraction=0.03):
    out = []
    for t, c in rows:
        if float(t) >= onset_s - 1e-9 and rng.random() < fraction:
            c = c + rng.choice((-1, 1)) * int(rng.uniform(0.5, 3.0) * PER_BAR)
        out.append((t, min(4095, max(0, c))))
    return out


def lost_bits(rows, rng, onset_s, bits=6):
    mask = ~((1 << bits) - 1)
    return [(t, c & mask if float(t) >= onset_s - 1e-9 else c) for t, c in rows]


def noisy(rows, rng, onset_s, sigma_bar=0.1):
    out = []
    for t, c in rows:
        if float(t) >= onset_s - 1e-9:
            c = int(round(c + rng.gauss(0.0, sigma_bar * PER_BAR)))
        out.append((t, min(4095, max(0, c))))
    return out


def clipped(rows, rng, onset_s, level_bar=5.0):
    top = int(round(ZERO + level_bar * PER_BAR))
    return [(t, min(c, top) if float(t) >= onset_s - 1e-9 else c) for t, c in rows]


FAULTS = [
    # (source trace, fault, onset s, description)
    ("normal_0000.csv", frozen, 20.0, "output frozen at its value from t = 20.00 s"),
    ("air_leak_0000.csv", spikes, 5.0, "EMI spikes of 0.5-3 bar on 3 % of the samples from t = 5.00 s"),
    ("orifice_block_0000.csv", lost_bits, 0.0, "ADC lost its 6 low bits from t = 0"),
    ("low_supply_0000.csv", noisy, 10.0, "extra white noise of 0.1 bar from t = 10.00 s"),
    ("normal_0000.csv", clipped, 0.0, "amplifier clips at 5.0 bar"),
]


def main():
    for i, (src, fault, onset, what) in enumerate(FAULTS):
        meta, rows = read(src)
        rng = random.Random(1000 + i)
        rows = fault(rows, rng, onset)
        label = src.split("_0000")[0]
        name = f"{label}_{fault.__name__}.csv"
        lines = []
        for m in meta:
            lines.append(m)
            if m.startswith("# label:"):
                lines.append(f"# sensor_fault: {what}")
        lines.append("t_s,adc")
        lines += [f"{t},{c}" for t, c in rows]
        (OUT / name).write_text("\n".join(lines) + "\n")
        print(f"wrote {OUT / name}")


if __name__ == "__main__":
    main()
