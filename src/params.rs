//! Physical parameters of the parking brake (SPEC §3) and the physical constants of SPEC §2.

use crate::mechanism::{Extensions, Mechanism, MechanismError};
use crate::units::{BarG, Meters};

/// Specific heat ratio of air.
pub const KAPPA: f64 = 1.4;
/// Specific gas constant of air, J/(kg K). (The paper's 288 is a typo: its C1, C2 use 287.)
pub const GAS_CONSTANT: f64 = 287.0;
/// Air temperature of the adiabatic model, K.
pub const TEMPERATURE_K: f64 = 293.15;
/// Critical pressure ratio: choked flow at or below it.
pub const CRITICAL_RATIO: f64 = 0.528;
/// Standard gravity is not used; forces come from pressure, spring and friction only.
/// Choked flow constant C1 = sqrt(k/R (2/(k+1))^((k+1)/(k-1))) ≈ 0.040418.
pub fn c1() -> f64 {
    libm::sqrt(KAPPA / GAS_CONSTANT * libm::pow(2.0 / (KAPPA + 1.0), (KAPPA + 1.0) / (KAPPA - 1.0)))
}
/// κ R √T0 Cf A C1: the choked pressure rate (bar/s per bar upstream) an orifice of diameter `d`
/// gives one m³ of gas at [`TEMPERATURE_K`] (divide by the volume; SPEC §2 flow and chamber).
pub fn choked_orifice_gain(discharge_coeff: f64, d: Meters) -> f64 {
    KAPPA * GAS_CONSTANT * libm::sqrt(TEMPERATURE_K) * discharge_coeff * circle_area(d) * c1()
}
/// Unchoked flow constant C2 = sqrt(2k/(R(k-1))) ≈ 0.156174.
pub fn c2() -> f64 {
    libm::sqrt(2.0 * KAPPA / (GAS_CONSTANT * (KAPPA - 1.0)))
}

/// Area of a circular orifice or bore of diameter `d`, m².
pub fn circle_area(d: Meters) -> f64 {
    core::f64::consts::PI * 0.25 * d.0 * d.0
}

/// Everything the twin needs to know about one brake and its release.
///
/// One lumped cylinder stands for the four spring-brake cylinders (SPEC §3). Defaults are the
/// SPEC's nominal values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwinParams {
    /// Supply (reducing-valve output) pressure.
    pub supply: BarG,
    /// Diameter of the calibrated release orifice.
    pub orifice: Meters,
    /// Diameter of an equivalent leak orifice to atmosphere (0 = tight).
    pub leak: Meters,
    /// Discharge coefficient Cf of both orifices.
    pub discharge_coeff: f64,
    /// Dead volume V0 at x = 0, m³.
    pub dead_volume_m3: f64,
    /// Total piston area A, m².
    pub piston_area_m2: f64,
    /// Stroke L to the end stop.
    pub stroke: Meters,
    /// Moving mass M, kg.
    pub mass_kg: f64,
    /// Spring preload F0 at x = 0, N.
    pub preload_n: f64,
    /// Spring rate K, N/m.
    pub spring_rate_n_per_m: f64,
    /// LuGre bristle stiffness sigma0, N/m.
    pub sigma0_n_per_m: f64,
    /// LuGre bristle damping sigma1, N s/m.
    pub sigma1_n_s_per_m: f64,
    /// Viscous friction B, N s/m.
    pub viscous_n_s_per_m: f64,
    /// Coulomb friction Fc, N.
    pub coulomb_n: f64,
    /// Static (breakaway) friction Fs, N.
    pub static_n: f64,
    /// Stribeck velocity vs, m/s.
    pub stribeck_m_per_s: f64,
    /// Mechanisms beyond SPEC §2 ([`crate::mechanism`]); [`Extensions::NONE`] for the base
    /// model of SPEC §2, which the twin then runs bit for bit unchanged.
    pub ext: Extensions,
}

/// `Ok` when every `(value, lo, hi)` has a value in `lo..=hi` (so not NaN), else `err`.
pub(crate) fn within(checks: &[(f64, f64, f64)], err: ParamError) -> Result<(), ParamError> {
    if checks.iter().all(|&(value, lo, hi)| value >= lo && value <= hi) {
        Ok(())
    } else {
        Err(err)
    }
}

impl TwinParams {
    /// Nominal supply pressure (reducing valve), bar g.
    pub const NOMINAL_SUPPLY_BAR_G: f64 = 7.7;
    /// Nominal release orifice diameter, mm.
    pub const NOMINAL_ORIFICE_MM: f64 = 1.25;

    /// The nominal healthy brake of SPEC §3.
    pub fn nominal() -> Self {
        let area = 4.0 * circle_area(Meters(0.1));
        let stroke = 0.060;
        let coulomb = 150.0;
        let preload = 4.0e5 * area;
        Self {
            supply: BarG(Self::NOMINAL_SUPPLY_BAR_G),
            orifice: Meters::from_mm(Self::NOMINAL_ORIFICE_MM),
            leak: Meters(0.0),
            discharge_coeff: 0.8,
            dead_volume_m3: 3.0e-3,
            piston_area_m2: area,
            stroke: Meters(stroke),
            mass_kg: 20.0,
            preload_n: preload,
            // End stop reached at 7.2 bar: 7.2 bar·A = F0 + Fc + K L.
            spring_rate_n_per_m: (7.2e5 * area - preload - coulomb) / stroke,
            sigma0_n_per_m: 1e5,
            sigma1_n_s_per_m: 2e3,
            viscous_n_s_per_m: 2e3,
            coulomb_n: coulomb,
            static_n: 300.0,
            stribeck_m_per_s: 0.01,
            ext: Extensions::NONE,
        }
    }

