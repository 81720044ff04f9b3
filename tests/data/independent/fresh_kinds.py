#!/usr/bin/env python3
"""Second round of the independent test: kinds chosen after the guard was built (valve delays,
a slowly rising supply, a low supply with a leak, zero offset and span errors). Writes kinds/ next
to this script (needs numpy)."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np
import plant as pl
import gen
gen.ROOT = os.path.dirname(os.path.abspath(__file__))
from fresh import fleet  # noqa: E402 (fresh.py only generates when run itself)
locos = fleet(777001, 0.05, "kinds")
rng = np.random.default_rng(99001)
specs = []
def add(kind, cls, extra, sensor=None):
    j = len([s for s in specs if s[0] == kind])
    loco = locos[j % 6]
    p, desc = gen.class_params(cls, loco, rng)
    p.update(extra)
    specs.append((kind, cls, j, loco, p, sensor, extra))
for d in (0.5, 1.0, 1.5):
    for cls in gen.CLASSES:
        for _ in range(4):
            add(f"delay{d}", cls, {"valve_delay": d})
for _ in range(10): add("supply_ramp", "normal", {"ramp_tau": 3.0})
for _ in range(10): add("leak_plus_low", "low_supply", {"d_leak": rng.uniform(0.6, 1.1) * 1e-3})
for cls in ("normal", "air_leak"):
    for _ in range(5): add("offset015", cls, {}, ("offset", 0.15))
    for _ in range(5): add("gain11", cls, {}, ("gain", 1.1))
P = pl.simulate_batch([s[4] for s in specs])
items = []
for (kind, cls, j, loco, p, sensor, extra), pb in zip(specs, P):
    seed = 9_100_000 + len(items)
    r = np.random.default_rng(seed)
    note = f"{kind} {extra}"
    if sensor:
        if sensor[0] == "offset": pb = pb + sensor[1]
        else: pb = pb * sensor[1]
        note += f" sensor {sensor}"
    codes = pl.to_adc(pb, r)
    items.append(dict(fname=f"{kind}_{cls}_{j:02d}.csv", label=cls, loco=loco["name"], codes=codes,
                      meta={"label": cls, "locomotive": loco["name"], "split": "test", "seed": seed, "note": note,
                            "source": "indep plant.py, fresh kinds"}))
gen.write_set("kinds", items, P)
