//! The optional mechanisms the base model of SPEC §2 lacks, described once.
//!
//! Every mechanism has one magnitude. [`MECHANISMS`] is the one table that says, per mechanism,
//! its name (as written on the command line, in files and reports), its unit, the magnitude that
//! switches it off, a plain-language description, and, for each model that has it (the brake
//! twin of [`crate::twin`], the reservoir of [`crate::reservoir`]), the range the model
//! supports, the range an audit searches, where its local fits start and the range a
//! *plausible* hidden effect is drawn from. Validation ([`Extensions::validate`],
//! [`crate::reservoir::ReservoirParams::validate`]), the host's data generator and sweeps, the
//! model audits, the command-line help and the reports all read it; nothing else lists them.
//!
//! The physics of each mechanism is in the models (module docs of [`crate::twin`] and
//! [`crate::reservoir`]); the host's f64 plant implements the same definitions.
//!
//! Plausible ranges are where a mechanism is physically credible for a spring-brake release
//! *and* changes a 60 s trace by clearly more than the σ = 0.01 bar sensor noise and the ±5 %
//! manufacturing spread of SPEC §5 (below that no audit can name it). The supply air temperature
//! without heat transfer scales every orifice flow exactly like the discharge coefficient Cf,
//! which varies by ±5 % per locomotive: between ≈ 235 K and ≈ 375 K it cannot be told from
//! manufacturing spread, so its plausible range is the hot side beyond that limit.

/// A magnitude a model cannot take ([`Extensions::validate_in`]); the parameter sets wrap it
/// in their `ParamError` (`crate::params`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MechanismError {
    /// The mechanism's magnitude lies outside the range the model supports ([`Scope::valid`]).
    OutOfRange(Mechanism),
    /// The mechanism is on but the model does not have it.
    Unsupported(Mechanism),
}

impl core::fmt::Display for MechanismError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::OutOfRange(m) => {
                let d = m.descriptor();
                let (lo, hi) = d.brake.valid;
                write!(f, "{m} out of the supported range (brake twin: {lo}..={hi} {}", d.unit)?;
                if let Some(r) = d.reservoir {
                    write!(f, "; reservoir: {}..={} {}", r.valid.0, r.valid.1, d.unit)?;
                }
                f.write_str(")")
            }
            Self::Unsupported(m) => write!(f, "{m} is not a mechanism of this model"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for MechanismError {}

/// The gas temperature of the base model, K: `params::TEMPERATURE_K` (equal by a test there;
/// this module sits below `params` and does not import it).
const BASE_TEMPERATURE_K: f64 = 293.15;

/// One optional mechanism (the index of its entry in [`MECHANISMS`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Mechanism {
    /// The valve command reaches the chamber late.
    TransportDelay,
    /// The valve opens gradually.
    ValveLag,
    /// The chamber air exchanges heat with the wall.
    HeatTransfer,
    /// The transducer responds with a lag.
    SensorLag,
    /// The transducer's zero is off.
    SensorOffset,
    /// The transducer's span is off.
    SensorGain,
    /// The supply sags with the flow drawn.
    RegulatorDroop,
    /// The spring stiffens along the stroke.
    ProgressiveSpring,
    /// A seal seeps air in proportion to the pressure.
    LaminarLeak,
    /// The supply air is not at room temperature.
    GasTemperature,
}

/// How an audit maps its unit search coordinate `u` in 0..=1 onto a magnitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SearchScale {
    /// `lo + (hi − lo) u`.
    Linear,
    /// A time constant searched as a rate: `lo / u`, and off (0) where that reaches `hi`, so
    /// that `u = 0` switches the mechanism off and short time constants are not crowded.
    Reciprocal,
}

/// What one model knows about a mechanism.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scope {
    /// Magnitudes the model supports (inclusive): validation rejects anything else.
    pub valid: (f64, f64),
    /// Range an audit searches (inside `valid`, covering `plausible`).
    pub search: (f64, f64),
    /// How the audit walks `search`.
    pub scale: SearchScale,
    /// Magnitudes the audit's local fits start from (several, so that a poor start cannot hide
    /// the mechanism).
    pub starts: &'static [f64],
    /// Plausible magnitudes of a hidden effect: one or two disjoint intervals (two for a
    /// deviation that can go either way).
    pub plausible: &'static [(f64, f64)],
    /// Why those magnitudes are plausible.
    pub plausible_why: &'static str,
    /// False when the model's measured signal cannot separate this mechanism from a change of
    /// the base parameters (an audit may then rightly answer that nothing is missing).
    pub identifiable: bool,
}

