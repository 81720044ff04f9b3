//! Unit newtypes used at every interface of the core.
//!
//! Inside the twin pressures are absolute; everything that crosses an interface (traces, CAN,
//! CLI) is gauge pressure in bar, as a brake engineer reads it off a gauge.
//!
//! The fixed-point types carry their format ([`Q`]): [`PressureQ24`] (bar absolute, Q7.24),
//! [`MetersQ32`] (lengths in metres, Q-1.32), [`KelvinQ8`].

use crate::fixed::Q;

/// Atmospheric pressure used by the model, in bar absolute (SPEC §2: P0 = 1.000e5 Pa).
pub const ATMOSPHERE_BAR_ABS: f64 = 1.0;

/// Gauge pressure in bar (bar g): 0 at atmosphere.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct BarG(pub f64);

impl BarG {
    /// Absolute pressure in bar.
    pub fn to_abs_bar(self) -> f64 {
        self.0 + ATMOSPHERE_BAR_ABS
    }
    /// Absolute pressure in pascal.
    pub fn to_abs_pa(self) -> f64 {
        self.to_abs_bar() * 1e5
    }
}

/// Time in seconds.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Seconds(pub f64);

/// Raw 12-bit ADC reading of the chamber pressure transducer (0..=4095 when valid).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct AdcCounts(pub u16);

/// Length in metres (orifice diameters, piston travel).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Meters(pub f64);

impl Meters {
    /// From millimetres.
    pub fn from_mm(mm: f64) -> Self {
        Self(mm * 1e-3)
    }
    /// In millimetres.
    pub fn mm(self) -> f64 {
        self.0 * 1e3
    }
}

/// Pressure in bar **absolute**, Q7.24 fixed point in an `i32` (1 LSB = 2^-24 bar ≈ 6e-3 Pa,
/// range ±128 bar). This is the twin's internal pressure representation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct PressureQ24(pub i32);

impl PressureQ24 {
    /// Number of fractional bits.
    pub const FRAC_BITS: u32 = 24;
    /// One bar.
    pub const ONE_BAR: i32 = 1 << 24;
    /// Atmospheric pressure (1.000 bar abs).
    pub const ATMOSPHERE: Self = Self(Self::ONE_BAR);

    /// From a gauge pressure (host/init-time conversion; saturates to the Q7.24 range).
    pub fn from_bar_g(p: BarG) -> Self {
        let q = libm::round(p.to_abs_bar() * f64::from(Self::ONE_BAR));
        // `as` saturates out-of-range floats and maps NaN to 0.
        Self(q as i32)
    }
    /// To gauge pressure (for reports and traces).
    pub fn to_bar_g(self) -> BarG {
        BarG(f64::from(self.0) / f64::from(Self::ONE_BAR) - ATMOSPHERE_BAR_ABS)
    }
    /// The pressure as a Q24 number in an `i64`, for fixed-point arithmetic.
    #[inline(always)]
    pub const fn q(self) -> Q<i64, 24> {
        Q(self.0 as i64)
    }
    /// From a Q24 number (bar abs), saturating to the `i32` range.
    #[inline(always)]
    pub const fn from_q(p: Q<i64, 24>) -> Self {
        Self(p.saturate().0)
    }
}

/// Length in metres, Q-1.32 fixed point in an `i32` (1 LSB = 2^-32 m ≈ 2.3e-10 m, range
/// ±0.5 m): the twin's piston travel, stroke and bristle deflection. In this crate a
/// `Q<i32, 32>` is always a length in metres, so the conversions are methods of the format;
/// [`MetersQ32::to_m`] is the one Q32 → metres conversion of the project.
pub type MetersQ32 = Q<i32, 32>;

impl Q<i32, 32> {
    /// From a length (host/init-time conversion; rounds, saturates to ±0.5 m, NaN gives 0).
    pub fn from_m(length: Meters) -> Self {
        Self::from_f64(length.0)
    }
    /// In metres (for reports and traces).
    pub fn to_m(self) -> Meters {
        Meters(self.to_f64())
    }
    /// In millimetres (for reports and traces).
    pub fn to_mm(self) -> f64 {
        self.to_m().mm()
    }
}

/// Absolute temperature in kelvin, Q23.8 fixed point in an `i32` (1 LSB = 1/256 K).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct KelvinQ8(pub i32);

impl KelvinQ8 {
    /// Number of fractional bits.
    pub const FRAC_BITS: u32 = 8;

    /// From a temperature in °C (host/init-time conversion; saturates, NaN gives 0 K).
    pub fn from_celsius(c: f64) -> Self {
        let q = libm::round((c + 273.15) * 256.0);
        Self(q as i32)
    }
    /// In kelvin (for reports).
    pub fn kelvin(self) -> f64 {
        f64::from(self.0) / 256.0
    }
}
