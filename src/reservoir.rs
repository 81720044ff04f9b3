//! A compressor-fed air reservoir in fixed point, assembled from the twin's pieces: the model of
//! the real MetroPT-3 air production unit (SPEC §8) that `host-sim audit-metro` fits.
//!
//! | piece | shared with the brake twin |
//! |---|---|
//! | constant-volume chamber, energy equation with optional wall heat | [`chamber_substep`] |
//! | consumption + leakage: an orifice to atmosphere (flow table) and a laminar leak | [`vent_increments`] (the twin's flow table) |
//! | compressor command: transport delay and opening lag | [`ValveLine`], [`LineCoeffs`] |
//! | transducer: lag, offset, gain | [`SensorCoeffs`] |
//!
//! The one new piece is the compressor: a **mass-flow source** (a screw compressor delivers a
//! nearly constant mass flow against 8–10 bar, unlike an orifice from a fixed supply) while it is
//! *loaded*, delivering air at the measured outlet temperature.
//!
//! # Q formats
//!
//! In the types ([`Q`]): pressure Q7.24 bar absolute ([`PressureQ24`]), gas temperature over
//! the wall temperature [`TEMPERATURE_K`] as θ Q24, increments per substep summed in Q40 bar and
//! rounded once (as in the twin). One [`Reservoir::update`] advances [`RESERVOIR_SUBSTEP_S`].
//!
//! # Mechanisms ([`Extensions`], ranges in [`crate::mechanism::Descriptor::reservoir`])
//!
//! - `transport_delay`: loading reaches the reservoir this long after the command (the
//!   compressor outlet must first climb to reservoir pressure before the check valve opens);
//!   unloading acts at once.
//! - `valve_lag`: the delivered flow rises as 1 − e^(−t/τ) after loading.
//! - `heat_transfer`: the gas temperature is a state, relaxing to the wall with this time
//!   constant; the compressor delivers at the input temperature. Off (the base model, SPEC §2
//!   chamber equation at constant T): every flow is at [`TEMPERATURE_K`].
//! - `sensor_lag`, `sensor_offset`, `sensor_gain`: the transducer.
//! - `laminar_leak`: an extra leak ∝ gauge pressure, this many g/s at 7 bar g.
//!
//! # The wall node ([`WallNode`], reservoir only)
//!
//! With `heat_transfer` on, the gas exchanges heat with a wall at the ambient temperature: one
//! thermal node. A steel reservoir's wall and the pipework near the inlet hold heat, though: the
//! gas warms them while the compressor delivers hot air, and after unloading the gas cools
//! first to the warmed wall (τ of `heat_transfer`), then with the wall over minutes. The wall
//! node is that second state: θ_w relaxes toward the gas with the gas-to-wall heat-capacity
//! ratio ε (at [`WALL_REF_BAR`], scaled with the gas mass) and cools to ambient with its own
//! time constant,
//!
//! dθ_w/dt = ε (m/m_ref) (θ − θ_w)/τ − (θ_w − 1)/τ_w,
//!
//! and the gas's heat term pulls θ toward θ_w instead of 1: the extra heat p (θ_w − 1)/(θ τ) per
//! second enters the chamber as an energy increment, so the twin's [`chamber_substep`] is
//! unchanged (and the brake twin's bits with it). Off (ε = 0) the model is bit for bit the
//! one-node one.
//!
//! `regulator_droop`, `progressive_spring` and `gas_temperature` have no counterpart (no
//! regulator, no piston, the delivery temperature is an input): [`ReservoirParams::validate`]
//! rejects them.

use crate::fixed::Q;
use crate::mechanism::{Extensions, Mechanism::*};
use crate::params::{choked_orifice_gain, within, ParamError, GAS_CONSTANT, KAPPA, TEMPERATURE_K};
use crate::twin::{
    chamber_substep, heat_rate, isqrt, laminar_gain, vent_increments, LineCoeffs, SensorCoeffs, ValveLine,
    LAMINAR_SLOPE,
};
use crate::units::{KelvinQ8, Meters, PressureQ24};

