//! The `f64` reference twin: the equations of SPEC §2 evaluated with the exact flow formula
//! and a fine fixed step, used only to check the fixed-point twin of the core.
//!
//! Same physics, same end-stop convention (inelastic constraints at 0 and L), independent
//! arithmetic: f64 everywhere, `powf`/`sqrt`/`exp` instead of tables, a 20 µs step (50× finer
//! than the core's 1 ms substep) with the same semi-implicit treatment of linear damping.
//!
//! It is also the "measured-like" plant of the model-discrepancy audit: the mechanisms of
//! [`pbm::mechanism::Extensions`] (see there for their definitions) are evaluated here in f64,
//! independently of the core's integer terms. The gas temperature is a state (energy equation)
//! when heat transfer is on; the valve command travels through a delay line and the valve opens
//! with a first-order area lag; the transducer ([`ReferenceTwin::sensor_bar_g`]) lags, offsets
//! and scales the chamber pressure. With no extension the step is the base model's, unchanged.

use pbm::mechanism::Mechanism;
use pbm::params::{c1, c2, circle_area, CRITICAL_RATIO, GAS_CONSTANT, KAPPA, TEMPERATURE_K};
use pbm::Meters;
use pbm::{ParamError, TwinParams};

/// Integration step of the reference, seconds.
pub const REFERENCE_STEP_S: f64 = 20e-6;
/// Atmospheric pressure, Pa.
pub const P0: f64 = 1.0e5;

/// Mass flow (kg/s) through an orifice of area `area` from `pu` to `pd` (Pa abs), SPEC §2;
/// negative when `pd > pu`.
pub fn orifice_mass_flow(cf: f64, area: f64, pu: f64, pd: f64) -> f64 {
    if area == 0.0 || pu == pd {
        return 0.0;
    }
    if pd > pu {
        return -orifice_mass_flow(cf, area, pd, pu);
    }
    let r = pd / pu;
    let k = KAPPA;
    let sqrt_t = TEMPERATURE_K.sqrt();
    if r <= CRITICAL_RATIO {
        cf * area * c1() * pu / sqrt_t
    } else {
        cf * area * c2() * pu / sqrt_t * r.powf(1.0 / k) * (1.0 - r.powf((k - 1.0) / k)).sqrt()
    }
}

/// State of the reference twin in SI units (pressure absolute, Pa).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceState {
    /// Chamber pressure, Pa abs.
    pub p: f64,
    /// Piston travel, m.
    pub x: f64,
    /// Piston velocity, m/s.
    pub v: f64,
    /// Bristle deflection, m.
    pub z: f64,
}

/// State of the plant's optional mechanisms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantExtState {
    /// Last valve command.
    pub command: bool,
    /// Valve position the chamber sees (after the transport delay).
    pub effective: bool,
    /// Time since the last command change, s (`None`: it has arrived).
    pub pending_s: Option<f64>,
    /// Time since the effective valve last switched, s.
    pub since_switch_s: f64,
    /// Gas temperature, K.
    pub gas_k: f64,
    /// Transducer state (lagged chamber gauge pressure), bar.
    pub sensed_bar_g: f64,
}

/// The f64 reference twin.
#[derive(Debug, Clone)]
pub struct ReferenceTwin {
    params: TwinParams,
    area_in: f64,
    area_leak: f64,
    step_s: f64,
    /// Current state.
    pub state: ReferenceState,
    /// State of the optional mechanisms.
    pub ext_state: PlantExtState,
}

impl ReferenceTwin {
    /// A reference twin at the release command.
    pub fn new(params: &TwinParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(Self {
            params: *params,
            area_in: circle_area(params.orifice),
            area_leak: circle_area(params.leak),
            step_s: REFERENCE_STEP_S,
            state: ReferenceState { p: P0, x: 0.0, v: 0.0, z: 0.0 },
            ext_state: PlantExtState {
                command: false,
                effective: false,
                pending_s: None,
                since_switch_s: 1e9,
                gas_k: if params.ext[Mechanism::HeatTransfer] > 0.0 {
                    TEMPERATURE_K
                } else {
                    params.ext[Mechanism::GasTemperature]
                },
                sensed_bar_g: 0.0,
            },
        })
    }

