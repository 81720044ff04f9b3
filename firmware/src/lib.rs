//! Firmware of the spring parking brake monitor for a Cortex-M4F (`thumbv7em-none-eabihf`).
//!
//! The monitor logic is the `no_std` core (`pbm`, the repository's root package): the monitor
//! task drives `pbm::pipeline::Pipeline`, the same per-sample path `host-sim replay` runs. This
//! crate only supplies what a microcontroller needs around it:
//!
//! - [`app`]: the monitor application (sample, monitor, transmit and watchdog loops), generic
//!   over its drivers: the QEMU `monitor` binary and the board image (`board/`) both run it.
//! - [`adc`]: the sample source and valve command traits, and the QEMU trace player.
//! - [`executor`]: an embassy executor whose idle loop sleeps with `WFI` (QEMU treats `WFE` as
//!   a no-op, so the stock thread executor would spin); the board uses it too.
//! - [`stack`]: peak stack by painting.
//!
//! With the feature `qemu` (default; the QEMU `mps2-an386` build):
//!
//! - [`time_driver`]: the embassy-time driver on the Cortex-M SysTick timer.
//! - [`console`]: the defmt logger, the candump output and the exit status over ARM
//!   semihosting, and the panic handler.
//! - [`candump`]: an `embedded_can::blocking::Can` that writes candump log lines (the core's
//!   `pbm::can::candump` formatter).
//! - [`vectors`]: the 32 device interrupt vectors of the MPS2 AN386.
//! - [`golden`]: the host-computed checkpoints of the nominal release, compiled into flash.
//! - [`classifier_golden`]: the host-computed golden vectors of the int8 classifier and their
//!   check.
//!
//! Binaries (QEMU): `twin-check` (the twin in QEMU against the host's golden values),
//! `classifier-check` (the int8 classifier against the host's golden vectors), `monitor` (the
//! monitor as embassy tasks: ADC, monitor, CAN, watchdog) and `bench` (cost figures).
#![no_std]
#![deny(missing_docs)]

pub mod adc;
pub mod app;
#[cfg(feature = "qemu")]
pub mod candump;
pub mod classifier_golden;
#[cfg(feature = "qemu")]
pub mod console;
pub mod executor;
pub mod golden;
pub mod stack;
#[cfg(feature = "qemu")]
pub mod time_driver;
#[cfg(feature = "qemu")]
pub mod vectors;