    /// Same brake with another orifice diameter (mm).
    pub fn with_orifice_mm(mut self, mm: f64) -> Self {
        self.orifice = Meters::from_mm(mm);
        self
    }
    /// Same brake with a leak of the given equivalent diameter (mm, 0 = none).
    pub fn with_leak_mm(mut self, mm: f64) -> Self {
        self.leak = Meters::from_mm(mm);
        self
    }
    /// Same brake on another supply pressure (bar g).
    pub fn with_supply_bar_g(mut self, bar: f64) -> Self {
        self.supply = BarG(bar);
        self
    }

    /// Checks that every parameter is finite and inside the range the fixed-point twin is
    /// scaled for (see `twin` for the Q formats).
    pub fn validate(&self) -> Result<(), ParamError> {
        let checks: [(f64, f64, f64, ParamError); 16] = [
            (self.supply.0, 0.0, 15.0, ParamError::Supply),
            (self.orifice.0, 0.0, 10e-3, ParamError::Orifice),
            (self.leak.0, 0.0, 5e-3, ParamError::Leak),
            (self.discharge_coeff, 0.05, 1.0, ParamError::DischargeCoeff),
            (self.dead_volume_m3, 0.2e-3, 50e-3, ParamError::Volume),
            (self.piston_area_m2, 1e-4, 0.1, ParamError::Area),
            (self.stroke.0, 1e-3, 0.4, ParamError::Stroke),
            (self.mass_kg, 0.5, 500.0, ParamError::Mass),
            (self.preload_n, 0.0, 60e3, ParamError::Spring),
            (self.spring_rate_n_per_m, 0.0, 4e6, ParamError::Spring),
            (self.sigma0_n_per_m, 1e3, 4e6, ParamError::Friction),
            (self.sigma1_n_s_per_m, 0.0, 1e5, ParamError::Friction),
            (self.viscous_n_s_per_m, 0.0, 1e5, ParamError::Friction),
            (self.coulomb_n, 1.0, 1e4, ParamError::Friction),
            (self.static_n, 1.0, 1e4, ParamError::Friction),
            (self.stribeck_m_per_s, 1e-4, 1.0, ParamError::Friction),
        ];
        for (value, lo, hi, err) in checks {
            if !(value >= lo && value <= hi) {
                return Err(err);
            }
        }
        if self.static_n < self.coulomb_n {
            return Err(ParamError::Friction);
        }
        self.ext.validate().map_err(ParamError::from)
    }
}

impl Default for TwinParams {
    fn default() -> Self {
        Self::nominal()
    }
}

/// A parameter outside the range the twin supports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamError {
    /// Supply pressure not in 0..=15 bar g.
    Supply,
    /// Release orifice not in 0..=10 mm.
    Orifice,
    /// Leak diameter not in 0..=5 mm.
    Leak,
    /// Discharge coefficient not in 0.05..=1.
    DischargeCoeff,
    /// Dead volume not in 0.2..=50 L.
    Volume,
    /// Piston area not in 1 cm²..=0.1 m².
    Area,
    /// Stroke not in 1..=400 mm.
    Stroke,
    /// Moving mass not in 0.5..=500 kg.
    Mass,
    /// Preload or spring rate out of range.
    Spring,
    /// A friction parameter out of range (or Fs < Fc).
    Friction,
    /// A mechanism's magnitude outside the range the model supports ([`crate::mechanism::Scope::valid`]).
    Extension(Mechanism),
    /// A mechanism the model does not have ([`crate::mechanism::Descriptor::reservoir`]).
    Unsupported(Mechanism),
    /// A reservoir model parameter out of range (see [`crate::reservoir::ReservoirParams`]).
    Reservoir,
}

impl core::fmt::Display for ParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let what = match *self {
            Self::Extension(m) => return MechanismError::OutOfRange(m).fmt(f),
            Self::Unsupported(m) => return MechanismError::Unsupported(m).fmt(f),
            Self::Supply => "supply pressure must be 0..=15 bar g",
            Self::Orifice => "orifice diameter must be 0..=10 mm",
            Self::Leak => "leak diameter must be 0..=5 mm",
            Self::DischargeCoeff => "discharge coefficient must be 0.05..=1",
            Self::Volume => "dead volume must be 0.2..=50 L",
            Self::Area => "piston area must be 1e-4..=0.1 m²",
            Self::Stroke => "stroke must be 1..=400 mm",
            Self::Mass => "moving mass must be 0.5..=500 kg",
            Self::Spring => "spring preload (0..=60 kN) or rate (0..=4e6 N/m) out of range",
            Self::Friction => "friction parameter out of range (or static < Coulomb)",
            Self::Reservoir => {
                "reservoir volume (0.01..=10 m³), compressor flow (0..=200 g/s), outlet orifice \
                 (0..=20 mm, stable at the 0.5 s step) or discharge coefficient (0.05..=1) out of range"
            }
        };
        f.write_str(what)
    }
}

impl From<MechanismError> for ParamError {
    fn from(e: MechanismError) -> Self {
        match e {
            MechanismError::OutOfRange(m) => Self::Extension(m),
            MechanismError::Unsupported(m) => Self::Unsupported(m),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for ParamError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gas_temperature_is_off_at_the_base_model_temperature() {
        assert_eq!(Mechanism::GasTemperature.descriptor().off, TEMPERATURE_K);
        assert!(!Extensions::NONE.is_on(Mechanism::GasTemperature));
    }
}
