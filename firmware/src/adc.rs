//! The pressure ADC and the release command as the sampling task sees them, and their QEMU
//! stand-ins.
//!
//! embedded-hal 1.0 has no ADC trait, so the firmware defines what it needs: a
//! [`SampleSource`] that yields one ADC code per 100 Hz sample. On QEMU, [`Paced`] reads a
//! [`PressureAdc`] on an embassy-time ticker and [`TraceAdc`] plays back a recorded trace
//! compiled into flash; on the board (`board/`) a hardware timer triggers the conversions and
//! DMA delivers them, so no software timing is involved.

use pbm::AdcCounts;

/// Where the monitor's samples come from: one chamber-pressure ADC code every 10 ms.
#[allow(async_fn_in_trait)] // single-threaded executor: no `Send` bound is wanted
pub trait SampleSource {
    /// Waits for the next sample; `None` when the input has ended (a recorded trace; a board's
    /// ADC never ends).
    async fn next(&mut self) -> Option<AdcCounts>;
}

/// A [`PressureAdc`] read on a 100 Hz embassy-time ticker (the QEMU build's sampling).
#[cfg(feature = "qemu")]
pub struct Paced<A> {
    adc: A,
    ticker: embassy_time::Ticker,
}

#[cfg(feature = "qemu")]
impl<A: PressureAdc> Paced<A> {
    /// Starts the ticker now: the first sample is read 10 ms later.
    pub fn new(adc: A) -> Self {
        Self { adc, ticker: embassy_time::Ticker::every(embassy_time::Duration::from_millis(10)) }
    }
}

#[cfg(feature = "qemu")]
impl<A: PressureAdc> SampleSource for Paced<A> {
    async fn next(&mut self) -> Option<AdcCounts> {
        self.ticker.next().await;
        self.adc.read().ok()
    }
}

/// A 12-bit ADC channel wired to the chamber pressure transducer.
pub trait PressureAdc {
    /// Why a conversion produced no code.
    type Error: Copy + core::fmt::Debug;
    /// One conversion, started and finished within the call (a few µs on real hardware).
    fn read(&mut self) -> Result<AdcCounts, Self::Error>;
}

/// Why [`TraceAdc`] has no more samples.
#[cfg(feature = "qemu")]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TraceEnd {
    /// Every recorded sample has been played.
    Exhausted,
}

/// Plays back recorded ADC codes, one per [`PressureAdc::read`].
#[cfg(feature = "qemu")]
#[derive(Debug, Clone)]
pub struct TraceAdc {
    samples: &'static [u16],
    next: usize,
}

#[cfg(feature = "qemu")]
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

#[cfg(feature = "qemu")]
impl PressureAdc for TraceAdc {
    type Error = TraceEnd;

    fn read(&mut self) -> Result<AdcCounts, TraceEnd> {
        let code = self.samples.get(self.next).copied().ok_or(TraceEnd::Exhausted)?;
        self.next += 1;
        Ok(AdcCounts(code))
    }
}

#[cfg(feature = "qemu")]
mod trace_data {
    include!(concat!(env!("OUT_DIR"), "/adc_trace.rs"));
}

#[cfg(feature = "qemu")]
pub use trace_data::{ADC_TRACE, ADC_TRACE_LOCOMOTIVE, ADC_TRACE_NAME};

/// The driver's release command (the valve-command input), read once per sample beside the ADC.
///
/// On the board this is a GPIO input (the line from the driver's brake valve switch, debounced
/// from its EXTI edges, `board/`). On QEMU, [`TraceValve`] holds it on for the whole
/// recorded trace: a recorded trace is one release from the command (SPEC §5), which is also how
/// `host-sim replay` reads it.
pub trait ValveCommand {
    /// `true` while a release is requested.
    fn release_requested(&mut self) -> bool;
}

/// The valve command of a recorded release: on from the first sample.
#[cfg(feature = "qemu")]
#[derive(Debug, Clone, Copy, Default)]
pub struct TraceValve;

#[cfg(feature = "qemu")]
impl ValveCommand for TraceValve {
    fn release_requested(&mut self) -> bool {
        true
    }
}
