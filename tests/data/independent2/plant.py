#!/usr/bin/env python3
"""Independent plant of a spring-parking-brake release (written from /work/shared/SPEC.md only).

Writes a SPEC §7 data set (manifest.csv + traces) of ONE locomotive.

  plant.py --out DIR [--seed S] [--n 16] [--noise 0.01] [--units adc|bar]
           [--effect name=value ...] [--meta key=value ...] [--garbage KIND]

Physics: ISO 6358 orifice from supply into chamber, adiabatic chamber with moving piston
(V = V0 + A x), preloaded spring, LuGre friction, hard end stops (0 and L), transducer noise
added before a 12-bit ADC.  Fixed-step integration (dt = 0.5 ms) vectorised over releases.
Per-locomotive spread SPEC §5 (drawn once), per-release variation: supply +-5 mbar,
Fc/Fs +-2 %, V0 +-0.5 %.

Effects (name=value[,value2...]) - see EFFECTS below / README.md.
"""
import argparse, json, math, os, sys
import numpy as np

k = 1.4; R = 287.0; T0 = 293.15; P0 = 1.0e5; PCR = 0.528
C1 = 0.040418; C2 = 0.156174
AP = 4 * math.pi * 0.05 ** 2
BAR = 1e5


def flow(pu, pd, cfa, T=T0):
    """signed mass flow pu->pd through an orifice with Cf*A = cfa (arrays)."""
    fwd = pu >= pd
    hi = np.where(fwd, pu, pd); lo = np.where(fwd, pd, pu)
    r = lo / np.maximum(hi, 1.0)
    choked = r <= PCR
    un = C2 * r ** (1 / k) * np.sqrt(np.maximum(1 - r ** ((k - 1) / k), 0.0))
    m = cfa * hi / np.sqrt(T) * np.where(choked, C1, un)
    return np.where(fwd, m, -m)


def area(d_mm):
    return math.pi * (d_mm * 1e-3 / 2) ** 2


EFFECTS = {
    # --- outside the project's library -------------------------------------------------
    'dead2': 'second volume V2 [L] behind a small orifice d2 [mm]: dead2=V2,d2',
    'pleak': 'leak orifice d [mm] to atmosphere open only above p_open [bar g]: pleak=d,p_open',
    'cut': 'supply interrupted (valve closed) from t1 for dur [s]: cut=t1,dur',
    'vent': 'supply vented to atmosphere from t1 for dur [s]: vent=t1,dur',
    'stick': 'piston sticks at x_stick [mm] for dur [s]: stick=x,dur',
    'porif': 'orifice closes with pressure drop: d_eff = d (1 - c dp/7.7bar): porif=c',
    'quant': 'sensor output quantised to step q [bar] (written as p_bar): quant=q',
    'drift': 'sensor drift rate [bar/s] over the release: drift=r',
    'spikes': 'spikes of amplitude a [bar], n per release: spikes=a,n',
    'hunt': 'regulator hunting +-a [bar] at f [Hz]: hunt=a,f',
    'leakx': 'leak that opens with piston travel past x [mm], d [mm]: leakx=d,x',
    'bleed': 'chamber leak through a valve whose opening decays (relief valve reseating): bleed=d,tau',
    'nonlin': 'transducer bow: + b*4*(p/10)(1-p/10) [bar]: nonlin=b',
    'rough': 'friction x f over travel x1..x2 [mm] (rough bore patch): rough=f,x1,x2',
    'lowleak': 'seal leak d [mm] that closes above p_close [bar g]: lowleak=d,p_close',
    'tvar': 'per-release supply gas temperature uniform in T1..T2 [K]: tvar=T1,T2',
    'supvar': 'per-release supply spread +- s [bar] (instead of 5 mbar): supvar=s',
    'delay_jit': 'per-release random valve delay uniform 0..s [s]: delay_jit=s',
    # --- inside (my own versions of the library's mechanism names) -------------------------
    'transport_delay': 'valve opens s seconds late',
    'valve_lag': 'valve area opens with first-order time constant s',
    'sensor_lag': 'first-order transducer lag tau s',
    'sensor_offset': 'transducer offset bar',
    'sensor_gain': 'transducer gain ratio',
    'regulator_droop': 'supply drops by value [bar] at the full choked flow of the nominal orifice',
    'laminar_leak': 'laminar leak m = c*(P-P0)/bar [g/s per bar]',
    'heat_transfer': 'gas exchanges heat with wall (293.15 K), time constant tau [s]',
    'gas_temperature': 'supply gas temperature [K]',
    'progressive_spring': 'spring force K x (1 + r x/L)',
    'dead_volume': 'V0 x factor',
    'cf': 'discharge coefficient x factor',
    'preload': 'spring preload F0 x factor',
    'friction': 'Fc, Fs x factor',
    'orifice': 'orifice diameter mm (undocumented unless --meta orifice_mm=..)',
    'leak': 'SPEC leak orifice d [mm] to atmosphere',
    'supply': 'supply bar g (replaces regulator setting)',
}


