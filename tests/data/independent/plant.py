#!/usr/bin/env python3
"""Independent plant for the spring parking brake release (SPEC §2-§5).

Written from /work/shared/SPEC.md only (no project source read).  A batch of
releases is integrated at once (numpy arrays, one element per trace) with a
fixed-step classical RK4 at 0.5 ms; the chamber pressure is sampled every
10 ms (100 Hz), then transducer noise (sigma 0.01 bar) and 12-bit ADC
quantisation are applied.

State per trace: P (Pa abs), x (m), v (m/s), z (m, LuGre bristle).
End stops: stiff (1e8 N/m), damped (zeta 0.7) penalty springs at x=0 and x=L.

Extra per-trace "mechanisms" (used by the `unfamiliar` set), all default off:
  dropout_t0/dropout_t1/dropout_mode : supply vented (mode 1: Ps=0 bar g) or
                                       blocked (mode 2: no inflow) in [t0,t1)
  stage_t / stage_ps                 : two-stage regulator: Ps=stage_ps for t<stage_t
  osc_amp / osc_f                    : regulator hunting, Ps += amp*sin(2 pi f t)
  ramp_tau                           : supply rising as Ps*(1-exp(-t/tau))
  valve_delay                        : no inflow before t=valve_delay
  leak_thr                           : leak only above this gauge pressure (bar)
  stick_x0/stick_x1/stick_fs         : extra static friction on a stroke window
  L                                  : stroke (m)
  T                                  : gas temperature (K)
"""
import math
import numpy as np

K_GAS = 1.4
R_GAS = 287.0
T_NOM = 293.15
P0 = 1.0e5
P_CR = 0.528
C1 = 0.040418
C2 = 0.156174
BAR = 1.0e5

A_PIST = 4 * math.pi * 0.05 ** 2
L_NOM = 0.060
M_NOM = 20.0
F0_NOM = 4.0 * BAR * A_PIST
FC_NOM = 150.0
FS_NOM = 300.0
VS_NOM = 0.01
K_NOM = (7.2 * BAR * A_PIST - F0_NOM - FC_NOM) / L_NOM
SIG0, SIG1, B_VISC = 1e5, 2e3, 2e3
V0_NOM = 3.0e-3
CF_NOM = 0.8
PS_NOM = 7.7

K_STOP = 1e8
C_STOP = 2 * 0.7 * math.sqrt(K_STOP * M_NOM)

DT = 0.5e-3
FS_HZ = 100
T_END = 60.0


def area(d_m):
    return math.pi * np.asarray(d_m, dtype=float) ** 2 / 4.0


def flow(pu, pd, a, cf, T):
    """Signed mass flow (kg/s) from pu to pd through area a (element-wise)."""
    hi = np.maximum(pu, pd)
    lo = np.minimum(pu, pd)
    sign = np.where(pu >= pd, 1.0, -1.0)
    r = lo / hi
    r = np.clip(r, 0.0, 1.0)
    sq = np.sqrt(T)
    choked = cf * a * C1 * hi / sq
    unch = cf * a * C2 * hi / sq * r ** (1.0 / K_GAS) * np.sqrt(np.maximum(0.0, 1.0 - r ** ((K_GAS - 1.0) / K_GAS)))
    return sign * np.where(r <= P_CR, choked, unch)


DEFAULTS = dict(
    ps=PS_NOM, d_orifice=1.25e-3, d_leak=0.0, cf=CF_NOM, V0=V0_NOM, F0=F0_NOM, K=K_NOM,
    Fc=FC_NOM, Fs=FS_NOM, vs=VS_NOM, M=M_NOM, L=L_NOM, T=T_NOM,
    dropout_t0=1e9, dropout_t1=1e9, dropout_mode=0.0,
    stage_t=0.0, stage_ps=0.0, osc_amp=0.0, osc_f=0.0, ramp_tau=0.0, valve_delay=0.0,
    leak_thr=-1.0, stick_x0=1.0, stick_x1=1.0, stick_fs=0.0,
)