    /// The same twin with another integration step (seconds, clamped to 1 µs..=1 ms); a coarser
    /// step trades accuracy for speed when generating large data sets.
    pub fn with_step(mut self, step_s: f64) -> Self {
        self.step_s = if step_s.is_finite() { step_s.clamp(1e-6, 1e-3) } else { REFERENCE_STEP_S };
        self
    }

    /// The plant's parameters.
    pub fn params(&self) -> &TwinParams {
        &self.params
    }

    /// Changes the base parameters mid-release, keeping the state: the time-varying conditions
    /// of the open-world cases ([`crate::open_world`]: a hunting regulator, a leak that opens
    /// above a pressure, an orifice that ices up). Not validated; the mechanism extensions are
    /// not to be changed (their state is not re-initialised).
    pub fn retune(&mut self, f: impl FnOnce(&mut TwinParams)) {
        f(&mut self.params);
        self.area_in = circle_area(self.params.orifice);
        self.area_leak = circle_area(self.params.leak);
    }

    /// Advances `duration` seconds with the valve open (release) or closed (vent).
    pub fn advance(&mut self, duration: f64, valve_open: bool) {
        let n = (duration / self.step_s).round() as u64;
        if self.params.ext.is_none() {
            for _ in 0..n {
                self.step(self.step_s, valve_open);
            }
        } else {
            for _ in 0..n {
                self.step_extended(self.step_s, valve_open);
            }
        }
    }

    /// What the transducer reads, bar g: the chamber pressure without sensor extensions, else
    /// `offset + gain · lag(p)`.
    pub fn sensor_bar_g(&self) -> f64 {
        let e = &self.params.ext;
        if !e.has_sensor_terms() {
            return self.pressure_bar_g();
        }
        let lagged = if e[Mechanism::SensorLag] > 0.0 { self.ext_state.sensed_bar_g } else { self.pressure_bar_g() };
        e[Mechanism::SensorOffset] + e[Mechanism::SensorGain] * lagged
    }

