//! SVG plots of a replayed trace: measured vs twin pressure, and the residual.

use crate::chart::{title_and_legend, LegendEntry, Swatch, OKABE_ITO};
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

/// Okabe–Ito colours of the measured and the twin pressure.
const MEASURED: RGBColor = OKABE_ITO[0];
const TWIN: RGBColor = OKABE_ITO[1];

/// The series of one replay plot (all slices of equal length; NaN marks a missing point,
/// e.g. a sensor-fault sample, and breaks the line).
#[derive(Debug, Clone, Copy)]
pub struct ReplayPlot<'a> {
    /// Title above the upper panel.
    pub title: &'a str,
    /// Time, s.
    pub t_s: &'a [f64],
    /// Measured pressure, bar g.
    pub measured_bar: &'a [f64],
    /// Twin pressure, bar g.
    pub twin_bar: &'a [f64],
    /// Measured − twin, bar.
    pub residual_bar: &'a [f64],
}

/// Axis range over the finite values, padded by 5 % (at least `min_span / 2` each side);
/// `±min_span` when there is no finite value.
pub fn range<'a>(values: impl IntoIterator<Item = &'a f64>, min_span: f64) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    if !(lo.is_finite() && hi.is_finite()) {
        return -min_span..min_span;
    }
    let pad = ((hi - lo) * 0.05).max(min_span * 0.5);
    (lo - pad)..(hi + pad)
}

/// Runs of consecutive finite points, so that gaps (NaN) break the line.
fn runs<'a>(t: &'a [f64], y: &'a [f64]) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut cur = Vec::new();
    for (&a, &b) in t.iter().zip(y) {
        if a.is_finite() && b.is_finite() {
            cur.push((a, b));
        } else if !cur.is_empty() {
            out.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// Writes the plot as SVG to `path`.
pub fn write_replay_svg(path: &Path, p: &ReplayPlot<'_>) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| anyhow!("plot {}: {e}", path.display());
    let root = SVGBackend::new(path, (1000, 740)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (upper, lower) = root.split_vertically(460);
    let t_range = range(p.t_s, 1.0);
    let t_range = t_range.start.max(0.0)..t_range.end;

    let legend = [
        LegendEntry { label: "measured", color: MEASURED, swatch: Swatch::Line },
        LegendEntry { label: "twin", color: TWIN, swatch: Swatch::Line },
    ];
    let upper = title_and_legend(&upper, p.title, &legend)?;
    let mut chart = ChartBuilder::on(&upper)
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(t_range.clone(), range(&[p.measured_bar, p.twin_bar].concat(), 0.5))
        .map_err(|e| err(&e))?;
    chart.configure_mesh().x_desc("t, s").y_desc("pressure, bar g").draw().map_err(|e| err(&e))?;
    for run in runs(p.t_s, p.measured_bar) {
        chart.draw_series(LineSeries::new(run, MEASURED.stroke_width(2))).map_err(|e| err(&e))?;
    }
    for run in runs(p.t_s, p.twin_bar) {
        chart.draw_series(LineSeries::new(run, TWIN.stroke_width(2))).map_err(|e| err(&e))?;
    }

    let mut chart = ChartBuilder::on(&lower)
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(t_range, range(p.residual_bar, 0.05))
        .map_err(|e| err(&e))?;
    chart.configure_mesh().x_desc("t, s").y_desc("residual, bar").draw().map_err(|e| err(&e))?;
    for run in runs(p.t_s, p.residual_bar) {
        chart.draw_series(LineSeries::new(run, OKABE_ITO[7])).map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
