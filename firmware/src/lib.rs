//! Firmware of the spring parking brake monitor for a Cortex-M4F (`thumbv7em-none-eabihf`).
//!
//! The monitor logic is the `no_std` core (`pbm`, the repository's root package); this crate
//! only supplies what a microcontroller needs around it:
//!
//! - [`time_driver`]: the embassy-time driver on the Cortex-M SysTick timer.
//! - [`executor`]: an embassy executor whose idle loop sleeps with `WFI` (QEMU treats `WFE` as
//!   a no-op, so the stock thread executor would spin).
//! - [`console`]: text output and the process exit code over ARM semihosting, and the panic
//!   handler.
//! - [`golden`]: the host-computed checkpoints of the nominal release, compiled into flash.
//!
//! Binaries: `twin-check` (the twin in QEMU against the host's golden values).
#![no_std]
#![deny(missing_docs)]

pub mod console;
pub mod executor;
pub mod golden;
pub mod time_driver;