    /// One step with the optional mechanisms (f64, independent of the core's integer terms).
    fn step_extended(&mut self, h: f64, valve_open: bool) {
        let q = self.params;
        let e = q.ext;
        let es = &mut self.ext_state;
        // Valve command through the delay line, then first-order opening of the new path.
        if valve_open != es.command {
            es.command = valve_open;
            es.pending_s = Some(0.0);
        }
        // The switch may fall inside this step, at `ts` seconds from its start.
        let area_frac =
            |since: f64| if e[Mechanism::ValveLag] > 0.0 { 1.0 - (-since / e[Mechanism::ValveLag]).exp() } else { 1.0 };
        let mut switch_at = None;
        if let Some(t) = es.pending_s {
            if t + h >= e[Mechanism::TransportDelay] {
                switch_at = Some((e[Mechanism::TransportDelay] - t).clamp(0.0, h));
                es.pending_s = None;
            } else {
                es.pending_s = Some(t + h);
            }
        }
        let paths = match switch_at {
            Some(ts) => {
                let old = (es.effective, ts / h * area_frac(es.since_switch_s + 0.5 * ts));
                es.effective = es.command;
                es.since_switch_s = h - ts;
                [old, (es.effective, (h - ts) / h * area_frac(0.5 * (h - ts)))]
            }
            None => {
                let cur = (es.effective, area_frac(es.since_switch_s + 0.5 * h));
                es.since_switch_s += h;
                [cur, (false, 0.0)]
            }
        };

        let s = self.state;
        let a = q.piston_area_m2;
        let (x, v, z) = piston_step(&q, &s, h, e[Mechanism::ProgressiveSpring]);
        let dx = x - s.x;

        // Chamber energy balance: V dp = (k−1)(cp Ts m_in − cp T m_out + Q) dt − k p dV, with the
        // orifice flows at their upstream temperature.
        let t_supply = e[Mechanism::GasTemperature];
        let thermal = e[Mechanism::HeatTransfer] > 0.0;
        let t_gas = es.gas_k;
        let vol = q.dead_volume_m3 + a * s.x;
        let supply = q.supply.to_abs_pa();
        let nominal_area = circle_area(Meters::from_mm(pbm::TwinParams::NOMINAL_ORIFICE_MM));
        let m_ref = q.discharge_coeff * nominal_area * c1() * supply / t_supply.sqrt();
        let flow = |pu: f64, pd: f64, area: f64, t_up: f64, t_down: f64| {
            // Mass flow with the upstream temperature; returns (mass, enthalpy temperature).
            let m = orifice_mass_flow(q.discharge_coeff, area, pu, pd);
            if m >= 0.0 {
                (m * (TEMPERATURE_K / t_up).sqrt(), t_up)
            } else {
                (m * (TEMPERATURE_K / t_down).sqrt(), t_down)
            }
        };
        let (mut m_net, mut h_net) = (0.0, 0.0);
        for (open, share) in paths {
            if share <= 0.0 {
                continue;
            }
            let mut pu = if open { supply } else { P0 };
            if open && e[Mechanism::RegulatorDroop] > 0.0 && s.p < supply {
                // Implicit supply sag pu = Ps − droop · m(pu)/m_ref: bisection on [p, Ps].
                let (mut lo, mut hi) = (s.p, supply);
                for _ in 0..50 {
                    let mid = 0.5 * (lo + hi);
                    let (m, _) = flow(mid, s.p, self.area_in, t_supply, t_gas);
                    if mid - supply + e[Mechanism::RegulatorDroop] * 1e5 * (share * m).max(0.0) / m_ref <= 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                pu = 0.5 * (lo + hi);
            }
            let t_up = if open { t_supply } else { t_gas };
            let (m, t) = flow(pu, s.p, self.area_in, t_up, t_gas);
            m_net += share * m;
            h_net += share * m * t;
        }
        let (m_leak, _) = flow(s.p, P0, self.area_leak, t_gas, t_gas);
        let m_lam = e[Mechanism::LaminarLeak] * 1e-3 * (s.p - P0) / 7e5;
        m_net -= m_leak + m_lam;
        h_net -= (m_leak + m_lam) * t_gas;
        let heat = if thermal { s.p * (TEMPERATURE_K - t_gas) / (t_gas * e[Mechanism::HeatTransfer]) } else { 0.0 };
        let dp = (KAPPA * GAS_CONSTANT / vol * h_net + heat) * h - KAPPA * s.p / vol * a * dx;
        let p_new = (s.p + dp).max(0.0);
        if thermal {
            // T = pV/(mR): dT/T = dp/p + dV/V − dm/m, m = pV/(RT).
            let mass = s.p * vol / (GAS_CONSTANT * t_gas);
            let rel = dp / s.p.max(1.0) + a * dx / vol - m_net * h / mass.max(1e-12);
            es.gas_k = (t_gas * (1.0 + rel)).clamp(50.0, 2000.0);
        }
        if e[Mechanism::SensorLag] > 0.0 {
            let target = p_new / 1e5 - 1.0;
            es.sensed_bar_g = target + (es.sensed_bar_g - target) * (-h / e[Mechanism::SensorLag]).exp();
        }
        self.state = ReferenceState { p: p_new, x, v, z };
    }

    fn step(&mut self, h: f64, valve_open: bool) {
        let q = &self.params;
        let s = self.state;
        let a = q.piston_area_m2;
        let (x, v, z) = piston_step(q, &s, h, 0.0);
        let dx = x - s.x;

        // Chamber: dP/dt = kRT/V (m_in − m_leak) − kP/V dV/dt.
        let vol = q.dead_volume_m3 + a * s.x;
        let upstream = if valve_open { q.supply.to_abs_pa() } else { P0 };
        let m_in = orifice_mass_flow(q.discharge_coeff, self.area_in, upstream, s.p);
        let m_leak = orifice_mass_flow(q.discharge_coeff, self.area_leak, s.p, P0);
        let dp = KAPPA * GAS_CONSTANT * TEMPERATURE_K / vol * (m_in - m_leak) * h - KAPPA * s.p / vol * a * dx;
        self.state = ReferenceState { p: (s.p + dp).max(0.0), x, v, z };
    }

    /// Gauge pressure, bar.
    pub fn pressure_bar_g(&self) -> f64 {
        self.state.p / 1e5 - 1.0
    }
}

/// Travel (m) and velocity (m/s) of the base piston driven by a *given* chamber pressure
/// (`p_bar_g`, one value per `sample_s`, linearly interpolated between samples), integrated at
/// [`REFERENCE_STEP_S`]: the motion a measured pressure trace implies, for the audit's
/// reconstruction of the unmodelled flow ([`crate::missing_flow`]). One value per sample.
pub fn piston_under_pressure(params: &TwinParams, p_bar_g: &[f64], sample_s: f64) -> (Vec<f64>, Vec<f64>) {
    let mut state = ReferenceState { p: P0, x: 0.0, v: 0.0, z: 0.0 };
    let substeps = ((sample_s / REFERENCE_STEP_S).round() as usize).max(1);
    let h = sample_s / substeps as f64;
    let mut x = Vec::with_capacity(p_bar_g.len());
    let mut v = Vec::with_capacity(p_bar_g.len());
    for (i, &p) in p_bar_g.iter().enumerate() {
        x.push(state.x);
        v.push(state.v);
        let next = p_bar_g.get(i + 1).copied().unwrap_or(p);
        for k in 0..substeps {
            let w = k as f64 / substeps as f64;
            state.p = ((1.0 - w) * p + w * next + 1.0) * 1e5;
            let (nx, nv, nz) = piston_step(params, &state, h, 0.0);
            state = ReferenceState { p: state.p, x: nx, v: nv, z: nz };
        }
    }
    (x, v)
}

/// One step of the piston: `M dv/dt = (P − P0) A − F0 − K (1 + β x/L) x − F_f` with LuGre friction
/// `F_f` (`β` = `progressive`, 0 for the base spring), `(sigma1 + B) v` implicit, inelastic end
/// stops. Returns the new `(x, v, z)`.
fn piston_step(q: &TwinParams, s: &ReferenceState, h: f64, progressive: f64) -> (f64, f64, f64) {
    let l = q.stroke.0;
    let g = q.coulomb_n + (q.static_n - q.coulomb_n) * (-(s.v / q.stribeck_m_per_s).powi(2)).exp();
    // dz/dt = v − |v| · zdot_nl_per_v
    let zdot_nl_per_v = q.sigma0_n_per_m * s.z / g;
    // With β = 0 the factor is exactly 1.0, so the base spring is F0 + K x to the last bit.
    let f_ext = (s.p - P0) * q.piston_area_m2
        - q.preload_n
        - q.spring_rate_n_per_m * (1.0 + progressive * s.x / l) * s.x
        - q.sigma0_n_per_m * s.z
        + q.sigma1_n_s_per_m * s.v.abs() * zdot_nl_per_v;
    let c = q.sigma1_n_s_per_m + q.viscous_n_s_per_m;
    let mut v = (s.v + h / q.mass_kg * f_ext) / (1.0 + h * c / q.mass_kg);
    let mut x = s.x + h * v;
    if x <= 0.0 {
        x = 0.0;
        v = 0.0;
    } else if x >= l {
        x = l;
        v = 0.0;
    }
    let z = s.z + h * (v - v.abs() * zdot_nl_per_v);
    (x, v, z)
}
