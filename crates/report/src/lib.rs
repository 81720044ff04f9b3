//! Charts and pages of the parking brake monitor's reports: SVG line charts and replay plots
//! (plotters, SVG back end) and the self-contained HTML page model with its renderer and checker.
//!
//! A leaf crate: it knows nothing of the monitor, only of series, labels and sections, so every
//! tool that draws goes through the same code.
#![deny(missing_docs)]

pub mod chart;
pub mod plot;
pub mod report_html;