/// Everything the project says about one mechanism.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Descriptor {
    /// Which mechanism.
    pub mechanism: Mechanism,
    /// Name on the command line (`--effect NAME=VALUE`), in files and reports.
    pub name: &'static str,
    /// Unit of the magnitude.
    pub unit: &'static str,
    /// The magnitude that switches the mechanism off.
    pub off: f64,
    /// What the mechanism is and what its magnitude means, in plain words.
    pub description: &'static str,
    /// In the brake twin.
    pub brake: Scope,
    /// In the reservoir model (`None`: the reservoir has no such mechanism).
    pub reservoir: Option<Scope>,
}

/// The mechanisms, in [`Mechanism`] order.
pub const MECHANISMS: [Descriptor; Mechanism::COUNT] = [
    Descriptor {
        mechanism: Mechanism::TransportDelay,
        name: "transport_delay",
        unit: "s",
        off: 0.0,
        description:
            "The air reaches the chamber this long after the valve is commanded (a long pipe or a pilot valve; \
             a transducer that reports with a pure delay looks the same in the pressure).",
        brake: Scope {
            valid: (0.0, 10.0),
            search: (0.0, 3.0),
            scale: SearchScale::Linear,
            starts: &[0.1, 0.5, 1.2],
            plausible: &[(0.1, 0.8)],
            plausible_why: "10–50 m of 1/2\" pipe plus a pilot valve",
            identifiable: true,
        },
        reservoir: Some(Scope {
            valid: (0.0, 120.0),
            search: (0.0, 40.0),
            scale: SearchScale::Linear,
            starts: &[2.0, 12.0, 32.0],
            plausible: &[(4.0, 20.0)],
            plausible_why: "the compressor outlet must climb to reservoir pressure before the check valve opens",
            identifiable: true,
        }),
    },
    Descriptor {
        mechanism: Mechanism::ValveLag,
        name: "valve_lag",
        unit: "s",
        off: 0.0,
        description: "The valve opens gradually: its flow area approaches full opening with this time constant.",
        brake: Scope {
            valid: (0.0, 20.0),
            search: (0.0, 5.0),
            scale: SearchScale::Linear,
            starts: &[0.1, 0.6, 2.0],
            plausible: &[(0.2, 1.5)],
            plausible_why: "a slow pilot-operated or sticky valve",
            identifiable: true,
        },
        reservoir: Some(Scope {
            valid: (0.0, 300.0),
            search: (0.0, 60.0),
            scale: SearchScale::Linear,
            starts: &[3.0, 18.0, 48.0],
            plausible: &[(8.0, 40.0)],
            plausible_why: "a compressor that comes up to full delivery slowly",
            identifiable: true,
        }),
    },
    Descriptor {
        mechanism: Mechanism::HeatTransfer,
        name: "heat_transfer",
        unit: "s",
        off: 0.0,
        description: "The air in the chamber exchanges heat with the cylinder wall with this time constant \
                      (the base model fills without any heat exchange).",
        brake: Scope {
            valid: (0.0, 1000.0),
            search: (0.3, 200.0),
            scale: SearchScale::Reciprocal,
            starts: &[1.5, 6.0, 30.0],
            plausible: &[(2.0, 15.0)],
            plausible_why: "small steel chambers cool in seconds",
            identifiable: true,
        },
        reservoir: Some(Scope {
            valid: (0.0, 10_000.0),
            search: (5.0, 5.0e6),
            scale: SearchScale::Reciprocal,
            starts: &[100.0, 50.0 / 3.0, 6.25],
            plausible: &[(10.0, 60.0)],
            plausible_why: "a large reservoir of thin steel cools within a minute",
            identifiable: true,
        }),
    },
    Descriptor {
        mechanism: Mechanism::SensorLag,
        name: "sensor_lag",
        unit: "s",
        off: 0.0,
        description: "The pressure transducer follows the pressure with this time constant \
                      (a snubber or a long sensing line).",
        brake: Scope {
            valid: (0.0, 20.0),
            search: (0.0, 2.0),
            scale: SearchScale::Linear,
            starts: &[0.05, 0.25, 0.8],
            plausible: &[(0.05, 0.4)],
            plausible_why: "a snubber or a long sensing line",
            identifiable: true,
        },
        reservoir: Some(Scope {
            valid: (0.0, 300.0),
            search: (0.0, 60.0),
            scale: SearchScale::Linear,
            starts: &[3.0, 18.0, 48.0],
            plausible: &[(8.0, 40.0)],
            plausible_why: "a heavily damped gauge line",
            identifiable: true,
        }),
    },
    Descriptor {
        mechanism: Mechanism::SensorOffset,
        name: "sensor_offset",
        unit: "bar",
        off: 0.0,
        description: "The transducer reads this much too high (negative: too low) at every pressure (zero drift).",
        brake: Scope {
            valid: (-2.0, 2.0),
            search: (-0.5, 0.5),
            scale: SearchScale::Linear,
            starts: &[-0.05, 0.05],
            plausible: &[(-0.15, -0.03), (0.03, 0.15)],
            plausible_why: "zero drift of a 0–10 bar transducer",
            identifiable: true,
        },
        reservoir: Some(Scope {
            valid: (-2.0, 2.0),
            search: (-0.2, 0.2),
            scale: SearchScale::Linear,
            starts: &[-0.04, 0.04],
            plausible: &[(-0.15, -0.03), (0.03, 0.15)],
            plausible_why: "zero drift of a 0–16 bar transducer",
            // Between 8 and 10 bar an offset is a small change of the fitted compressor delivery
            // and decay rate: dp/dt = fill − λ p seen through o + g p has the same form.
            identifiable: false,
        }),
    },
    Descriptor {
        mechanism: Mechanism::SensorGain,
        name: "sensor_gain",
        unit: "ratio",
        off: 1.0,
        description: "The transducer reads this multiple of the true gauge pressure (span error).",
        brake: Scope {
            valid: (0.5, 1.5),
            search: (0.8, 1.2),
            scale: SearchScale::Linear,
            starts: &[0.97, 1.03],
            plausible: &[(0.95, 0.98), (1.02, 1.05)],
            plausible_why: "span error of a transducer out of calibration",
            identifiable: true,
        },
        reservoir: Some(Scope {
            valid: (0.5, 1.5),
            search: (0.9, 1.1),
            scale: SearchScale::Linear,
            starts: &[0.98, 1.02],
            plausible: &[(0.92, 0.98), (1.02, 1.08)],
            plausible_why: "span error of a transducer out of calibration",
            // As the offset: a change of delivery and decay rate between 8 and 10 bar.
            identifiable: false,
        }),
    },
    Descriptor {
        mechanism: Mechanism::RegulatorDroop,
        name: "regulator_droop",
        unit: "bar",
        off: 0.0,
        description: "The supply pressure sags while air flows, by this much at the full flow of the nominal \
                      1.25 mm orifice and in proportion to the flow (an undersized reducing valve).",
        brake: Scope {
            valid: (0.0, 5.0),
            search: (0.0, 4.0),
            scale: SearchScale::Linear,
            starts: &[0.3, 1.2],
            plausible: &[(0.4, 1.5)],
            plausible_why: "an undersized reducing valve (below ≈ 0.4 bar a discharge coefficient and supply \
                            inside their tolerance mimic it)",
            identifiable: true,
        },
        reservoir: None,
    },
    Descriptor {
        mechanism: Mechanism::ProgressiveSpring,
        name: "progressive_spring",
        unit: "ratio",
        off: 0.0,
        description: "The spring stiffens along the stroke: at full stroke its force beyond the preload is \
                      (1 + this) times the linear spring's, and its rate (1 + 2 × this) times the nominal \
                      rate (conical or nested springs).",
        brake: Scope {
            valid: (-0.9, 5.0),
            search: (-0.5, 2.0),
            scale: SearchScale::Linear,
            starts: &[0.15, 0.6],
            plausible: &[(0.1, 0.5)],
            plausible_why: "conical or nested springs",
            identifiable: true,
        },
        reservoir: None,
    },
    Descriptor {
        mechanism: Mechanism::LaminarLeak,
        name: "laminar_leak",
        unit: "g/s",
        off: 0.0,
        description: "Air seeps out through a porous seal at a rate proportional to the gauge pressure: \
                      this many grams per second at 7 bar.",
        brake: Scope {
            valid: (0.0, 20.0),
            search: (0.0, 3.0),
            scale: SearchScale::Linear,
            starts: &[0.1, 0.6],
            plausible: &[(0.1, 0.5)],
            plausible_why: "a porous seal (the nominal inflow is about 2 g/s)",
            identifiable: true,
        },
        reservoir: Some(Scope {
            valid: (0.0, 100.0),
            search: (0.0, 1.5),
            scale: SearchScale::Linear,
            starts: &[0.075, 0.45, 1.2],
            plausible: &[(0.5, 1.5)],
            plausible_why: "worn seals and fittings of an air production unit",
            // A laminar leak ∝ (p − 1) is the outlet orifice's ∝ p minus a constant at 8–10 bar.
            identifiable: false,
        }),
    },
    Descriptor {
        mechanism: Mechanism::GasTemperature,
        name: "gas_temperature",
        unit: "K",
        off: BASE_TEMPERATURE_K,
        description: "The supply air arrives at this temperature instead of 293 K (air straight from a \
                      compressor whose aftercooler failed).",
        brake: Scope {
            valid: (150.0, 500.0),
            search: (180.0, 450.0),
            scale: SearchScale::Linear,
            starts: &[250.0, 340.0, 390.0],
            plausible: &[(378.0, 400.0)],
            plausible_why: "a failed aftercooler; cooler air cannot be told from manufacturing spread",
            identifiable: true,
        },
        reservoir: None,
    },
];