/// Length of one [`Reservoir::update`], s.
pub const RESERVOIR_SUBSTEP_S: f64 = 0.5;

/// Wall (reference) temperature in kelvin.
const WALL_KELVIN: Q<i64, 8> = Q(75_046); // round(293.15 · 256)

/// Largest compressor pressure increment per substep, bar.
const MAX_STEP_BAR: f64 = 0.25;
/// Largest laminar leak gain per substep, per bar g.
const MAX_LAMINAR_GAIN: f64 = 2e-3;
/// Delivery temperatures are clamped to 1..=600 K.
const MAX_DELIVERY: Q<i64, 8> = Q(600 << 8);

/// θ_w = 1 (the wall at ambient) in the wall state's Q40.
const WALL_ONE: Q<i64, 40> = Q(1 << 40);

/// Pressure (bar abs) at which [`WallNode::capacity_ratio`] is given: ≈ 10 bar g, the top of
/// a compressor cycle. The gas's heat capacity scales with its mass, p/θ.
pub const WALL_REF_BAR: f64 = 11.0;

/// The reservoir wall as a second thermal node (module documentation). Needs `heat_transfer`
/// (its τ couples gas and wall).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallNode {
    /// Heat capacity of the gas at [`WALL_REF_BAR`] and the ambient temperature over the wall's
    /// (ε); 0 switches the node off (the wall stays at the ambient temperature).
    pub capacity_ratio: f64,
    /// Time constant of the wall's cooling to ambient, s.
    pub cooling_s: f64,
}

impl WallNode {
    /// No wall node: the one-node thermal model.
    pub const OFF: WallNode = WallNode { capacity_ratio: 0.0, cooling_s: 0.0 };

    /// Valid range of ε.
    pub const CAPACITY_RATIO: (f64, f64) = (0.0, 5.0);
    /// Valid range of τ_w, s.
    pub const COOLING_S: (f64, f64) = (10.0, 1e6);

    /// Whether the node is on.
    pub fn is_on(&self) -> bool {
        self.capacity_ratio != 0.0
    }
}

/// Physical parameters of the reservoir model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReservoirParams {
    /// Reservoir volume, m³. Only flows per volume are observable from a pressure record, so a
    /// fit fixes it and reports the flows at this volume.
    pub volume_m3: f64,
    /// Compressor delivery while loaded, g/s.
    pub compressor_g_per_s: f64,
    /// Equivalent orifice of consumption and leakage to atmosphere (diameter).
    pub outlet: Meters,
    /// Discharge coefficient of the outlet orifice.
    pub discharge_coeff: f64,
    /// Optional mechanisms (see the module documentation for the supported ones).
    pub ext: Extensions,
    /// The wall as a second thermal node ([`WallNode::OFF`]: none).
    pub wall: WallNode,
}

impl ReservoirParams {
    /// Checks ranges and that only supported mechanisms are on.
    pub fn validate(&self) -> Result<(), ParamError> {
        let checks: [(f64, f64, f64); 4] = [
            (self.volume_m3, 0.01, 10.0),
            (self.compressor_g_per_s, 0.0, 200.0),
            (self.outlet.0, 0.0, 20e-3),
            (self.discharge_coeff, 0.05, 1.0),
        ];
        within(&checks, ParamError::Reservoir)?;
        // The mechanisms' ranges at this model's time scale (the brake twin's are for a 60 s
        // release); the laminar leak is also bounded through its gain in [`ReservoirCoeffs::new`].
        self.ext.validate_in(|d| d.reservoir)?;
        if self.wall.is_on() {
            let w = self.wall;
            within(
                &[
                    (w.capacity_ratio, WallNode::CAPACITY_RATIO.0, WallNode::CAPACITY_RATIO.1),
                    (w.cooling_s, WallNode::COOLING_S.0, WallNode::COOLING_S.1),
                ],
                ParamError::Reservoir,
            )?;
            // The node exchanges heat with the gas through the heat transfer's τ.
            if self.ext[HeatTransfer] <= 0.0 {
                return Err(ParamError::Reservoir);
            }
        }
        Ok(())
    }
}

