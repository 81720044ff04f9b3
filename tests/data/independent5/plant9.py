"""Independent brake plant written from /work/shared/SPEC.md only (tester 9).

RK4, fixed 1 ms step, plain floats. End stops are inelastic constraints (the limit of a stiff,
damped stop). Optional mechanisms (library and outside it) are selected through `eff`.
"""
import math, random

k = 1.4; R = 287.0; T0 = 293.15; P0 = 1.0e5; PCR = 0.528
C1 = 0.040418; C2 = 0.156174
A = 4 * math.pi * 0.05 ** 2
L = 0.060; M = 20.0
SIG0, SIG1, BV = 1e5, 2e3, 2e3
FC, FS, VS = 150.0, 300.0, 0.01


def nominal():
    F0 = 4.0e5 * A
    K = (7.2e5 * A - F0 - FC) / L
    return dict(Ps=7.7, d=1.25, Cf=0.8, V0=3.0e-3, F0=F0, K=K, Fc=FC, Fs=FS, leak=0.0)


def loco(rng, spread=0.05):
    p = nominal()
    for key in ("V0", "F0", "K", "Cf", "Fc", "Fs"):
        p[key] *= 1 + rng.uniform(-spread, spread)
    p["Ps"] = 7.7 + rng.uniform(-0.03, 0.03)
    return p


def orifice(pu, pd, area, Cf, Tu=T0):
    """mass flow pu->pd (kg/s), sign-aware."""
    if pu < pd:
        return -orifice(pd, pu, area, Cf, Tu)
    if pu <= 0:
        return 0.0
    r = pd / pu
    if r <= PCR:
        return Cf * area * C1 * pu / math.sqrt(Tu)
    return Cf * area * C2 * pu / math.sqrt(Tu) * r ** (1 / k) * math.sqrt(max(0.0, 1 - r ** ((k - 1) / k)))


def orifice_b(pu, pd, area, Cf, b, Tu=T0):
    """ISO 6358 form with critical ratio b (same choked flow as Sanville)."""
    if pu <= pd:
        return 0.0
    r = pd / pu
    mc = Cf * area * C1 * pu / math.sqrt(Tu)
    if r <= b:
        return mc
    return mc * math.sqrt(max(0.0, 1 - ((r - b) / (1 - b)) ** 2))


