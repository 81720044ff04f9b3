#!/usr/bin/env python3
"""Deterministic generator of the independent test sets (clean, sensor, unfamiliar).

Usage: python3 gen.py [clean|sensor|unfamiliar ...]   (default: all three)
Writes <set>/manifest.csv and <set>/traces/test/*.csv next to this script (needs numpy).
"""
import os
import sys
import numpy as np
import plant as pl

ROOT = os.path.dirname(os.path.abspath(__file__))
CLASSES = ["normal", "air_leak", "orifice_block", "leak_and_block", "low_supply"]
FLEET_SEED = 90210
N_LOCO = 6


def fleet():
    rng = np.random.default_rng(FLEET_SEED)
    locos = []
    for i in range(N_LOCO):
        u = lambda: rng.uniform(0.95, 1.05)
        locos.append(dict(
            name=f"indep-{i + 1:02d}",
            V0=pl.V0_NOM * u(), F0=pl.F0_NOM * u(), K=pl.K_NOM * u(), cf=pl.CF_NOM * u(),
            Fc=pl.FC_NOM * u(), Fs=pl.FS_NOM * u(), reg=pl.PS_NOM + rng.uniform(-0.03, 0.03)))
    return locos


def class_params(cls, loco, rng):
    p = {k: loco[k] for k in ("V0", "F0", "K", "cf", "Fc", "Fs")}
    p["ps"] = loco["reg"]
    desc = {}
    if cls in ("air_leak", "leak_and_block"):
        p["d_leak"] = rng.uniform(0.5, 1.2) * 1e-3
        desc["d_leak_mm"] = p["d_leak"] * 1e3
    if cls in ("orifice_block", "leak_and_block"):
        p["d_orifice"] = rng.uniform(0.35, 1.0) * 1e-3
        desc["d_orifice_mm"] = p["d_orifice"] * 1e3
    if cls == "low_supply":
        p["ps"] = rng.uniform(3.5, 7.2)
        desc["ps_bar"] = p["ps"]
    return p, desc


def fmt(d):
    return " ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in d.items())


def write_set(name, items, pbar):
    """items: list of dict(fname, label, loco, meta, codes)"""
    d = os.path.join(ROOT, name)
    os.makedirs(os.path.join(d, "traces", "test"), exist_ok=True)
    rows = ["file,label,locomotive,split"]
    for it in items:
        rel = f"traces/test/{it['fname']}"
        pl.write_trace(os.path.join(d, rel), it["codes"], it["meta"])
        rows.append(f"{rel},{it['label']},{it['loco']},test")
    with open(os.path.join(d, "manifest.csv"), "w") as f:
        f.write("\n".join(rows) + "\n")
    print(f"{name}: {len(items)} traces -> {d}")


# ---------------------------------------------------------------- clean
def gen_clean():
    locos = fleet()
    rng = np.random.default_rng(1001)
    specs = []
    for ci, cls in enumerate(CLASSES):
        for j in range(40):
            loco = locos[(j + ci) % N_LOCO]
            p, desc = class_params(cls, loco, rng)
            specs.append((cls, j, loco, p, desc))
    P = pl.simulate_batch([s[3] for s in specs])
    items = []
    for (cls, j, loco, p, desc), pb in zip(specs, P):
        seed = 1_000_000 + CLASSES.index(cls) * 1000 + j
        codes = pl.to_adc(pb, np.random.default_rng(seed))
        items.append(dict(fname=f"{cls}_{j:04d}.csv", label=cls, loco=loco["name"], codes=codes,
                          meta={"label": cls, "locomotive": loco["name"], "split": "test", "seed": seed,
                                "truth": fmt(desc) or "nominal",
                                "source": "indep plant.py RK4 0.5 ms, noise 0.01 bar, 12-bit ADC"}))
    write_set("clean", items, P)


# ---------------------------------------------------------------- sensor
SENSOR_FAULTS = ["drift_up", "drift_down", "gain_step", "intermittent_freeze", "adc_10bit",
                 "sample_hold_dup", "mains_alias", "lag", "stuck_last_good", "bit_flip"]


