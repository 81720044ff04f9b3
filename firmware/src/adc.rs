//! The pressure ADC as the sampling task sees it, and its QEMU stand-in.
//!
//! embedded-hal 1.0 has no ADC trait, so the firmware defines the one method it needs. A board
//! support crate implements it over its HAL (for an STM32F4: one regular conversion of the
//! transducer channel with `stm32f4xx_hal::adc::Adc::convert`, 12-bit right-aligned); on QEMU,
//! [`TraceAdc`] plays back a recorded trace compiled into flash.

use pbm::AdcCounts;

/// A 12-bit ADC channel wired to the chamber pressure transducer.
pub trait PressureAdc {
    /// Why a conversion produced no code.
    type Error: Copy + core::fmt::Debug;
    /// One conversion, started and finished within the call (a few µs on real hardware).
    fn read(&mut self) -> Result<AdcCounts, Self::Error>;
}

/// Why [`TraceAdc`] has no more samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TraceEnd {
    /// Every recorded sample has been played.
    Exhausted,
}

/// Plays back recorded ADC codes, one per [`PressureAdc::read`].
#[derive(Debug, Clone)]
pub struct TraceAdc {
    samples: &'static [u16],
    next: usize,
}

impl TraceAdc {
    /// A player at the first sample of `samples`.
    pub const fn new(samples: &'static [u16]) -> Self {
        Self { samples, next: 0 }
    }

    /// Samples played so far.
    pub fn played(&self) -> usize {
        self.next
    }
}

impl PressureAdc for TraceAdc {
    type Error = TraceEnd;

    fn read(&mut self) -> Result<AdcCounts, TraceEnd> {
        let code = self.samples.get(self.next).copied().ok_or(TraceEnd::Exhausted)?;
        self.next += 1;
        Ok(AdcCounts(code))
    }
}

mod trace_data {
    include!(concat!(env!("OUT_DIR"), "/adc_trace.rs"));
}

pub use trace_data::{ADC_TRACE, ADC_TRACE_LOCOMOTIVE, ADC_TRACE_NAME};

/// The driver's release command (the valve-command input), read once per sample beside the ADC.
///
/// On a board this is a GPIO input (`embedded_hal::digital::InputPin::is_high` on the line
/// from the driver's brake valve switch). On QEMU, [`TraceValve`] holds it on for the whole
/// recorded trace: a recorded trace is one release from the command (SPEC §5), which is also how
/// `host-sim replay` reads it.
pub trait ValveCommand {
    /// `true` while a release is requested.
    fn release_requested(&mut self) -> bool;
}

/// The valve command of a recorded release: on from the first sample.
#[derive(Debug, Clone, Copy, Default)]
pub struct TraceValve;

impl ValveCommand for TraceValve {
    fn release_requested(&mut self) -> bool {
        true
    }
}
