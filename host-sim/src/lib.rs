//! Host side of the parking brake monitor: the f64 reference twin, trace files, fleet data,
//! replay, training and reports. Everything per-sample runs through the `pbm` core.
#![deny(missing_docs)]

pub mod audit;
pub mod audit_plot;
pub mod audit_sweep;
pub mod bench;
pub mod can_bus;
pub mod can_cmd;
pub mod can_log;
pub mod chart;
pub mod dataset;
pub mod demo;
pub mod estimate;
pub mod evaluate;
pub mod fit;
pub mod generate;
pub mod metro;
pub mod nn;
pub mod plant;
pub mod plot;
pub mod reference;
pub mod replay;
pub mod report_html;
pub mod sensor_faults;
pub mod simulate;
pub mod trace;
pub mod train;