impl Mechanism {
    /// Number of mechanisms.
    pub const COUNT: usize = 10;

    /// Every mechanism, in table order.
    pub const ALL: [Mechanism; Self::COUNT] = [
        Self::TransportDelay,
        Self::ValveLag,
        Self::HeatTransfer,
        Self::SensorLag,
        Self::SensorOffset,
        Self::SensorGain,
        Self::RegulatorDroop,
        Self::ProgressiveSpring,
        Self::LaminarLeak,
        Self::GasTemperature,
    ];

    /// Its entry in [`MECHANISMS`].
    pub const fn descriptor(self) -> &'static Descriptor {
        &MECHANISMS[self as usize]
    }

    /// Its name (command line, files, reports).
    pub const fn name(self) -> &'static str {
        self.descriptor().name
    }

    /// The unit of its magnitude.
    pub const fn unit(self) -> &'static str {
        self.descriptor().unit
    }

    /// The magnitude that switches it off.
    pub const fn off(self) -> f64 {
        self.descriptor().off
    }

    /// True when the twin's code for this mechanism is compiled in (the core's cargo feature of
    /// the mechanism's name; `extensions` turns all ten on, as the host tools build). A firmware
    /// image compiles in only the mechanism an audit named, and the twin's extended path then
    /// carries only that mechanism's terms.
    pub const fn compiled(self) -> bool {
        match self {
            Self::TransportDelay => cfg!(feature = "transport_delay"),
            Self::ValveLag => cfg!(feature = "valve_lag"),
            Self::HeatTransfer => cfg!(feature = "heat_transfer"),
            Self::SensorLag => cfg!(feature = "sensor_lag"),
            Self::SensorOffset => cfg!(feature = "sensor_offset"),
            Self::SensorGain => cfg!(feature = "sensor_gain"),
            Self::RegulatorDroop => cfg!(feature = "regulator_droop"),
            Self::ProgressiveSpring => cfg!(feature = "progressive_spring"),
            Self::LaminarLeak => cfg!(feature = "laminar_leak"),
            Self::GasTemperature => cfg!(feature = "gas_temperature"),
        }
    }

    /// True when any mechanism is compiled in ([`Self::compiled`]): without one the twin's
    /// extended path is compiled out.
    pub const ANY_COMPILED: bool = {
        let mut i = 0;
        let mut any = false;
        while i < Self::COUNT {
            any |= Self::ALL[i].compiled();
            i += 1;
        }
        any
    };

    /// The mechanism called `name`, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }
}