def simulate_batch(params_list, t_end=T_END, dt=DT, record_x=False):
    """params_list: list of dicts (keys of DEFAULTS).  Returns p_bar_g (N, n) at 100 Hz."""
    n_tr = len(params_list)
    P = {k: np.array([float(p.get(k, v)) for p in params_list]) for k, v in DEFAULTS.items()}
    a_in = area(P["d_orifice"])
    a_lk = area(P["d_leak"])
    cf, T = P["cf"], P["T"]
    M, L, F0, Kk = P["M"], P["L"], P["F0"], P["K"]
    Fc, Fs, vs = P["Fc"], P["Fs"], P["vs"]
    V0 = P["V0"]
    ps_abs_base = P["ps"] * BAR + P0
    st_abs = P["stage_ps"] * BAR + P0

    def supply(t):
        ps = ps_abs_base.copy()
        if np.any(P["stage_t"] > 0):
            ps = np.where(t < P["stage_t"], st_abs, ps)
        if np.any(P["osc_amp"] > 0):
            ps = ps + P["osc_amp"] * BAR * np.sin(2 * math.pi * P["osc_f"] * t)
        if np.any(P["ramp_tau"] > 0):
            tau = np.maximum(P["ramp_tau"], 1e-9)
            ps = np.where(P["ramp_tau"] > 0, P0 + (ps - P0) * (1 - np.exp(-t / tau)), ps)
        in_do = (t >= P["dropout_t0"]) & (t < P["dropout_t1"])
        ps = np.where(in_do & (P["dropout_mode"] == 1), P0, ps)
        return ps, in_do & (P["dropout_mode"] == 2)

    def deriv(t, p, x, v, z):
        ps, blocked = supply(t)
        m_in = flow(ps, p, a_in, cf, T)
        m_in = np.where(blocked | (t < P["valve_delay"]), 0.0, m_in)
        m_lk = flow(p, np.full_like(p, P0), a_lk, cf, T)
        thr = P["leak_thr"]
        gate = np.where(thr >= 0, 0.5 * (1 + np.tanh(((p - P0) / BAR - thr) / 0.05)), 1.0)
        m_lk = m_lk * gate
        V = V0 + A_PIST * x
        dp = K_GAS * R_GAS * T / V * (m_in - m_lk) - K_GAS * p / V * A_PIST * v
        # LuGre
        fs_eff = Fs + np.where((x >= P["stick_x0"]) & (x < P["stick_x1"]), P["stick_fs"], 0.0)
        g = Fc + (fs_eff - Fc) * np.exp(-(v / vs) ** 2)
        dz = v - SIG0 * np.abs(v) * z / g
        ff = SIG0 * z + SIG1 * dz + B_VISC * v
        fstop = np.where(x < 0, -K_STOP * x - C_STOP * v, 0.0) + np.where(x > L, -K_STOP * (x - L) - C_STOP * v, 0.0)
        acc = ((p - P0) * A_PIST - F0 - Kk * x - ff + fstop) / M
        return dp, v, acc, dz

    p = np.full(n_tr, P0)
    x = -F0 / K_STOP  # resting on the stop under preload
    v = np.zeros(n_tr)
    z = np.zeros(n_tr)
    n_samp = int(round(t_end * FS_HZ))
    sub = int(round(1.0 / FS_HZ / dt))
    out = np.empty((n_tr, n_samp))
    xs = np.empty((n_tr, n_samp)) if record_x else None
    t = 0.0
    h = dt
    for i in range(n_samp):
        out[:, i] = (p - P0) / BAR
        if record_x:
            xs[:, i] = x
        for _ in range(sub):
            k1 = deriv(t, p, x, v, z)
            k2 = deriv(t + h / 2, p + h / 2 * k1[0], x + h / 2 * k1[1], v + h / 2 * k1[2], z + h / 2 * k1[3])
            k3 = deriv(t + h / 2, p + h / 2 * k2[0], x + h / 2 * k2[1], v + h / 2 * k2[2], z + h / 2 * k2[3])
            k4 = deriv(t + h, p + h * k3[0], x + h * k3[1], v + h * k3[2], z + h * k3[3])
            p = p + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            x = x + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            v = v + h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
            z = z + h / 6 * (k1[3] + 2 * k2[3] + 2 * k3[3] + k4[3])
            t += h
    return (out, xs) if record_x else out


def to_adc(p_bar, rng, noise=0.01):
    p = p_bar + rng.normal(0.0, noise, size=np.shape(p_bar))
    return np.clip(np.round(4095 * (0.1 + 0.08 * p)), 0, 4095).astype(int)


def p_to_code_float(p_bar):
    return 4095 * (0.1 + 0.08 * np.asarray(p_bar))


def write_trace(path, codes, meta):
    lines = [f"# {k}: {v}" for k, v in meta.items()]
    lines.append("t_s,adc")
    lines += [f"{i / FS_HZ:.2f},{int(c)}" for i, c in enumerate(codes)]
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    # Landmark check against SPEC §3
    import sys
    cases = [
        ("healthy", {}),
        ("orifice 0.4 mm", dict(d_orifice=0.4e-3)),
        ("no orifice 3.5 mm", dict(d_orifice=3.5e-3)),
        ("supply 4.027", dict(ps=4.027)),
        ("leak 1.0 mm", dict(d_leak=1.0e-3)),
    ]
    t_end = float(sys.argv[1]) if len(sys.argv) > 1 else 60.0
    out, xs = simulate_batch([c[1] for c in cases], t_end=t_end, record_x=True)
    tt = np.arange(out.shape[1]) / FS_HZ
    for (name, _), p, x in zip(cases, out, xs):
        mv = np.nonzero(x > 0.2e-3)[0]
        brk = p[mv[0]] if len(mv) else float("nan")
        es = np.nonzero(x > L_NOM - 0.2e-3)[0]
        t765 = np.nonzero(p >= 7.65)[0]
        t4027 = np.nonzero(p >= 4.027)[0]
        print(f"{name:20s} breakaway {brk:.3f} bar  endstop {tt[es[0]] if len(es) else float('nan'):.2f}s  "
              f"t7.65 {tt[t765[0]] if len(t765) else float('nan'):.2f}s  t4.027 {tt[t4027[0]] if len(t4027) else float('nan'):.2f}s  "
              f"final p {p[-1]:.3f} x {x[-1]*1e3:.1f}mm")
