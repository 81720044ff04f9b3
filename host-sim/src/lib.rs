//! Host side of the parking brake monitor: the f64 reference twin, trace files, fleet data,
//! replay, training and reports. Everything per-sample runs through the `pbm` core.
#![deny(missing_docs)]

pub mod bench;
pub mod dataset;
pub mod generate;
pub mod reference;
pub mod simulate;
pub mod trace;
