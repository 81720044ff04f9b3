//! The fleet view of the parking brake monitor: which locomotive has which fault, how sure the
//! monitor is, and which one is about to fail.
//!
//! - [`commands`]: the `host-sim fleet` commands.
//! - [`record`]: one release as the history keeps it.
//! - [`report`]: the fleet page (HTML, inline SVG).
//! - [`db`]: the fleet history in SQLite (schema, natural key, transactions, WAL).
//! - [`export`]: the history as a Parquet file.
//! - [`ingest`]: traces, data sets and cab CAN logs into the history.
//! - [`trend`]: per-locomotive trends of the estimates and the early warning (CUSUM).
//! - [`status`]: the one-line-per-locomotive view.
//! - [`scenario`]: the slow-degradation data set; [`measure`]: lead time and false warnings.
//!
//! Everything the monitor computes (verdicts, confidences, estimates) comes from the core
//! (`pbm`) through the lab's replay; this crate stores and follows it over time.
#![deny(missing_docs)]

pub mod commands;
pub mod db;
pub mod export;
pub mod ingest;
pub mod measure;
pub mod record;
pub mod report;
pub mod scenario;
pub mod status;
pub mod trend;