def simulate(n, rng, eff, dt=5e-4, tend=60.0):
    # locomotive spread (once)
    u = (lambda: 1.0) if os.environ.get("NOSPREAD") else (lambda: 1 + rng.uniform(-0.05, 0.05))
    V0 = 3.0e-3 * u(); F0n = 4.0 * BAR * AP; F0 = F0n * u(); Fc = 150.0 * u(); Fs = 300.0 * u()
    Kn = (7.2 * BAR * AP - F0n - 150.0) / 0.060; K = Kn * u(); Cf = 0.8 * u()
    reg = 7.7 + (0 if os.environ.get("NOSPREAD") else rng.uniform(-0.03, 0.03))
    loco = dict(V0=V0, F0=F0, K=K, Cf=Cf, Fc=Fc, Fs=Fs, reg=reg)
    # per release
    sv = eff.get('supvar', [0.005])[0]
    Ps = (eff.get('supply', [reg])[0] + rng.uniform(-sv, sv, n)) * BAR + P0
    V0 = V0 * (1 + rng.uniform(-0.005, 0.005, n)) * eff.get('dead_volume', [1.0])[0]
    fr = eff.get('friction', [1.0])[0]
    Fc = Fc * (1 + rng.uniform(-0.02, 0.02, n)) * fr
    Fs = Fs * (1 + rng.uniform(-0.02, 0.02, n)) * fr
    F0 = F0 * eff.get('preload', [1.0])[0]
    Cf = Cf * eff.get('cf', [1.0])[0]
    M = 20.0; L = 0.060; s0 = 1e5; s1 = 2e3; B = 2e3; vs = 0.01
    d_or = eff.get('orifice', [1.25])[0]
    A_or = area(d_or)
    Tin = eff.get('gas_temperature', [T0])[0]
    if 'tvar' in eff:
        Tin = rng.uniform(eff['tvar'][0], eff['tvar'][1], n)
    tau_h = eff.get('heat_transfer', [None])[0]
    td = np.full(n, eff.get('transport_delay', [0.0])[0])
    if 'delay_jit' in eff:
        td = td + rng.uniform(0, eff['delay_jit'][0], n)
    tv = eff.get('valve_lag', [0.0])[0]
    droop = eff.get('regulator_droop', [0.0])[0] * BAR
    m_ref = 0.8 * area(1.25) * C1 * (7.7 * BAR + P0) / math.sqrt(T0)
    lam = eff.get('laminar_leak', [0.0])[0] * 1e-3 / BAR
    prog = eff.get('progressive_spring', [0.0])[0]
    A_leak = area(eff['leak'][0]) if 'leak' in eff else 0.0

    P = np.full(n, P0); x = np.zeros(n); v = np.zeros(n); z = np.zeros(n)
    mass = P * V0 / (R * T0)
    P2 = np.full(n, P0)
    stuck_until = np.full(n, -1.0); stick_done = np.zeros(n, bool)
    bleed_open = np.zeros(n, bool); bleed_t = np.full(n, np.inf)
    mprev = np.zeros(n)
    nsamp = int(round(tend * 100)); sub = int(round(0.01 / dt))
    outP = np.empty((nsamp, n)); outX = np.empty((nsamp, n))
    for i in range(nsamp):
        outP[i] = P; outX[i] = x
        for j in range(sub):
            t = (i * sub + j) * dt
            # ---- supply side
            pu = Ps.copy()
            if droop:
                pu = pu - droop * np.maximum(mprev, 0) / m_ref
            if 'hunt' in eff:
                a, f = eff['hunt'][:2]
                pu = pu + a * BAR * math.sin(2 * math.pi * f * t)
            open_frac = np.where(t >= td, 1.0, 0.0)
            if tv > 0:
                open_frac = np.where(t >= td, 1 - np.exp(-(t - td) / tv), 0.0)
            Aeff = A_or * open_frac
            if 'porif' in eff:
                c = eff['porif'][0]
                dp = np.maximum(pu - P, 0) / (7.7 * BAR)
                Aeff = Aeff * np.maximum(1 - c * dp, 0.05) ** 2
            if 'cut' in eff:
                t1, du = eff['cut'][:2]
                if t1 <= t < t1 + du:
                    Aeff = Aeff * 0.0
            if 'vent' in eff:
                t1, du = eff['vent'][:2]
                if t1 <= t < t1 + du:
                    pu = np.full(n, P0)
            m_in = flow(pu, P, Cf * Aeff, Tin)
            mprev = m_in
            # ---- outflows
            m_out = np.zeros(n)
            if A_leak:
                m_out = m_out + flow(P, np.full(n, P0), Cf * A_leak)
            if lam:
                m_out = m_out + lam * (P - P0)
            if 'pleak' in eff:
                d, po = eff['pleak'][:2]
                m_out = m_out + np.where(P - P0 > po * BAR, flow(P, np.full(n, P0), Cf * area(d)), 0.0)
            if 'leakx' in eff:
                d, xo = eff['leakx'][:2]
                m_out = m_out + np.where(x > xo * 1e-3, flow(P, np.full(n, P0), Cf * area(d)), 0.0)
            if 'bleed' in eff:
                # relief valve: opens when P first exceeds 5.5 bar g, then reseats with time const tau
                d, tb = eff['bleed'][:2]
                newly = (~bleed_open) & (P - P0 > 5.5 * BAR)
                bleed_t = np.where(newly, t, bleed_t); bleed_open |= newly
                fac = np.where(bleed_open, np.exp(-(t - bleed_t) / tb), 0.0)
                m_out = m_out + flow(P, np.full(n, P0), Cf * area(d)) * fac
            if 'lowleak' in eff:
                d, pc = eff['lowleak'][:2]
                m_out = m_out + np.where(P - P0 < pc * BAR, flow(P, np.full(n, P0), Cf * area(d)), 0.0)
            m12 = np.zeros(n)
            if 'dead2' in eff:
                V2, d2 = eff['dead2'][:2]
                m12 = flow(P, P2, Cf * area(d2))
                P2 = P2 + dt * k * R * T0 / (V2 * 1e-3) * m12
            # ---- chamber
            V = V0 + AP * x
            dP = k * R / V * (Tin * m_in - T0 * (m_out + m12)) - k * P / V * AP * v
            if tau_h:
                Tg = P * V / (mass * R)
                dP = dP + P * (T0 / Tg - 1) / tau_h
            mass = mass + dt * (m_in - m_out - m12)
            # ---- piston (LuGre, hard stops)
            g = Fc + (Fs - Fc) * np.exp(-(v / vs) ** 2)
            if 'rough' in eff:
                fr_, x1, x2 = eff['rough'][:3]
                g = g * np.where((x > x1 * 1e-3) & (x < x2 * 1e-3), fr_, 1.0)
            rate = s0 * np.abs(v) / g
            zss = np.sign(v) * g / s0
            zn = np.where(rate > 1e-12, zss + (z - zss) * np.exp(-rate * dt), z + v * dt)
            dz = (zn - z) / dt
            Ff = s0 * zn + s1 * dz + B * v
            Fsp = F0 + K * x * (1 + prog * x / L)
            a = ((P - P0) * AP - Fsp - Ff) / M
            vn = v + a * dt
            xn = x + vn * dt
            lo = xn <= 0; vn = np.where(lo & (vn < 0), 0.0, vn); xn = np.where(lo, 0.0, xn)
            hi = xn >= L; vn = np.where(hi & (vn > 0), 0.0, vn); xn = np.where(hi, L, xn)
            if 'stick' in eff:
                xs, du = eff['stick'][:2]
                start = (~stick_done) & (xn >= xs * 1e-3)
                stuck_until = np.where(start, t + du, stuck_until); stick_done |= start
                st = t < stuck_until
                xn = np.where(st, xs * 1e-3, xn); vn = np.where(st, 0.0, vn)
                zn = np.where(st, z, zn)
            P = P + dt * dP
            x, v, z = xn, vn, zn
    return outP, outX, loco


