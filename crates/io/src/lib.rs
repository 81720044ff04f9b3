//! Host I/O of the parking brake monitor: the files the host tools read and write.
//!
//! - [`trace`]: ADC / pressure traces (SPEC §7), reader and writer.
//! - [`dataset`]: data sets (`manifest.csv`, `truth.csv`) and the traces they name.
//! - [`can_log`]: candump logs (`candump -L` format), reader and writer.
//! - [`can_bus`]: where frames go and come from (log, mock bus, SocketCAN).
//! - [`archive`]: fleet archives (many releases in one Parquet file) and replay results as Parquet.
//!
//! Nothing here runs a model: the lab crate replays, the report crate draws.
#![deny(missing_docs)]

pub mod archive;
pub mod can_bus;
pub mod can_log;
pub mod dataset;
pub mod error;
pub mod files;
pub mod lines;
pub mod metro;
pub mod table;
pub mod trace;