/// Integer coefficients of the reservoir model, per [`RESERVOIR_SUBSTEP_S`].
///
/// | field | format | meaning |
/// |---|---|---|
/// | `inflow` | Q40 | compressor pressure increment per substep at the wall temperature, bar |
/// | `c_vent` | Q32 | outlet orifice: choked increment per substep per bar upstream |
/// | `laminar` | Q40 | laminar leak increment per substep per bar g |
/// | `line` | [`LineCoeffs`] | delay (loading only) and lag of the compressor flow |
/// | `heat_rate` | Q30 | h/τ of the wall heat transfer (0 = adiabatic base) |
/// | `wall_gain` | Q30 | ε h /(τ p_ref): the wall's warming per substep per bar of p/θ and unit θ − θ_w |
/// | `wall_cooling` | Q30 | h/τ_w: the wall's cooling to ambient per substep (0 = no wall node) |
/// | `sensor` | [`SensorCoeffs`] | transducer |
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReservoirCoeffs {
    inflow: Q<i64, 40>,
    c_vent: Q<i64, 32>,
    laminar: Q<i64, 40>,
    line: LineCoeffs,
    heat_rate: Q<i64, 30>,
    wall_gain: Q<i64, 30>,
    wall_cooling: Q<i64, 30>,
    sensor: SensorCoeffs,
}

impl ReservoirCoeffs {
    /// Derives the integer coefficients (init time, `f64`).
    pub fn new(p: &ReservoirParams) -> Result<Self, ParamError> {
        p.validate()?;
        let h = RESERVOIR_SUBSTEP_S;
        let e = &p.ext;
        // Same orifice gain as the twin's, per substep.
        let c_vent = vent_rate_per_s(p) * h;
        let inflow = fill_rate_bar_per_s(p) * h;
        let laminar = laminar_gain(e[LaminarLeak], TEMPERATURE_K, p.volume_m3, h);
        // Explicit steps must stay small (accuracy and monotonicity: the vent step is monotone
        // down to atmosphere while `c_vent · LAMINAR_SLOPE < 1`, kept with a factor of two), which
        // also bounds every product of the substep inside i64.
        if c_vent * LAMINAR_SLOPE >= 0.5 || inflow > MAX_STEP_BAR || laminar > MAX_LAMINAR_GAIN {
            return Err(ParamError::Reservoir);
        }
        Ok(Self {
            inflow: Q::from_f64(inflow),
            c_vent: Q::from_f64(c_vent),
            laminar: Q::from_f64(laminar),
            line: LineCoeffs::new(e[TransportDelay], e[ValveLag], h),
            heat_rate: heat_rate(e[HeatTransfer], h),
            wall_gain: if p.wall.is_on() {
                Q::from_f64(p.wall.capacity_ratio * h / (e[HeatTransfer] * WALL_REF_BAR)).max(Q(1))
            } else {
                Q::ZERO
            },
            wall_cooling: if p.wall.is_on() { heat_rate(p.wall.cooling_s, h) } else { Q::ZERO },
            sensor: SensorCoeffs::new(e[SensorLag], e[SensorOffset], e[SensorGain], h),
        })
    }
}

/// The reservoir model: coefficients plus state (pressure, gas temperature, compressor line,
/// transducer), advanced [`RESERVOIR_SUBSTEP_S`] per [`Reservoir::update`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reservoir {
    coeffs: ReservoirCoeffs,
    /// Reservoir pressure, bar abs.
    p: PressureQ24,
    /// Gas temperature over the ambient (reference) temperature.
    theta: Q<i64, 24>,
    /// Wall temperature over the ambient temperature (1 without a wall node), in Q40: its
    /// increments per substep are ~10⁻⁵, and Q24 would round each by up to 0.6 %.
    wall: Q<i64, 40>,
    line: ValveLine,
    /// Transducer state (lagged pressure), bar abs.
    sensed: Q<i64, 24>,
}

