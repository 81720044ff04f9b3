#!/usr/bin/env python3
"""Second round of the independent test: fresh seeds and locomotives (`fresh`, 500 releases; `wide`,
200 releases with a ±8 % fleet spread). Writes fresh/ and wide/ next to this script (needs numpy)."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np
import plant as pl
import gen
gen.ROOT = os.path.dirname(os.path.abspath(__file__))

def fleet(seed, spread, prefix):
    rng = np.random.default_rng(seed)
    locos = []
    for i in range(6):
        u = lambda: rng.uniform(1 - spread, 1 + spread)
        locos.append(dict(name=f"{prefix}-{i+1:02d}", V0=pl.V0_NOM*u(), F0=pl.F0_NOM*u(), K=pl.K_NOM*u(),
                          cf=pl.CF_NOM*u(), Fc=pl.FC_NOM*u(), Fs=pl.FS_NOM*u(),
                          reg=pl.PS_NOM + rng.uniform(-0.03, 0.03)))
    return locos

def make(name, fleet_seed, spread, per_class, rng_seed, noise_base):
    locos = fleet(fleet_seed, spread, name)
    rng = np.random.default_rng(rng_seed)
    specs = []
    for ci, cls in enumerate(gen.CLASSES):
        for j in range(per_class):
            loco = locos[(j + ci) % 6]
            p, desc = gen.class_params(cls, loco, rng)
            specs.append((cls, j, loco, p, desc))
    P = pl.simulate_batch([s[3] for s in specs])
    items = []
    for (cls, j, loco, p, desc), pb in zip(specs, P):
        seed = noise_base + gen.CLASSES.index(cls) * 1000 + j
        codes = pl.to_adc(pb, np.random.default_rng(seed))
        items.append(dict(fname=f"{cls}_{j:04d}.csv", label=cls, loco=loco["name"], codes=codes,
                          meta={"label": cls, "locomotive": loco["name"], "split": "test", "seed": seed,
                                "truth": gen.fmt(desc) or "nominal", "source": "indep plant.py, fresh seeds"}))
    gen.write_set(name, items, P)

if __name__ == "__main__":
    make("fresh", 424242, 0.05, 100, 5150, 7_000_000)
    make("wide", 8675309, 0.08, 40, 6161, 8_000_000)