def apply_sensor(fault, onset, p_true, rng):
    """Returns codes and a description. p_true: noise-free gauge pressure at 100 Hz."""
    n = len(p_true)
    t = np.arange(n) / pl.FS_HZ
    after = t >= onset
    p = p_true + rng.normal(0, 0.01, n)
    q = lambda pp: np.clip(np.round(pl.p_to_code_float(pp)), 0, 4095).astype(int)
    if fault == "drift_up":
        p = p + 0.5 * np.clip((t - onset) / 20.0, 0, 1)
        return q(p), f"offset drift +0.5 bar over 20 s from t={onset:g} s, then held"
    if fault == "drift_down":
        p = p - 0.3 * np.clip((t - onset) / 20.0, 0, 1)
        return q(p), f"offset drift -0.3 bar over 20 s from t={onset:g} s, then held"
    if fault == "gain_step":
        p = np.where(after, p * 0.8, p)
        return q(p), f"span gain step x0.8 at t={onset:g} s"
    if fault == "intermittent_freeze":
        c = q(p)
        ph = rng.uniform(0, 2.0)
        for k in range(n):
            if after[k] and ((t[k] - onset + ph) % 2.0) < 0.2 and k > 0:
                c[k] = c[k - 1]
        return c, f"0.2 s holds every 2 s from t={onset:g} s (phase {ph:.2f} s)"
    if fault == "adc_10bit":
        c = q(p)
        c = np.where(after, (c // 4) * 4, c)
        return c, f"10-bit ADC (codes floor to multiple of 4) from t={onset:g} s"
    if fault == "sample_hold_dup":
        c = q(p)
        idx = np.nonzero(after)[0]
        odd = idx[(idx % 2 == 1)]
        c[odd] = c[odd - 1]
        return c, f"every other sample repeated from t={onset:g} s"
    if fault == "mains_alias":
        amp = rng.uniform(0.05, 0.2)
        f = rng.uniform(0.2, 3.0)
        ph = rng.uniform(0, 2 * np.pi)
        p = p + np.where(after, amp * np.sin(2 * np.pi * f * t + ph), 0.0)
        return q(p), f"aliased mains interference {amp:.3f} bar at {f:.2f} Hz from t={onset:g} s"
    if fault == "lag":
        y = p.copy()
        a = 1 - np.exp(-0.01 / 0.5)
        for k in range(1, n):
            if after[k]:
                y[k] = y[k - 1] + a * (p[k] - y[k - 1])
        return q(y), f"first-order sensor lag tau=0.5 s from t={onset:g} s"
    if fault == "stuck_last_good":
        c = q(p)
        k0 = int(round(onset * pl.FS_HZ))
        c[k0:] = c[k0 - 1]
        return c, f"stuck at last good value after t={onset:g} s"
    if fault == "bit_flip":
        c = q(p)
        m = after & (rng.random(n) < 0.01)
        c = np.where(m, c ^ 64, c)
        return c, f"bit 6 (64 codes) flipped on 1% of samples from t={onset:g} s ({int(m.sum())} samples)"
    raise ValueError(fault)


def gen_sensor():
    locos = fleet()
    rng = np.random.default_rng(2002)
    specs = []
    for fi, fault in enumerate(SENSOR_FAULTS):
        for oi, onset_kind in enumerate(["start", "mid"]):
            for ci, cls in enumerate(CLASSES):
                for rep in range(2):
                    loco = locos[(fi + oi + ci + rep) % N_LOCO]
                    p, desc = class_params(cls, loco, rng)
                    if fault == "stuck_last_good":
                        onset = 8.0 if onset_kind == "start" else 16.0
                    else:
                        onset = 0.0 if onset_kind == "start" else 10.0
                    specs.append((fault, onset_kind, onset, cls, rep, loco, p, desc))
    P = pl.simulate_batch([s[6] for s in specs])
    items = []
    for i, ((fault, ok, onset, cls, rep, loco, p, desc), pb) in enumerate(zip(specs, P)):
        seed = 2_000_000 + i
        codes, fdesc = apply_sensor(fault, onset, pb, np.random.default_rng(seed))
        items.append(dict(fname=f"{fault}_{ok}_{cls}_{rep}.csv", label=cls, loco=loco["name"], codes=codes,
                          meta={"label": cls, "locomotive": loco["name"], "split": "test", "seed": seed,
                                "sensor_fault": f"{fault}: {fdesc}", "truth": fmt(desc) or "nominal",
                                "source": "indep plant.py RK4 0.5 ms, 12-bit ADC + injected sensor fault"}))
    write_set("sensor", items, P)


# ---------------------------------------------------------------- unfamiliar
def unfamiliar_params(kind, base, rng):
    p = dict(base)
    if kind == "supply_dropout_vent":
        t0 = rng.uniform(5, 20)
        p.update(dropout_t0=t0, dropout_t1=t0 + 1.0, dropout_mode=1)
        return p, "normal", f"supply line vented to 0 bar g for 1 s at t={t0:.1f} s"
    if kind == "supply_dropout_block":
        t0 = rng.uniform(5, 20)
        p.update(dropout_t0=t0, dropout_t1=t0 + 1.0, dropout_mode=2)
        return p, "normal", f"supply blocked (no inflow) for 1 s at t={t0:.1f} s"
    if kind == "stiction_breakaway":
        fs = rng.uniform(1500, 3000)
        p.update(Fs=fs, vs=0.002)
        return p, "normal", f"piston stiction Fs={fs:.0f} N (breakaway ~{4.0 + fs / pl.A_PIST / 1e5:.2f} bar) then jump"
    if kind == "stiction_midstroke":
        x0 = rng.uniform(0.015, 0.035)
        fs = rng.uniform(2000, 4000)
        p.update(stick_x0=x0, stick_x1=x0 + 0.005, stick_fs=fs, vs=0.002)
        return p, "normal", f"sticky spot at x={x0 * 1e3:.0f}-{x0 * 1e3 + 5:.0f} mm, extra Fs={fs:.0f} N, then jump"
    if kind == "two_stage_regulator":
        ps1 = rng.uniform(4.5, 5.5)
        ts = rng.uniform(8, 15)
        p.update(stage_ps=ps1, stage_t=ts)
        return p, "normal", f"two-stage regulator: {ps1:.2f} bar g until t={ts:.1f} s, then {p['ps']:.2f}"
    if kind == "big_volume":
        f = rng.uniform(1.35, 1.45)
        p["V0"] = p["V0"] * f
        return p, "orifice_block", f"chamber dead volume x{f:.2f}"
    if kind == "leak_above_5bar":
        d = rng.uniform(0.8, 1.5)
        thr = rng.uniform(4.8, 5.2)
        p.update(d_leak=d * 1e-3, leak_thr=thr)
        return p, "air_leak", f"leak {d:.2f} mm only above {thr:.2f} bar g (relief valve cracking)"
    if kind == "regulator_hunting":
        amp = rng.uniform(0.2, 0.5)
        f = rng.uniform(0.1, 0.5)
        p.update(osc_amp=amp, osc_f=f)
        return p, "normal", f"regulator hunting +-{amp:.2f} bar at {f:.2f} Hz"
    if kind == "valve_delay":
        d = rng.uniform(2, 5)
        p.update(valve_delay=d)
        return p, "normal", f"release valve opens {d:.1f} s after the command"
    if kind == "short_stroke":
        L = rng.uniform(0.030, 0.045)
        p.update(L=L)
        return p, "normal", f"obstructed stroke: end stop at {L * 1e3:.0f} mm"
    raise ValueError(kind)


UNF_KINDS = ["supply_dropout_vent", "supply_dropout_block", "stiction_breakaway", "stiction_midstroke",
             "two_stage_regulator", "big_volume", "leak_above_5bar", "regulator_hunting", "valve_delay",
             "short_stroke"]


def gen_unfamiliar():
    locos = fleet()
    rng = np.random.default_rng(3003)
    specs = []
    for ki, kind in enumerate(UNF_KINDS):
        for j in range(10):
            loco = locos[(ki + j) % N_LOCO]
            base, _ = class_params("normal", loco, rng)
            p, label, note = unfamiliar_params(kind, base, rng)
            specs.append((kind, j, loco, p, label, note))
    P = pl.simulate_batch([s[3] for s in specs])
    items = []
    for i, ((kind, j, loco, p, label, note), pb) in enumerate(zip(specs, P)):
        seed = 3_000_000 + i
        codes = pl.to_adc(pb, np.random.default_rng(seed))
        items.append(dict(fname=f"{kind}_{j:02d}.csv", label=label, loco=loco["name"], codes=codes,
                          meta={"label": label, "locomotive": loco["name"], "split": "test", "seed": seed,
                                "note": f"{kind}: {note} (outside the 5 classes; label = closest class)",
                                "source": "indep plant.py RK4 0.5 ms, noise 0.01 bar, 12-bit ADC"}))
    write_set("unfamiliar", items, P)


if __name__ == "__main__":
    sets = sys.argv[1:] or ["clean", "sensor", "unfamiliar"]
    for s in sets:
        {"clean": gen_clean, "sensor": gen_sensor, "unfamiliar": gen_unfamiliar}[s]()