def sensor(Pabs, rng, eff, noise):
    nsamp, n = Pabs.shape
    t = np.arange(nsamp) * 0.01
    p = (Pabs - P0) / BAR
    if 'sensor_lag' in eff:
        tau = eff['sensor_lag'][0]; al = 1 - math.exp(-0.01 / tau)
        y = np.empty_like(p); y[0] = p[0]
        for i in range(1, nsamp):
            y[i] = y[i - 1] + al * (p[i] - y[i - 1])
        p = y
    if 'nonlin' in eff:
        b = eff['nonlin'][0]; p = p + b * 4 * (p / 10) * (1 - p / 10)
    p = p * eff.get('sensor_gain', [1.0])[0] + eff.get('sensor_offset', [0.0])[0]
    if 'drift' in eff:
        p = p + eff['drift'][0] * t[:, None]
    p = p + rng.normal(0, noise, p.shape)
    if 'spikes' in eff:
        a, ns = eff['spikes'][:2]
        for j in range(n):
            idx = rng.integers(0, nsamp, int(ns))
            p[idx, j] += a * rng.choice([-1, 1], len(idx))
    return t, p


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--out', required=True)
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--n', type=int, default=16)
    ap.add_argument('--noise', type=float, default=0.01)
    ap.add_argument('--units', default='adc')
    ap.add_argument('--effect', action='append', default=[])
    ap.add_argument('--meta', action='append', default=[])
    ap.add_argument('--garbage', default=None)
    a = ap.parse_args()
    eff = {}
    for e in a.effect:
        nm, val = e.split('=')
        assert nm in EFFECTS, nm
        eff[nm] = [float(s) for s in val.split(',')]
    rng = np.random.default_rng(a.seed)
    Pabs, X, loco = simulate(a.n, rng, eff)
    t, p = sensor(Pabs, rng, eff, a.noise)
    units = 'bar' if 'quant' in eff else a.units
    if 'quant' in eff:
        q = eff['quant'][0]; p = np.round(p / q) * q
    os.makedirs(os.path.join(a.out, 'traces'), exist_ok=True)
    rows = []
    for j in range(a.n):
        fn = f'traces/rel_{j:03d}.csv'
        pj = p[:, j].copy(); tj = t.copy(); u = units
        hdr = [f'# locomotive: L-{a.seed}', '# label: unknown', f'# seed: {a.seed}', f'# trace: {j}',
               '# source: independent tester plant (plant.py)']
        hdr += [f'# {kv.split("=")[0]}: {kv.split("=")[1]}' for kv in a.meta]
        g = a.garbage
        if g == 'norelease':
            pj = np.random.default_rng(j).normal(0, a.noise, len(pj))
        elif g == 'constant':
            pj = np.full(len(pj), 7.7)
        elif g == 'nan' and j % 3 == 0:
            pj[1000:1100] = np.nan
        elif g == 'allnan':
            pj[:] = np.nan
        elif g == 'kpa':
            u = 'bar'; pj = pj * 100.0  # kPa written as bar
        elif g == 'psi':
            u = 'bar'; pj = pj * 14.5038
        elif g == 'mbar_small':
            u = 'bar'; pj = pj / 1000.0 * 10  # decibar-ish / wrong scale x0.01
        elif g == 'truncated':
            pj = pj[:300]; tj = tj[:300]
        elif g == 'truncated12':
            pj = pj[:1200]; tj = tj[:1200]
        elif g == 'truncated5':
            pj = pj[:500]; tj = tj[:500]
        elif g == 'absolute':
            u = 'bar'; pj = pj + 1.0  # absolute pressure written as gauge
        elif g == 'ms':
            tj = tj * 1000.0  # time in ms
        elif g == 'slow':
            tj = tj * 10.0  # wrong sample rate (10 Hz labelled)
        elif g == 'reversed':
            pj = pj[::-1].copy()
        elif g == 'shuffled_time' and j == 0:
            tj = tj.copy(); tj[100], tj[101] = tj[101], tj[100]
        elif g == 'wrongmeta':
            hdr.append('# supply_bar_g: 5.0')
        elif g == 'wrongmeta_orifice':
            hdr.append('# orifice_mm: 0.6')
        elif g == 'badmeta':
            hdr.append('# orifice_mm: banana')
        elif g == 'mixed_loco' and j % 2 == 1:
            pass
        with open(os.path.join(a.out, fn), 'w') as f:
            f.write('\n'.join(hdr) + '\n')
            if u == 'adc':
                f.write('t_s,adc\n')
                cnt = np.clip(np.round(4095 * (0.1 + 0.08 * pj)), 0, 4095)
                for ti, c in zip(tj, cnt):
                    f.write(f'{ti:.2f},{"nan" if np.isnan(c) else int(c)}\n')
            else:
                f.write('t_s,p_bar\n')
                for ti, c in zip(tj, pj):
                    f.write(f'{ti:.2f},{c:.5f}\n')
        rows.append(f'{fn},unknown,L-{a.seed},train')
    with open(os.path.join(a.out, 'manifest.csv'), 'w') as f:
        f.write('file,label,locomotive,split\n' + '\n'.join(rows) + '\n')
    # truth (kept out of the data set's manifest; the audit ignores unknown files)
    Pg = (Pabs - P0) / BAR
    info = dict(effects=eff, loco=loco, noise=a.noise, seed=a.seed, garbage=a.garbage,
                final_bar=float(Pg[-1].mean()), final_x_mm=float(X[-1].mean() * 1e3))
    i4 = np.argmax(X[:, 0] > 1e-4); ie = np.argmax(X[:, 0] >= 0.0599)
    i765 = np.argmax(Pg[:, 0] >= 7.65) if (Pg[:, 0] >= 7.65).any() else -1
    info.update(breakaway_bar=float(Pg[i4, 0]), endstop_s=ie * 0.01, t765_s=i765 * 0.01)
    with open(os.path.join(a.out, 'truth.json'), 'w') as f:
        json.dump(info, f, indent=1)
    print(json.dumps({k: info[k] for k in ('breakaway_bar', 'endstop_s', 't765_s', 'final_bar', 'final_x_mm')}))


if __name__ == '__main__':
    main()
