"""Independent plant for the spring parking brake (written from SPEC.md physics only).

Vectorised over many releases at once: every parameter is an array of shape (N,).
Integrator: classic RK4 at dt = 1 ms, output every 10 ms (100 Hz).
States: P (Pa abs chamber), x (m), v (m/s), z (LuGre bristle, m), m (gas mass, kg, used only by
heat transfer), Pm (Pa abs, intermediate volume between two orifices / supply capacity),
Ts_lag (sensor first-order lag state, handled after integration).
"""
import numpy as np

k = 1.4; R = 287.0; T = 293.15; P0 = 1.0e5; PCR = 0.528
C1 = 0.040418; C2 = 0.156174
A = 4 * np.pi * 0.05 ** 2
L = 0.060; M = 20.0
SIG0, SIG1, BV = 1e5, 2e3, 2e3
FC, FS, VS = 150.0, 300.0, 0.01
F0N = 4.0e5 * A
KN = (7.2e5 * A - F0N - FC) / L
KSTOP = 2e7; CSTOP = 2.8e4


def orifice(pu, pd, area, cf, temp=T):
    """ISO 6358 / Sanville mass flow pu->pd (signed: negative if pd > pu)."""
    sgn = np.where(pu >= pd, 1.0, -1.0)
    hi = np.maximum(pu, pd); lo = np.minimum(pu, pd)
    r = lo / hi
    unch = C2 * r ** (1 / k) * np.sqrt(np.maximum(1 - r ** ((k - 1) / k), 0.0))
    fac = np.where(r <= PCR, C1, unch)
    return sgn * cf * area * fac * hi / np.sqrt(temp)


def area_of(d_mm):
    return np.pi * (np.asarray(d_mm) * 1e-3) ** 2 / 4


DEFAULTS = dict(
    ps=7.7, d_or=1.25, d_leak=0.0, cf=0.8, v0=3.0e-3, f0=F0N, kk=KN, fc=FC, fs=FS,
    # library-like mechanisms
    delay=0.0, valve_tau=0.0, heat_tau=0.0, ts=T, droop=0.0, prog=0.0, lam=0.0,
    # non-library effects
    open_ramp=0.0,          # valve area ramps linearly 0->1 over open_ramp s
    ripple_amp=0.0, ripple_hz=0.0, ripple_ph=0.0,  # supply ripple (bar)
    sw_t=1e9, ps2=7.7,      # supply switched to ps2 at sw_t
    crack=0.0,              # check valve cracking pressure (bar) in the supply line
    d_ser=0.0, vm=0.0,      # second orifice in series (mm) with intermediate volume vm (m3); vm>0 only
    fric_p=0.0,             # friction grows by fric_p per bar of chamber gauge pressure (relative)
    block_rate=0.0,         # orifice area fraction lost per second during the release
    p_init=0.0,             # initial chamber gauge pressure (bar)
    leak_above=1e9, d_leak2=0.0,  # leak opening above a pressure (bar g)
    stop_L=L,               # end stop position
    b_iso=0.0,              # ISO 6358 critical ratio b of the release orifice (0: SPEC Sanville law)
    d_leak_stroke=0.0,      # leak (mm) open only while the piston is between its stops (seal unseated)
)