def simulate(p, eff=None, dur=60.0, dt=1e-3):
    """returns (t, p_gauge_bar, x_mm) at 100 Hz (true chamber pressure)."""
    eff = eff or {}
    Ps = P0 + p["Ps"] * 1e5
    area = math.pi / 4 * (p["d"] * 1e-3) ** 2
    Cf = p["Cf"]; V0 = p["V0"]; F0 = p["F0"]; K = p["K"]
    Fc = p["Fc"] * eff.get("fric", 1.0); Fs = p["Fs"] * eff.get("fric", 1.0)
    fric_tau = eff.get("fric_decay_tau")        # friction (fric0 -> 1) x decaying
    fric0 = eff.get("fric0", 1.0)
    aleak = math.pi / 4 * (p.get("leak", 0.0) * 1e-3) ** 2
    delay = eff.get("delay", 0.0)
    vtau = eff.get("valve_lag", 0.0)
    htau = eff.get("heat_tau")
    Tin = eff.get("gas_T", T0)
    droop = eff.get("droop", 0.0)
    prog = eff.get("prog", 0.0)
    lam = eff.get("laminar", 0.0) * 1e-3 / 7e5       # kg/s per Pa gauge
    plk = eff.get("pleak")                            # (p_open_bar_g, d_mm)
    sag = eff.get("sag", 0.0)                         # bar per 60 s
    hunt = eff.get("hunt")                            # (amp bar, freq Hz)
    vol2 = eff.get("vol2")                            # (V2 m3, d_mm)
    stick = eff.get("stick")                          # (frac area, until t)
    crack = eff.get("crack", 0.0) * 1e5               # check valve cracking (Pa)
    vol_up = eff.get("vol_up")                        # volume between valve and orifice (V m3, d_valve mm)
    seal_bp = eff.get("seal_bypass", 0.0)             # kg per m of travel lost past the seal while sliding
    leak_at = eff.get("leak_at")                      # (t_open s, d mm): a seal that tears mid-release
    icing = eff.get("icing", 0.0)                     # orifice diameter shrinks by this fraction over 60 s
    Tw = eff.get("Tw", T0)                            # wall temperature for heat transfer
    isob = eff.get("iso_b")
    fric_p = eff.get("fric_p", 0.0)                   # friction x (1 + fric_p * p_gauge/7 bar): seal pressed by pressure
    leak_below = eff.get("leak_below")                # (p bar g, d mm): lip seal leaking only below p
    sstep = eff.get("supply_step")                    # (t s, drop bar)
    Mm = M * eff.get("mass", 1.0)
    comp = eff.get("compliance", 0.0)                 # hose/chamber volume grows by this fraction per 7 bar
    thermal = htau is not None or Tin != T0
    mnom = orifice(P0 + 7.7e5, P0, math.pi / 4 * (1.25e-3) ** 2, 0.8)
    if vol2:
        a2 = math.pi / 4 * (vol2[1] * 1e-3) ** 2
    if vol_up:
        aup = math.pi / 4 * (vol_up[1] * 1e-3) ** 2
    if plk:
        apl = math.pi / 4 * (plk[1] * 1e-3) ** 2; ppl = P0 + plk[0] * 1e5

    def supply(t):
        s = Ps - sag * 1e5 * t / 60.0
        if sstep and t >= sstep[0]:
            s -= sstep[1] * 1e5
        if hunt:
            s += hunt[0] * 1e5 * math.sin(2 * math.pi * hunt[1] * t)
        return s

    def valve(t):
        if t < delay:
            return 0.0
        f = 1.0
        if icing:
            f = (1 - icing * t / 60.0) ** 2
        if vtau > 0:
            f *= 1 - math.exp(-(t - delay) / vtau)
        if stick and t < stick[1]:
            f *= stick[0]
        return f

    def deriv(t, s):
        P, x, v, z, m, P2, Pu = s
        V = V0 * (1 + comp * (P - P0) / 7e5) + A * x
        vf = valve(t)
        ps = supply(t)
        # inflow
        if vol_up:
            mu = orifice(ps, Pu, aup * vf, 1.0)  # valve (large) into the upstream line
            min_ = orifice(Pu, P, area, Cf)
            dPu = k * R * T0 / vol_up[0] * (mu - min_)
        else:
            dPu = 0.0
            if vf > 0:
                if droop > 0:
                    # supply sags in proportion to the flow: solve pe = ps - droop*m(pe)/mnom (bisection)
                    if ps <= P:
                        min_ = orifice(ps, P, area * vf, Cf, Tin)
                    else:
                        lo, hi = P, ps
                        for _ in range(22):
                            mid = 0.5 * (lo + hi)
                            if mid - ps + droop * 1e5 * orifice(mid, P, area * vf, Cf, Tin) / mnom > 0:
                                hi = mid
                            else:
                                lo = mid
                        min_ = orifice(0.5 * (lo + hi), P, area * vf, Cf, Tin)
                else:
                    if isob:
                        min_ = orifice_b(ps, P, area * vf, Cf, isob, Tin)
                    else:
                        min_ = orifice(ps, P, area * vf, Cf, Tin) if ps > P + crack else 0.0
            else:
                min_ = 0.0
        Tg = P * V / (m * R) if thermal else T0
        mout = 0.0
        if aleak > 0:
            mout += orifice(P, P0, aleak, Cf, Tg)
        if lam > 0:
            mout += lam * (P - P0)
        if leak_below and P < P0 + leak_below[0] * 1e5:
            mout += orifice(P, P0, math.pi / 4 * (leak_below[1] * 1e-3) ** 2, Cf, Tg)
        if leak_at and t >= leak_at[0]:
            mout += orifice(P, P0, math.pi / 4 * (leak_at[1] * 1e-3) ** 2, Cf, Tg)
        if seal_bp:
            mout += seal_bp * abs(v)
        if plk and P > ppl:
            mout += orifice(P, P0, apl, Cf, Tg)
        if vol2:
            m2 = orifice(P, P2, a2, 0.8, Tg)
            mout += m2
            dP2 = k * R * T0 / vol2[0] * m2 if m2 > 0 else k * R * T0 / vol2[0] * m2
        else:
            dP2 = 0.0
        # piston
        g = Fc + (Fs - Fc) * math.exp(-(v / VS) ** 2)
        if fric_p:
            g *= 1 + fric_p * max(0.0, P - P0) / 7e5
        if fric_tau:
            sc = 1 + (fric0 - 1) * math.exp(-t / fric_tau)
            g *= sc
        dz = v - SIG0 * abs(v) * z / g
        Ff = SIG0 * z + SIG1 * dz + BV * v
        Fsp = K * x * (1 + prog * x / L)
        F = (P - P0) * A - F0 - Fsp - Ff
        a = F / Mm
        if x <= 0 and v <= 0 and a < 0:
            a = 0.0
            if v == 0:
                dz = 0.0
        if x >= L and v >= 0 and a > 0:
            a = 0.0
            if v == 0:
                dz = 0.0
        dm = min_ - mout
        if comp:
            # dV/dt = V0*comp/7e5 * dP/dt enters the chamber equation implicitly
            pass
        if thermal:
            dP = k * R / V * (Tin * min_ - Tg * mout) - k * P / V * A * v
            if htau:
                dP += R * m * (Tw - Tg) / (V * htau)
        else:
            dP = k * R * T0 / V * (min_ - mout) - k * P / V * A * v
        if comp:
            dP = dP / (1 + k * P * V0 * comp / (7e5 * V))
        return (dP, v, a, dz, dm, dP2, dPu)

    Pi = P0 + eff.get("precharge", 0.0) * 1e5
    s = [Pi, 0.0, 0.0, 0.0, Pi * V0 / (R * T0), P0, P0]
    n = int(round(dur / dt)); every = int(round(0.01 / dt))
    ts, ps_, xs = [], [], []
    t = 0.0
    for i in range(n):
        if i % every == 0:
            ts.append(round(i * dt, 6)); ps_.append((s[0] - P0) / 1e5); xs.append(s[1] * 1e3)
        k1 = deriv(t, s)
        s2 = [a + 0.5 * dt * b for a, b in zip(s, k1)]
        k2 = deriv(t + 0.5 * dt, s2)
        s3 = [a + 0.5 * dt * b for a, b in zip(s, k2)]
        k3 = deriv(t + 0.5 * dt, s3)
        s4 = [a + dt * b for a, b in zip(s, k3)]
        k4 = deriv(t + dt, s4)
        s = [a + dt / 6 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(s, k1, k2, k3, k4)]
        # end-stop constraints
        if s[1] < 0:
            s[1] = 0.0
            if s[2] < 0: s[2] = 0.0
        elif s[1] > L:
            s[1] = L
            if s[2] > 0: s[2] = 0.0
        t = (i + 1) * dt
    return ts, ps_, xs


