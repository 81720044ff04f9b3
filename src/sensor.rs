//! The chamber pressure transducer and its 12-bit ADC (SPEC §5).
//!
//! 0–10 bar g ratiometric transducer, 0.5–4.5 V, into a 12-bit ADC referenced to 5 V:
//! `counts = round(4095 · (0.1 + 0.08 · p))`. Readings below 0.25 V or above 4.75 V equivalent
//! are an open or shorted sensor, never a brake fault.

use crate::units::{AdcCounts, BarG, PressureQ24};

/// Full-scale ADC code.
pub const ADC_FULL_SCALE: u16 = 4095;
/// Lowest valid code: 0.25 V of 5 V (204.75 counts) rounds up to 205.
pub const ADC_MIN_VALID: u16 = 205;
/// Highest valid code: 4.75 V of 5 V (3890.25 counts) rounds down to 3890.
pub const ADC_MAX_VALID: u16 = 3890;
/// Counts per bar: 4095 · 0.08.
pub const COUNTS_PER_BAR: f64 = 4095.0 * 0.08;
/// Counts at 0 bar g: 4095 · 0.1.
pub const COUNTS_AT_ZERO: f64 = 4095.0 * 0.1;

/// Why the pressure signal cannot be trusted: an ADC reading outside the transducer's range, or
/// a signal whose statistics no working transducer on this pneumatic circuit can produce (see
/// [`crate::plausibility`]). Never a brake fault.
///
/// [`Self::code`] is the number sent on CAN (`SensorHealth` of `BPM_Status` and
/// `NoDiagnosisReason` of `BPM_FaultReport` share it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SensorFault {
    /// Below 0.25 V equivalent: open circuit or broken supply.
    OpenCircuit,
    /// Above 4.75 V equivalent: short to supply.
    ShortCircuit,
    /// The reading repeats one code far longer than the transducer's noise allows after it had
    /// shown a live signal: a frozen amplifier, ADC or driver buffer.
    Frozen,
    /// The reading is one constant code from the release command on: a dead channel.
    Dead,
    /// Sample-to-sample noise far above the transducer's (loose contact, EMI, failing supply).
    Noisy,
    /// Isolated outliers far from both neighbours (EMI spikes, bit errors).
    Spikes,
    /// Brief losses of the reading (out-of-range samples inside a valid signal).
    Dropouts,
    /// Low-order ADC codes never occur: the converter lost resolution (stuck low bits).
    LostResolution,
    /// The reading piles up at one level that is not a physical rail (amplifier clipping or
    /// saturation).
    Clipped,
    /// A jump faster than the chamber's pneumatics can produce.
    ImpossibleRate,
    /// A level the circuit cannot reach: not at atmosphere at the release command (zero offset)
    /// or above every regulator setting (gain error).
    ImplausibleLevel,
}

impl SensorFault {
    /// Every kind, in code order.
    pub const ALL: [Self; 11] = [
        Self::OpenCircuit,
        Self::ShortCircuit,
        Self::Frozen,
        Self::Dead,
        Self::Noisy,
        Self::Spikes,
        Self::Dropouts,
        Self::LostResolution,
        Self::Clipped,
        Self::ImpossibleRate,
        Self::ImplausibleLevel,
    ];

    /// CAN code (1..=2 and 5..=13; 0 is "ok", 3 and 4 are the fault report's other reasons).
    pub const fn code(self) -> u8 {
        match self {
            Self::OpenCircuit => 1,
            Self::ShortCircuit => 2,
            Self::Frozen => 5,
            Self::Dead => 6,
            Self::Noisy => 7,
            Self::Spikes => 8,
            Self::Dropouts => 9,
            Self::LostResolution => 10,
            Self::Clipped => 11,
            Self::ImpossibleRate => 12,
            Self::ImplausibleLevel => 13,
        }
    }

    /// The kind with CAN code `code`.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.code() == code)
    }

    /// Stable snake_case label (CAN value tables, files, `host-sim generate --sensor-fault`).
    pub const fn label(self) -> &'static str {
        match self {
            Self::OpenCircuit => "open_circuit",
            Self::ShortCircuit => "short_circuit",
            Self::Frozen => "frozen",
            Self::Dead => "dead",
            Self::Noisy => "noisy",
            Self::Spikes => "spikes",
            Self::Dropouts => "dropouts",
            Self::LostResolution => "lost_resolution",
            Self::Clipped => "clipped",
            Self::ImpossibleRate => "impossible_rate",
            Self::ImplausibleLevel => "implausible_level",
        }
    }
}