def simulate(params_list, tend=60.0, dt=1e-3, every=10):
    N = len(params_list)
    P = {key: np.array([float(p.get(key, dv)) for p in params_list]) for key, dv in DEFAULTS.items()}
    ps_abs = P['ps'] * 1e5 + P0
    ps2_abs = P['ps2'] * 1e5 + P0
    a_or = area_of(P['d_or']); a_leak = area_of(P['d_leak']); a_ser = area_of(P['d_ser'])
    a_leak2 = area_of(P['d_leak2'])
    use_ser = P['d_ser'] > 0
    vm = np.where(P['vm'] > 0, P['vm'], 1.0)
    m_ref = orifice(np.full(N, 7.7e5 + P0), np.full(N, P0), area_of(np.full(N, 1.25)), 0.8)
    stopL = P['stop_L']

    def rhs(t, y):
        p, x, v, z, m, pm = y
        # supply
        psup = np.where(t >= P['sw_t'], ps2_abs, ps_abs)
        psup = psup + P['ripple_amp'] * 1e5 * np.sin(2 * np.pi * P['ripple_hz'] * t + P['ripple_ph'])
        psup = psup - P['crack'] * 1e5
        # valve area factor
        fa = np.ones(N)
        fa = np.where(t < P['delay'], 0.0, fa)
        te = t - P['delay']
        fa = np.where(P['valve_tau'] > 0, fa * (1 - np.exp(-np.maximum(te, 0) / np.maximum(P['valve_tau'], 1e-9))), fa)
        fa = np.where(P['open_ramp'] > 0, fa * np.clip(te / np.maximum(P['open_ramp'], 1e-9), 0, 1), fa)
        fa = fa * np.maximum(1 - P['block_rate'] * t, 0.05)
        # flows
        # check valve: no reverse flow through it
        if np.any(P['crack'] > 0):
            psup = np.where(P['crack'] > 0, np.maximum(psup, np.where(use_ser, pm, p)), psup)
        up = np.where(use_ser, pm, psup)
        m_in = orifice(up, p, a_or * fa, P['cf'], P['ts'])
        if np.any(P['b_iso'] > 0):
            bb = np.maximum(P['b_iso'], 1e-6)
            hi = np.maximum(up, p); r = np.minimum(up, p) / hi
            sg = np.where(up >= p, 1.0, -1.0)
            ch = P['cf'] * a_or * fa * C1 * hi / np.sqrt(P['ts'])
            ell = np.sqrt(np.maximum(1 - ((r - bb) / (1 - bb)) ** 2, 0.0))
            m_iso = sg * ch * np.where(r <= bb, 1.0, ell)
            m_in = np.where(P['b_iso'] > 0, m_iso, m_in)
        if np.any(P['droop'] > 0):
            ps_eff = psup - P['droop'] * 1e5 * np.maximum(m_in, 0) / m_ref
            m_in = np.where(P['droop'] > 0, orifice(ps_eff, p, a_or * fa, P['cf'], P['ts']), m_in)
        m_ser = np.where(use_ser, orifice(psup, pm, a_ser, P['cf'], P['ts']), 0.0)
        m_leak = orifice(p, np.full(N, P0), a_leak, P['cf']) + P['lam'] * (p - P0)
        m_leak = m_leak + np.where(p - P0 > P['leak_above'] * 1e5, orifice(p, np.full(N, P0), a_leak2, P['cf']), 0.0)
        a_ls = area_of(P['d_leak_stroke'])
        m_leak = m_leak + np.where((x > 0.5e-3) & (x < stopL - 0.5e-3), orifice(p, np.full(N, P0), a_ls, P['cf']), 0.0)
        # piston
        xe = np.clip(x, 0, stopL)
        V = P['v0'] + A * xe
        moving = (x > 0) & (x < stopL)
        dV = A * v * moving
        gp = 1 + P['fric_p'] * np.maximum(p - P0, 0) / 1e5
        fc = P['fc'] * gp; fs = P['fs'] * gp
        g = fc + (fs - fc) * np.exp(-(v / VS) ** 2)
        dz = v - SIG0 * np.abs(v) * z / g
        ff = SIG0 * z + SIG1 * dz + BV * v
        kx = P['kk'] * x * (1 + P['prog'] * x / L)
        fstop = np.where(x < 0, -KSTOP * x - CSTOP * v, 0.0) + np.where(x > stopL, -KSTOP * (x - stopL) - CSTOP * v, 0.0)
        acc = ((p - P0) * A - P['f0'] - kx - ff + fstop) / M
        # chamber
        ts_ratio = P['ts']
        dp = k * R / V * (ts_ratio * m_in - T * m_leak) - k * p / V * dV
        dm = m_in - m_leak
        if np.any(P['heat_tau'] > 0):
            tau = np.maximum(P['heat_tau'], 1e-9)
            dp = dp + np.where(P['heat_tau'] > 0, (m * R * T / V - p) / tau, 0.0)
        dpm = np.where(use_ser, k * R * P['ts'] / vm * (m_ser - m_in), 0.0)
        return np.array([dp, v, acc, dz, dm, dpm])

    p_init = P['p_init'] * 1e5 + P0
    x_init = np.minimum(-(P['f0'] - (p_init - P0) * A) / KSTOP, 0)
    y = np.array([p_init, x_init, np.zeros(N), np.zeros(N),
                  p_init * P['v0'] / (R * T), np.where(use_ser, p_init, 0.0)])
    nsteps = int(round(tend / dt))
    out_p = np.empty((nsteps // every, N)); out_x = np.empty((nsteps // every, N))
    t = 0.0
    for i in range(nsteps):
        if i % every == 0:
            out_p[i // every] = y[0]; out_x[i // every] = y[1]
        k1 = rhs(t, y)
        k2 = rhs(t + dt / 2, y + dt / 2 * k1)
        k3 = rhs(t + dt / 2, y + dt / 2 * k2)
        k4 = rhs(t + dt, y + dt * k3)
        y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t = (i + 1) * dt
    tt = np.arange(nsteps // every) * dt * every
    return tt, (out_p - P0) / 1e5, out_x  # gauge bar


def sensor(tt, pg, rng, noise=0.01, offset=0.0, gain=1.0, lag=0.0, bits=12, mains=0.0, mains_hz=50.0,
           drift=0.0, bow=0.0, spikes=0.0, spike_amp=0.5):
    """pg: (n,) true gauge bar -> ADC counts (int)."""
    p = pg.copy()
    if lag > 0:
        a = 0.01 / (lag + 0.01)
        q = np.empty_like(p); acc = p[0]
        for i in range(len(p)):
            acc = acc + a * (p[i] - acc); q[i] = acc
        p = q
    p = p * gain + offset + drift * tt / 60.0 + bow * p * (10 - p) / 25.0
    p = p + mains * np.sin(2 * np.pi * mains_hz * tt + rng.uniform(0, 2 * np.pi))
    p = p + rng.normal(0, noise, len(p))
    if spikes > 0:
        idx = rng.random(len(p)) < spikes
        p[idx] += spike_amp * rng.choice([-1, 1], idx.sum())
    c = np.round(4095 * (0.1 + 0.08 * p))
    if bits < 12:
        step = 2 ** (12 - bits)
        c = np.round(c / step) * step
    return np.clip(c, 0, 4095).astype(int)


def loco_spread(rng, spread=0.05):
    u = lambda: 1 + rng.uniform(-spread, spread)
    return dict(v0=3.0e-3 * u(), f0=F0N * u(), kk=KN * u(), cf=0.8 * u(), fc=FC * u(), fs=FS * u(),
                ps=7.7 + rng.uniform(-0.03, 0.03))


if __name__ == '__main__':
    import time
    t0 = time.time()
    tt, pg, xx = simulate([{}, {'d_or': 0.4}, {'d_or': 3.5}, {'ps': 4.027}, {'d_leak': 1.0}])
    print('sim time', time.time() - t0)
    h = pg[:, 0]
    ib = np.argmax(xx[:, 0] > 1e-4); print('breakaway p', h[ib], 't', tt[ib])
    print('end stop t', tt[np.argmax(xx[:, 0] >= L - 1e-5)])
    print('7.65 at', tt[np.argmax(h >= 7.65)])
    print('0.4mm: 4.027 at', tt[np.argmax(pg[:, 1] >= 4.027)])
    print('3.5mm: 7.65 at', tt[np.argmax(pg[:, 2] >= 7.65)])
    print('ps 4.027: final', pg[-1, 3], 'x', xx[-1, 3])
    print('leak 1mm: final', pg[-1, 4], 'x', xx[-1, 4])
