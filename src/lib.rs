//! Spring parking brake monitor: the `no_std` core shared by the firmware and the host tools.
//!
//! No allocator, no HAL: time advances one ADC sample per call and every input comes in as an
//! argument, so the same code runs on the brake controller (Cortex-M4F), on x86 and in tests.
//!
//! - [`units`]: unit newtypes and the fixed-point pressure and length types.
//! - [`fixed`]: the fixed-point number type `Q<T, F>` (format in the type) and its operations.
//! - [`params`]: physical parameters (SPEC §3) and constants (SPEC §2).
//! - [`twin`]: the fixed-point digital twin of the release.
//! - [`sensor`]: the pressure transducer and ADC map (SPEC §5).
//! - [`plausibility`]: real-time checks that the pressure signal is one a working transducer
//!   can produce (frozen, dead, noisy, spikes, dropouts, lost resolution, clipping, rates, levels).
//! - [`fault`]: fault classes (SPEC §4).
//! - [`mechanism`]: the optional mechanisms beyond SPEC §2, described once (name, unit, ranges,
//!   plain-language description) for validation, generator, audits, help and reports.
//! - [`metrics`]: NMSE (SPEC §6).
//! - [`monitor`]: the per-sample monitor: twin, residual, plausibility checks and online
//!   estimator (ADC in, step and status out).
//! - [`estimator`]: the online estimator of the release's physical parameters.
//! - [`features`]: the classifier's online features of a release.
//! - [`classifier`]: the int8 fault classifier and the rules of its verdict.
//! - [`report`]: fault and status reports, independent of the CAN layout.
//! - [`reservoir`]: a compressor-fed air reservoir built from the twin's pieces (the model of
//!   the real MetroPT-3 data, SPEC §8).
//! - [`can`]: CAN frames to the cab display (DBC layout, E2E, encoder, decoder, schedule) and
//!   the candump log format.
//! - [`pipeline`]: the whole per-sample path (monitor, release features, diagnosis policy, CAN
//!   schedule), shared by the firmware and `host-sim replay --can-log`.
//!
//! The modules form layers; each uses only modules of the layers above it (no cycles; checked by
//! `tests/module_layers.rs`):
//!
//! 0. `fixed` (the Q formats);
//! 1. `units`, `fault`, `metrics`, `mechanism`;
//! 2. `params`, `sensor`;
//! 3. `twin`, `plausibility`, `report`;
//! 4. `estimator`, `reservoir`, `can`;
//! 5. `monitor` (twin, plausibility checks, estimator), `features`;
//! 6. `classifier` (on the features);
//! 7. `pipeline` (monitor, features, classifier, diagnosis policy, CAN schedule).
#![cfg_attr(not(feature = "std"), no_std)]
#![deny(missing_docs)]
#![forbid(unsafe_code)]
// Fixed-point code reads `a * b >> s` as "form the product, then drop s fractional bits"
// everywhere; parenthesising every such product only adds noise.
#![allow(clippy::precedence)]

pub mod can;
pub mod classifier;
pub mod estimator;
pub mod fault;
pub mod features;
pub mod fixed;
pub mod mechanism;
pub mod metrics;
pub mod monitor;
pub mod params;
pub mod pipeline;
pub mod plausibility;
pub mod report;
pub mod reservoir;
pub mod sensor;
pub mod twin;
pub mod units;

pub use fault::FaultClass;
pub use params::{ParamError, TwinParams};
pub use twin::{Twin, TwinSample};
pub use units::{AdcCounts, BarG, KelvinQ8, Meters, MetersQ32, PressureQ24, Seconds};