impl core::fmt::Display for Mechanism {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

impl Scope {
    /// Magnitude at the audit's unit coordinate `u` (clamped to 0..=1).
    pub fn value_at(&self, u: f64) -> f64 {
        let (lo, hi) = self.search;
        let u = u.clamp(0.0, 1.0);
        match self.scale {
            SearchScale::Linear => lo + (hi - lo) * u,
            SearchScale::Reciprocal => {
                let rate = u / lo;
                if rate <= 1.0 / hi {
                    0.0
                } else {
                    1.0 / rate
                }
            }
        }
    }

    /// The unit coordinate of `value` (the inverse of [`Self::value_at`], clamped to 0..=1).
    pub fn coordinate_of(&self, value: f64) -> f64 {
        let (lo, hi) = self.search;
        match self.scale {
            SearchScale::Linear => ((value - lo) / (hi - lo)).clamp(0.0, 1.0),
            SearchScale::Reciprocal if value <= 0.0 => 0.0,
            SearchScale::Reciprocal => (lo / value).clamp(0.0, 1.0),
        }
    }

    /// A plausible magnitude from two uniform numbers in 0..1: the first picks the interval,
    /// the second the place in it.
    pub fn draw(&self, u_interval: f64, u_value: f64) -> f64 {
        let n = self.plausible.len();
        let i = ((u_interval * n as f64) as usize).min(n.saturating_sub(1));
        let (lo, hi) = self.plausible.get(i).copied().unwrap_or((0.0, 0.0));
        lo + (hi - lo) * u_value
    }
}

/// The magnitudes of every mechanism, indexed by [`Mechanism`]; each at its off value
/// ([`Extensions::NONE`]) switches it off, and with all off a model runs its base equations bit
/// for bit unchanged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extensions {
    values: [f64; Mechanism::COUNT],
}