def sensor(ps, rng, sig=0.01, lag=0.0, offset=0.0, gain=1.0, bow=0.0, ar_tau=0.0, hum=0.0, sat=0.0):
    out = []
    ar = math.exp(-0.01 / ar_tau) if ar_tau > 0 else 0.0
    e = 0.0
    i = -1
    y = ps[0]
    a = 1 - math.exp(-0.01 / lag) if lag > 0 else 1.0
    for p in ps:
        y += a * (p - y)
        i += 1
        e = ar * e + math.sqrt(1 - ar * ar) * rng.gauss(0, sig)
        q = gain * y + offset + bow * (y * (10 - y) / 25.0) + e
        q += hum * math.sin(2 * math.pi * 49.0 * i * 0.01)
        q -= sat * max(0.0, y - 6.0) ** 2 / 1.7 ** 2
        c = int(round(4095 * (0.1 + 0.08 * q)))
        out.append(min(4095, max(0, c)))
    return out


def write_trace(path, ts, counts, meta):
    with open(path, "w") as f:
        for kk, vv in meta.items():
            f.write(f"# {kk}: {vv}\n")
        f.write("t_s,adc\n")
        for t, c in zip(ts, counts):
            f.write(f"{t:.2f},{c}\n")


if __name__ == "__main__":
    import time
    t0 = time.time()
    ts, ps, xs = simulate(nominal())
    print("time", time.time() - t0)
    # landmarks
    def first(cond):
        for t, p, x in zip(ts, ps, xs):
            if cond(p, x):
                return t, p, x
    print("breakaway", first(lambda p, x: x > 0.5))
    print("end stop", first(lambda p, x: x >= 59.99))
    print("7.65", first(lambda p, x: p >= 7.65))
    n = nominal(); n["leak"] = 1.0
    ts, ps, xs = simulate(n)
    print("leak plateau", ps[-1], xs[-1])
    n = nominal(); n["d"] = 0.4
    ts, ps, xs = simulate(n)
    print("0.4mm 4.027", first(lambda p, x: p >= 4.027))