impl Reservoir {
    /// A reservoir at atmosphere, compressor unloaded for long, gas and wall at ambient.
    pub fn new(params: &ReservoirParams) -> Result<Self, ParamError> {
        let coeffs = ReservoirCoeffs::new(params)?;
        let one = PressureQ24::ATMOSPHERE;
        Ok(Self { coeffs, p: one, theta: Q::ONE, wall: WALL_ONE, line: ValveLine::CLOSED, sensed: one.q() })
    }

    /// Restarts from a transducer reading (bar abs): the pressure and the transducer state move
    /// together until the transducer reads `reading`, keeping the lag between them (a fresh
    /// model's transducer is settled). `settle`: also put the gas at the wall temperature and
    /// the compressor line at rest (unloaded), as after a long pause; otherwise both keep their
    /// state (a correction in the middle of a cycle). The wall node keeps its temperature either
    /// way: it is the slow state that carries from one cycle to the next.
    pub fn restart(&mut self, reading: PressureQ24, settle: bool) {
        let target = self.coeffs.sensor.pressure_for_reading(reading).q();
        let now = self.coeffs.sensor.pressure_for_reading(self.reading()).q();
        let shift = target - now;
        self.p = PressureQ24::from_q(self.p.q() + shift).max(PressureQ24(0));
        self.sensed += shift;
        if settle {
            self.theta = self.wall.rescale();
            self.line = ValveLine::CLOSED;
        }
    }

    /// Reservoir pressure (not what the transducer reads), bar abs.
    pub fn pressure(&self) -> PressureQ24 {
        self.p
    }

    /// What the transducer reads now (bar abs).
    pub fn reading(&self) -> PressureQ24 {
        self.coeffs.sensor.read(self.sensed)
    }

    /// Gas temperature over the ambient temperature (1 on the adiabatic base).
    pub fn theta(&self) -> Q<i64, 24> {
        self.theta
    }

    /// Wall temperature over the ambient temperature (1 without a wall node).
    pub fn wall_theta(&self) -> Q<i64, 24> {
        self.wall.rescale()
    }

    /// Puts the wall node at `theta` (over the ambient temperature), e.g. at the temperature it
    /// reaches while the compressor cycles; the gas and everything else keep their state. No
    /// effect without a wall node.
    pub fn set_wall_theta(&mut self, theta: Q<i64, 24>) {
        if self.has_wall_node() {
            self.wall = theta.clamp(Q(1 << 22), Q(1 << 26)).rescale();
        }
    }

    /// Whether the model has a wall node: a state that outlives a compressor cycle, so a run
    /// that starts in the middle of cycling must first bring it to its cycling temperature.
    pub fn has_wall_node(&self) -> bool {
        self.coeffs.wall_cooling != Q::ZERO
    }

