//! Fault classes of SPEC §4: stable snake_case labels used in files and on CAN.

/// The working state of a parking brake as named by the monitor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum FaultClass {
    /// Healthy.
    Normal = 0,
    /// Torn pipe or bad seal: leak orifice to atmosphere.
    AirLeak = 1,
    /// Wrong or blocked release orifice.
    OrificeBlock = 2,
    /// Both a leak and a blocked orifice.
    LeakAndBlock = 3,
    /// Reducing valve set low or supply drop.
    LowSupply = 4,
    /// Release orifice missing (beyond the paper): violent stroke.
    OrificeMissing = 5,
}

impl FaultClass {
    /// The five classes of the paper, in label order.
    pub const PAPER: [Self; 5] = [Self::Normal, Self::AirLeak, Self::OrificeBlock, Self::LeakAndBlock, Self::LowSupply];
    /// All classes including `orifice_missing`.
    pub const ALL: [Self; 6] =
        [Self::Normal, Self::AirLeak, Self::OrificeBlock, Self::LeakAndBlock, Self::LowSupply, Self::OrificeMissing];

    /// Stable snake_case label (SPEC §4).
    pub const fn label(self) -> &'static str {
        match self {
            Self::Normal => "normal",
            Self::AirLeak => "air_leak",
            Self::OrificeBlock => "orifice_block",
            Self::LeakAndBlock => "leak_and_block",
            Self::LowSupply => "low_supply",
            Self::OrificeMissing => "orifice_missing",
        }
    }

    /// Parses a label; `None` for anything else.
    pub fn from_label(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.label() == s)
    }

    /// Class from its numeric code (as sent on CAN).
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(Self::Normal),
            1 => Some(Self::AirLeak),
            2 => Some(Self::OrificeBlock),
            3 => Some(Self::LeakAndBlock),
            4 => Some(Self::LowSupply),
            5 => Some(Self::OrificeMissing),
            _ => None,
        }
    }
}

impl core::fmt::Display for FaultClass {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.label())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_round_trip() {
        for c in FaultClass::ALL {
            assert_eq!(FaultClass::from_label(c.label()), Some(c));
            assert_eq!(FaultClass::from_code(c as u8), Some(c));
        }
        assert_eq!(FaultClass::from_label("Normal"), None);
        assert_eq!(FaultClass::from_code(6), None);
    }
}