impl Extensions {
    /// No mechanism: the base model of SPEC §2.
    pub const NONE: Self = {
        let mut values = [0.0; Mechanism::COUNT];
        let mut i = 0;
        while i < Mechanism::COUNT {
            values[i] = MECHANISMS[i].off;
            i += 1;
        }
        Self { values }
    };

    /// These magnitudes with `mechanism` set to `value`.
    #[must_use]
    pub const fn with(mut self, mechanism: Mechanism, value: f64) -> Self {
        self.values[mechanism as usize] = value;
        self
    }

    /// True when every mechanism is off.
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// True when `mechanism` is on.
    pub fn is_on(&self, mechanism: Mechanism) -> bool {
        self[mechanism] != mechanism.off()
    }

    /// The mechanisms that are on, in table order.
    pub fn active(&self) -> impl Iterator<Item = (Mechanism, f64)> + '_ {
        Mechanism::ALL.into_iter().filter(|&m| self.is_on(m)).map(|m| (m, self[m]))
    }

    /// True when the transducer model differs from the ideal sensor.
    pub fn has_sensor_terms(&self) -> bool {
        [Mechanism::SensorLag, Mechanism::SensorOffset, Mechanism::SensorGain].into_iter().any(|m| self.is_on(m))
    }

    /// Checks every magnitude against the brake twin's supported range ([`Scope::valid`]); the
    /// error names the first mechanism outside it (NaN is outside every range).
    pub fn validate(&self) -> Result<(), MechanismError> {
        self.validate_in(|d| Some(d.brake))
    }

    /// Checks every magnitude against the range `scope` gives for its mechanism; a mechanism
    /// that is on where `scope` gives none is [`MechanismError::Unsupported`].
    pub fn validate_in(&self, scope: impl Fn(&Descriptor) -> Option<Scope>) -> Result<(), MechanismError> {
        for d in &MECHANISMS {
            let value = self[d.mechanism];
            match scope(d) {
                Some(s) if value >= s.valid.0 && value <= s.valid.1 => {}
                Some(_) => return Err(MechanismError::OutOfRange(d.mechanism)),
                None if value == d.off => {}
                None => return Err(MechanismError::Unsupported(d.mechanism)),
            }
        }
        Ok(())
    }
}