    /// Advances one substep with the compressor `loaded` (as commanded) delivering air at
    /// `delivery`; returns what the transducer reads (bar abs).
    pub fn update(&mut self, loaded: bool, delivery: KelvinQ8) -> PressureQ24 {
        let c = &self.coeffs;
        self.line.command(loaded);
        // The check valve opens only once the compressor outlet has climbed to reservoir
        // pressure: the delay applies to loading; unloading stops the delivery at once.
        let delay = if self.line.command { c.line.delay() } else { Q::ZERO };
        let paths = self.line.substep(&c.line, delay);
        let p = self.p;
        let thermal = c.heat_rate != Q::ZERO;
        let theta = self.theta.max(Q(1));
        let sqrt_theta = if thermal { isqrt(theta) } else { Q::ONE };
        let mut mass = Q::<i64, 40>::ZERO;
        for path in paths {
            if path.open {
                mass += c.inflow.mul_floor(path.share.rescale::<16>());
            }
        }
        // Delivered enthalpy: the mass increment at the delivery temperature (θ_d = T_d/T_wall).
        let mut energy = if thermal {
            let delivery = Q::<i64, 8>(i64::from(delivery.0)).clamp(Q(1 << 8), MAX_DELIVERY);
            let theta_d: Q<i64, 16> = delivery.div_trunc(WALL_KELVIN);
            mass.mul_floor(theta_d)
        } else {
            mass
        };
        let (vent_energy, vent_mass) = vent_increments(p, c.c_vent, c.laminar, theta, sqrt_theta, thermal);
        energy -= vent_energy;
        mass -= vent_mass;
        let wall_on = c.wall_cooling != Q::ZERO;
        let wall: Q<i64, 24> = self.wall.rescale();
        if wall_on {
            // The chamber's heat term pulls θ toward 1; a warm wall adds p (θ_w − 1)/θ · h/τ,
            // formed in Q40 (products in i128: p and θ_w − 1 are bounded only by the clamps).
            let excess: Q<i64, 24> = (wall - Q::ONE).div_trunc(theta);
            let per_bar: Q<i64, 40> = excess.mul_round(c.heat_rate);
            energy += p.q().wide_mul_floor::<40, 40>(per_bar);
        }
        let (p_new, theta_new) = chamber_substep(p, theta, energy, mass, Q::ONE, Q::ZERO, c.heat_rate);
        if wall_on {
            // dθ_w = ε h/(τ p_ref) · (p/θ) · (θ − θ_w) − h/τ_w · (θ_w − 1), from this substep's
            // start (explicit, like the chamber).
            let mass_rel: Q<i64, 24> = p.q().div_trunc(theta);
            let drive: Q<i64, 40> = mass_rel.mul_round::<24, 40>(theta - wall);
            let warming: Q<i64, 40> = drive.wide_mul_floor(c.wall_gain);
            let cooling: Q<i64, 40> = (self.wall - WALL_ONE).wide_mul_floor(c.wall_cooling);
            self.wall = (self.wall + warming - cooling).clamp(Q(1 << 38), Q(1 << 42));
        }
        if c.sensor.lags() {
            self.sensed = c.sensor.lag_substep(self.sensed, p.q(), p_new.q());
        } else {
            self.sensed = p_new.q();
        }
        self.p = p_new;
        self.theta = theta_new;
        c.sensor.read(self.sensed)
    }
}

/// Pressure rate (bar/s) of a choked outlet orifice per bar abs, at the wall temperature: the
/// decay rate λ of dp/dt = −λ p for the given outlet (for reports).
pub fn vent_rate_per_s(p: &ReservoirParams) -> f64 {
    choked_orifice_gain(p.discharge_coeff, p.outlet) / p.volume_m3
}

