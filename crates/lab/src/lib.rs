//! The lab of the parking brake monitor: everything that simulates, replays, fits or audits on the
//! host, in `f64` beside the fixed-point core.
//!
//! - [`reference`]: the independent f64 reference twin; [`plant`]: it with the optional mechanisms.
//! - [`generate`], [`sensor_faults`], [`random`]: the fleet data generator and its sensor faults.
//! - [`simulate`]: one release, either engine.
//! - [`replay`]: recorded traces through the core's `Pipeline` (results, summaries, CAN logs).
//! - [`fit`], [`estimate`]: the batch least-squares fit and the online estimator's accuracy.
//! - [`audit`], [`audit_plot`], [`audit_sweep`], [`metro`]: the model-discrepancy audit on
//!   releases and on the real MetroPT-3 record.
//! - [`can_cmd`]: the cab display's view of CAN logs, sending, the demonstration log.
//! - [`bench`]: throughput figures.
#![deny(missing_docs)]

pub mod audit;
pub mod audit_plot;
pub mod audit_sweep;
pub mod bench;
pub mod can_cmd;
pub mod estimate;
pub mod fit;
pub mod generate;
pub mod metro;
pub mod missing_flow;
pub mod open_world;
pub mod plant;
pub mod random;
pub mod reference;
pub mod replay;
pub mod sensor_faults;
pub mod simulate;