impl Default for Extensions {
    fn default() -> Self {
        Self::NONE
    }
}

impl core::ops::Index<Mechanism> for Extensions {
    type Output = f64;
    fn index(&self, m: Mechanism) -> &f64 {
        &self.values[m as usize]
    }
}

impl core::ops::IndexMut<Mechanism> for Extensions {
    fn index_mut(&mut self, m: Mechanism) -> &mut f64 {
        &mut self.values[m as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_in_enum_order_and_consistent() {
        for (i, d) in MECHANISMS.iter().enumerate() {
            assert_eq!(d.mechanism as usize, i, "{} out of order", d.name);
            assert_eq!(Mechanism::from_name(d.name), Some(d.mechanism));
            assert!(!d.description.is_empty() && !d.unit.is_empty());
            for s in core::iter::once(d.brake).chain(d.reservoir) {
                let (vlo, vhi) = s.valid;
                assert!(vlo <= d.off && d.off <= vhi, "{}: off value must be valid", d.name);
                assert!(vlo <= s.search.0 && s.search.1 <= vhi || s.scale == SearchScale::Reciprocal, "{}", d.name);
                for &(lo, hi) in s.plausible {
                    assert!(lo < hi && vlo <= lo && hi <= vhi, "{}: plausible inside valid", d.name);
                    assert!(s.search.0 <= lo && hi <= s.search.1, "{}: search covers plausible", d.name);
                }
                for &x in s.starts {
                    assert!(s.search.0 <= x && x <= s.search.1, "{}: start {x} inside the search", d.name);
                    let back = s.value_at(s.coordinate_of(x));
                    assert!((back - x).abs() <= 1e-9 * x.abs().max(1.0), "{}: {x} -> {back}", d.name);
                }
            }
        }
        assert_eq!(Mechanism::from_name("nope"), None);
    }

    #[test]
    fn off_values_switch_off_and_validation_names_the_mechanism() {
        let mut e = Extensions::NONE;
        assert!(e.is_none() && e.validate().is_ok() && e.active().count() == 0);
        e[Mechanism::SensorGain] = 9.0;
        assert_eq!(e.validate(), Err(MechanismError::OutOfRange(Mechanism::SensorGain)));
        e[Mechanism::SensorGain] = f64::NAN;
        assert_eq!(e.validate(), Err(MechanismError::OutOfRange(Mechanism::SensorGain)));
        let e = Extensions::NONE.with(Mechanism::RegulatorDroop, 0.5);
        assert!(e.validate().is_ok());
        assert_eq!(e.validate_in(|d| d.reservoir), Err(MechanismError::Unsupported(Mechanism::RegulatorDroop)));
        let mut active = e.active();
        assert_eq!(active.next(), Some((Mechanism::RegulatorDroop, 0.5)));
        assert_eq!(active.next(), None);
    }

    /// Each mechanism has its cargo feature (named as the mechanism), `extensions` turns on
    /// all of them, and build.rs knows the same list (for the `mechanism_image` cfg).
    #[test]
    fn every_mechanism_has_its_feature() {
        extern crate std;
        use std::format;
        let manifest = include_str!("../Cargo.toml");
        let build = include_str!("../build.rs");
        let extensions = manifest.split("extensions = [").nth(1).and_then(|r| r.split(']').next()).unwrap_or("");
        for m in Mechanism::ALL {
            assert!(manifest.contains(&format!("\n{} = []", m.name())), "{m}: no feature");
            assert!(extensions.contains(&format!("\"{}\"", m.name())), "{m}: not in extensions");
            assert!(build.contains(&format!("\"{}\",", m.name())), "{m}: not in build.rs");
        }
    }

    #[test]
    fn reciprocal_search_is_off_at_zero() {
        let s = Mechanism::HeatTransfer.descriptor().brake;
        assert_eq!(s.value_at(0.0), 0.0);
        assert_eq!(s.value_at(1.0), 0.3);
        assert_eq!(s.coordinate_of(0.0), 0.0);
    }
}