impl core::fmt::Display for SensorFault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::OpenCircuit => "open circuit: ADC below 0.25 V",
            Self::ShortCircuit => "short circuit: ADC above 4.75 V",
            Self::Frozen => "frozen: the reading repeats exactly",
            Self::Dead => "dead: constant reading since the release command",
            Self::Noisy => "noisy: noise far above the transducer's",
            Self::Spikes => "spikes: samples far from both neighbours",
            Self::Dropouts => "dropouts: the reading is lost and comes back",
            Self::LostResolution => "lost resolution: an ADC bit never changes",
            Self::Clipped => "clipped: the reading piles up below its range",
            Self::ImpossibleRate => "impossible rate: faster than the pneumatics allow",
            Self::ImplausibleLevel => "implausible level: offset or gain error",
        })
    }
}

#[cfg(feature = "std")]
impl std::error::Error for SensorFault {}

/// Ideal ADC code for a gauge pressure, without noise (host-side sensor model).
pub fn adc_from_bar(p: BarG) -> AdcCounts {
    let c = libm::round(ADC_FULL_SCALE as f64 * (0.1 + 0.08 * p.0));
    AdcCounts(if c.is_nan() { 0 } else { c.clamp(0.0, ADC_FULL_SCALE as f64) as u16 })
}

/// Gauge pressure of an ADC code as a float (for reports; the monitor uses [`pressure_from_adc`]).
pub fn bar_from_adc(c: AdcCounts) -> BarG {
    BarG((f64::from(c.0) - COUNTS_AT_ZERO) / COUNTS_PER_BAR)
}

/// Multiplier turning half-counts above 409.5 into Q24 bar after a 17-bit shift.
const BAR_Q24_PER_HALF_COUNT_Q17: i64 = 3_356_262_600; // round(2^40 / 327.6)

/// Converts an ADC reading to absolute chamber pressure (Q7.24 bar), integer only.
///
/// Codes outside `ADC_MIN_VALID..=ADC_MAX_VALID` (including anything above 12 bits) are a
/// sensor fault.
pub fn pressure_from_adc(c: AdcCounts) -> Result<PressureQ24, SensorFault> {
    if c.0 < ADC_MIN_VALID {
        return Err(SensorFault::OpenCircuit);
    }
    if c.0 > ADC_MAX_VALID {
        return Err(SensorFault::ShortCircuit);
    }
    // (2 counts − 819) / 2 = counts − 409.5, kept in half-counts to stay integer.
    let half_counts = 2 * i64::from(c.0) - 819;
    let gauge_q24 = (half_counts * BAR_Q24_PER_HALF_COUNT_Q17) >> 17;
    Ok(PressureQ24((gauge_q24 + i64::from(PressureQ24::ONE_BAR)) as i32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adc_map_matches_spec() {
        assert_eq!(adc_from_bar(BarG(0.0)).0, 410); // 409.5 rounds away from zero
        assert_eq!(adc_from_bar(BarG(10.0)).0, 3686);
        assert_eq!(adc_from_bar(BarG(-5.0)).0, 0);
        assert_eq!(adc_from_bar(BarG(50.0)).0, 4095);
        assert_eq!(adc_from_bar(BarG(f64::NAN)).0, 0);
    }

    #[test]
    fn integer_conversion_matches_float() {
        for c in ADC_MIN_VALID..=ADC_MAX_VALID {
            let q = pressure_from_adc(AdcCounts(c)).unwrap().to_bar_g().0;
            let f = bar_from_adc(AdcCounts(c)).0;
            assert!((q - f).abs() < 1e-6, "{c}: {q} vs {f}");
        }
    }

    #[test]
    fn sensor_faults() {
        assert_eq!(pressure_from_adc(AdcCounts(0)), Err(SensorFault::OpenCircuit));
        assert_eq!(pressure_from_adc(AdcCounts(204)), Err(SensorFault::OpenCircuit));
        assert!(pressure_from_adc(AdcCounts(205)).is_ok());
        assert!(pressure_from_adc(AdcCounts(3890)).is_ok());
        assert_eq!(pressure_from_adc(AdcCounts(3891)), Err(SensorFault::ShortCircuit));
        assert_eq!(pressure_from_adc(AdcCounts(u16::MAX)), Err(SensorFault::ShortCircuit));
    }
}