/// Pressure rate (bar/s) of the compressor's delivery at the wall temperature (for reports).
pub fn fill_rate_bar_per_s(p: &ReservoirParams) -> f64 {
    KAPPA * GAS_CONSTANT * TEMPERATURE_K * p.compressor_g_per_s * 1e-3 / p.volume_m3 / 1e5
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> ReservoirParams {
        ReservoirParams {
            volume_m3: 0.5,
            compressor_g_per_s: 10.0,
            outlet: Meters::from_mm(0.5),
            discharge_coeff: 0.8,
            ext: Extensions::NONE,
            wall: WallNode::OFF,
        }
    }

    fn bar(q: PressureQ24) -> f64 {
        f64::from(q.0) / f64::from(PressureQ24::ONE_BAR)
    }

    #[test]
    fn base_fill_and_decay_follow_the_rates() {
        let p = params();
        let mut r = Reservoir::new(&p).unwrap();
        r.restart(PressureQ24::from_bar_g(crate::BarG(8.0)), true);
        let t_oil = KelvinQ8::from_celsius(60.0);
        // 60 s loaded: dp/dt = fill − λ p.
        let p0 = bar(r.pressure());
        for _ in 0..120 {
            r.update(true, t_oil);
        }
        let (fill, lam) = (fill_rate_bar_per_s(&p), vent_rate_per_s(&p));
        let expect = fill / lam + (p0 - fill / lam) * libm::exp(-lam * 60.0);
        assert!((bar(r.pressure()) - expect).abs() < 1e-4, "{} vs {expect}", bar(r.pressure()));
        // The adiabatic base ignores the delivery temperature.
        let mut hot = Reservoir::new(&p).unwrap();
        hot.restart(PressureQ24::from_bar_g(crate::BarG(8.0)), true);
        for _ in 0..120 {
            hot.update(true, KelvinQ8::from_celsius(90.0));
        }
        assert_eq!(hot.pressure(), r.pressure());
        // 10 min unloaded: p = p1 e^(−λ t).
        let p1 = bar(r.pressure());
        for _ in 0..1200 {
            r.update(false, t_oil);
        }
        let expect = p1 * libm::exp(-lam * 600.0);
        assert!((bar(r.pressure()) - expect).abs() < 1e-4, "{} vs {expect}", bar(r.pressure()));
    }

    #[test]
    fn heat_transfer_settles_hot_delivery_back_to_the_wall() {
        let mut p = params();
        p.ext[HeatTransfer] = 20.0;
        let mut r = Reservoir::new(&p).unwrap();
        r.restart(PressureQ24::from_bar_g(crate::BarG(8.0)), true);
        let hot = KelvinQ8::from_celsius(80.0);
        for _ in 0..180 {
            r.update(true, hot);
        }
        assert!(r.theta() > Q::ONE, "hot delivery warms the gas");
        let p_unload = bar(r.pressure());
        // Right after unloading the pressure falls faster than the vent alone: the gas cools.
        for _ in 0..240 {
            r.update(false, hot);
        }
        let lam = vent_rate_per_s(&p);
        let vent_only = p_unload * libm::exp(-lam * 120.0);
        assert!(bar(r.pressure()) < vent_only - 0.01, "{} vs {vent_only}", bar(r.pressure()));
        let theta = r.theta().to_f64();
        assert!((theta - 1.0).abs() < 0.01, "θ {theta} back at the wall after 6 τ");
    }

    #[test]
    fn a_wall_node_stores_the_heat_and_gives_it_back_slowly() {
        let mut one = params();
        one.ext[HeatTransfer] = 40.0;
        let mut two = one;
        two.wall = WallNode { capacity_ratio: 0.5, cooling_s: 3000.0 };
        let (mut a, mut b) = (Reservoir::new(&one).unwrap(), Reservoir::new(&two).unwrap());
        assert!(!a.has_wall_node() && b.has_wall_node());
        let start = PressureQ24::from_bar_g(crate::BarG(8.0));
        a.restart(start, true);
        b.restart(start, true);
        let hot = KelvinQ8::from_celsius(80.0);
        for _ in 0..180 {
            a.update(true, hot);
            b.update(true, hot);
        }
        // The gas warmed the wall, which now sits between ambient and the gas.
        assert!(b.wall_theta() > Q::ONE && b.wall_theta() < b.theta(), "{:?} {:?}", b.wall_theta(), b.theta());
        assert_eq!(a.wall_theta(), Q::ONE);
        // Five minutes after unloading the one-node gas is back at ambient; with the wall node
        // it is still warm, so the pressure is higher, and it keeps falling for longer.
        for _ in 0..600 {
            a.update(false, hot);
            b.update(false, hot);
        }
        assert!((a.theta().to_f64() - 1.0).abs() < 0.002, "{}", a.theta().to_f64());
        assert!(b.theta().to_f64() > 1.003, "{}", b.theta().to_f64());
        assert!(bar(b.pressure()) > bar(a.pressure()) + 0.02);
        let wall_then = b.wall_theta();
        for _ in 0..1200 {
            b.update(false, hot);
        }
        assert!(b.wall_theta() < wall_then, "the wall cools to ambient");
        // Settling puts the gas at the wall, not at ambient; the wall keeps its temperature.
        let wall = b.wall_theta();
        b.restart(start, true);
        assert_eq!((b.theta(), b.wall_theta()), (wall, wall));
        b.set_wall_theta(Q::ONE);
        assert_eq!(b.wall_theta(), Q::ONE);
    }

    #[test]
    fn a_wall_node_needs_heat_transfer_and_its_ranges() {
        let mut p = params();
        p.wall = WallNode { capacity_ratio: 0.5, cooling_s: 3000.0 };
        assert_eq!(Reservoir::new(&p), Err(ParamError::Reservoir), "no heat transfer to couple it");
        p.ext[HeatTransfer] = 40.0;
        assert!(Reservoir::new(&p).is_ok());
        p.wall.cooling_s = 1.0;
        assert_eq!(Reservoir::new(&p), Err(ParamError::Reservoir));
        p.wall = WallNode { capacity_ratio: f64::NAN, cooling_s: 3000.0 };
        assert_eq!(Reservoir::new(&p), Err(ParamError::Reservoir));
    }

    #[test]
    fn transport_delay_holds_back_loading_only() {
        let mut p = params();
        p.ext[TransportDelay] = 5.0;
        let mut r = Reservoir::new(&p).unwrap();
        let start = PressureQ24::from_bar_g(crate::BarG(8.0));
        r.restart(start, true);
        let t = KelvinQ8::from_celsius(60.0);
        for _ in 0..10 {
            r.update(true, t);
        }
        // 5 s of delay: only the vent acted.
        assert!(r.pressure() < start);
        r.update(true, t);
        assert!(r.pressure() > start);
        // Unloading acts at once.
        let before = r.pressure();
        r.update(false, t);
        assert!(r.pressure() < before);
    }

    #[test]
    fn sensor_terms_and_restart_invert_each_other() {
        let mut p = params();
        p.ext[SensorOffset] = -0.05;
        p.ext[SensorGain] = 1.03;
        p.ext[SensorLag] = 4.0;
        let mut r = Reservoir::new(&p).unwrap();
        let reading = PressureQ24::from_bar_g(crate::BarG(9.2));
        r.restart(reading, true);
        // 9.2 = −0.05 + 1.03 · gauge.
        assert!((bar(r.pressure()) - 1.0 - 9.25 / 1.03).abs() < 1e-6);
        let first = r.update(false, KelvinQ8::from_celsius(50.0));
        assert!((first.0 - reading.0).abs() < 1 << 12, "settled transducer reads its restart value");
        // While the transducer lags, a restart moves both and keeps the lag.
        for _ in 0..20 {
            r.update(true, KelvinQ8::from_celsius(50.0));
        }
        let lag = r.pressure().q() - r.sensed;
        assert!(lag > Q(1 << 16), "the transducer lags the rise");
        let target = PressureQ24(r.reading().0 + (1 << 20));
        r.restart(target, false);
        assert!((r.reading().0 - target.0).abs() <= 2);
        assert_eq!(r.pressure().q() - r.sensed, lag);
    }

    #[test]
    fn unsupported_or_unstable_parameters_are_rejected() {
        let mut p = params();
        p.ext[ProgressiveSpring] = 0.2;
        assert_eq!(Reservoir::new(&p), Err(ParamError::Unsupported(ProgressiveSpring)));
        let mut p = params();
        p.outlet = Meters::from_mm(19.0);
        assert_eq!(Reservoir::new(&p), Err(ParamError::Reservoir));
        let mut p = params();
        p.volume_m3 = f64::NAN;
        assert_eq!(Reservoir::new(&p), Err(ParamError::Reservoir));
    }

    #[test]
    fn saturates_instead_of_overflowing() {
        // The largest accepted delivery and leaks, hot gas, driven far past the sensor range.
        let mut p = params();
        p.volume_m3 = 0.1;
        p.compressor_g_per_s = 42.0;
        p.outlet = Meters::from_mm(1.0);
        p.ext[LaminarLeak] = 1.1;
        p.ext[HeatTransfer] = 5.0;
        p.wall = WallNode { capacity_ratio: WallNode::CAPACITY_RATIO.1, cooling_s: WallNode::COOLING_S.0 };
        let mut r = Reservoir::new(&p).unwrap();
        for delivery in [KelvinQ8(i32::MAX), KelvinQ8(i32::MIN), KelvinQ8(0)] {
            for _ in 0..20_000 {
                let read = r.update(true, delivery);
                assert!(read.0 > 0);
            }
            for _ in 0..2000 {
                r.update(false, delivery);
            }
        }
        let mut p = params();
        p.compressor_g_per_s = 50.0;
        p.volume_m3 = 0.1;
        assert_eq!(Reservoir::new(&p), Err(ParamError::Reservoir), "0.29 bar per substep");
    }
}
