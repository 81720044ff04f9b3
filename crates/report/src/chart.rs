//! A small multi-series line chart (SVG) shared by the host tools' reports.

use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

/// One line of a chart.
#[derive(Debug, Clone)]
pub struct Series<'a> {
    /// Legend label.
    pub label: &'a str,
    /// (x, y) points; non-finite points are skipped.
    pub points: Vec<(f64, f64)>,
    /// Line colour.
    pub color: RGBColor,
}

/// Axis labels and title of a chart.
#[derive(Debug, Clone, Copy)]
pub struct ChartLabels<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// X axis description.
    pub x: &'a str,
    /// Y axis description.
    pub y: &'a str,
}

/// The Okabe–Ito palette (Okabe & Ito, "Color Universal Design"): eight colours that stay
/// distinct with the common colour-vision deficiencies and in greyscale print, in an order where
/// the first five are the most distinct: blue, vermillion, bluish green, orange, reddish purple,
/// sky blue, yellow, black. The fault classes are drawn in this order.
pub const OKABE_ITO: [RGBColor; 8] = [
    RGBColor(0x00, 0x72, 0xB2),
    RGBColor(0xD5, 0x5E, 0x00),
    RGBColor(0x00, 0x9E, 0x73),
    RGBColor(0xE6, 0x9F, 0x00),
    RGBColor(0xCC, 0x79, 0xA7),
    RGBColor(0x56, 0xB4, 0xE9),
    RGBColor(0xF0, 0xE4, 0x42),
    RGBColor(0x00, 0x00, 0x00),
];

fn bounds(series: &[Series<'_>]) -> ((f64, f64), (f64, f64)) {
    let pts = series.iter().flat_map(|s| s.points.iter()).filter(|(x, y)| x.is_finite() && y.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if !x0.is_finite() {
        return ((0.0, 1.0), (0.0, 1.0));
    }
    let pad = ((y1 - y0) * 0.05).max(1e-3);
    ((x0, x1.max(x0 + 1e-9)), (y0 - pad, y1 + pad))
}

/// How a legend entry shows its series: a short line for curves, a dot for scatter points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Swatch {
    /// A 20 px line in the series colour.
    Line,
    /// A filled dot in the series colour.
    Dot,
}

/// One entry of a plot's legend.
#[derive(Debug, Clone, Copy)]
pub struct LegendEntry<'a> {
    /// What the series is.
    pub label: &'a str,
    /// Its colour, as drawn in the plot.
    pub color: RGBColor,
    /// How the swatch is drawn.
    pub swatch: Swatch,
}

/// Size of the title text above a plot given to plotters, px (written at 14.5 px).
pub const TITLE_TEXT_PX: u32 = 18;
/// Size of the legend text given to plotters, px (its SVG back end writes text at 1/1.24 of
/// that, 12.9 px here: the 12 px the reports ask of plot text).
pub const LEGEND_TEXT_PX: u32 = 16;
/// Height of one legend row, px.
const LEGEND_ROW_PX: i32 = 20;
/// Horizontal space of a swatch and the gap to its label, px.
const SWATCH_PX: i32 = 28;
/// Space between two legend entries, px.
const ENTRY_GAP_PX: i32 = 20;

/// Draws `title` and, below it, the legend as centred rows of colour swatches and labels, in a
/// band at the top of `area`, and returns the area below the band for the chart (build it
/// without a caption). The legend thus lies outside the data area and never covers a curve or a
/// point when printed; every plot of the reports places its legend this way.
pub fn title_and_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    entries: &[LegendEntry<'_>],
) -> Result<DrawingArea<DB, plotters::coord::Shift>> {
    let err = |e: &dyn std::fmt::Display| anyhow!("plot legend: {e}");
    let width = i32::try_from(area.dim_in_pixel().0).unwrap_or(i32::MAX);
    let legend_font = TextStyle::from(("sans-serif", LEGEND_TEXT_PX).into_font()).color(&BLACK);
    // Lay the entries out in rows that fit the width.
    let mut rows: Vec<Vec<(LegendEntry<'_>, i32)>> = vec![Vec::new()];
    let mut row_width = 0;
    for entry in entries {
        let (text_w, _) = area.estimate_text_size(entry.label, &legend_font).map_err(|e| err(&e))?;
        let w = SWATCH_PX + i32::try_from(text_w).unwrap_or(i32::MAX / 4);
        let needed = if row_width == 0 { w } else { row_width + ENTRY_GAP_PX + w };
        if row_width > 0 && needed > width - 24 {
            rows.push(Vec::new());
            row_width = w;
        } else {
            row_width = needed;
        }
        if let Some(row) = rows.last_mut() {
            row.push((*entry, w));
        }
    }
    rows.retain(|r| !r.is_empty());
    let title_h = if title.is_empty() { 6 } else { 10 + i32::try_from(TITLE_TEXT_PX).unwrap_or(18) + 8 };
    let band_h = title_h + LEGEND_ROW_PX * i32::try_from(rows.len()).unwrap_or(0) + 4;
    let (band, rest) = area.split_vertically(band_h);
    if !title.is_empty() {
        let style = TextStyle::from(("sans-serif", TITLE_TEXT_PX).into_font()).color(&BLACK).pos(
            plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Center,
                plotters::style::text_anchor::VPos::Top,
            ),
        );
        band.draw(&Text::new(title.to_owned(), (width / 2, 10), style)).map_err(|e| err(&e))?;
    }
    let label_style = legend_font.pos(plotters::style::text_anchor::Pos::new(
        plotters::style::text_anchor::HPos::Left,
        plotters::style::text_anchor::VPos::Center,
    ));
    for (i, row) in rows.iter().enumerate() {
        let total: i32 = row.iter().map(|(_, w)| *w).sum::<i32>() + ENTRY_GAP_PX * (row.len() as i32 - 1);
        let mut x = ((width - total) / 2).max(4);
        let y = title_h + LEGEND_ROW_PX * i32::try_from(i).unwrap_or(0) + LEGEND_ROW_PX / 2;
        for (entry, w) in row {
            match entry.swatch {
                Swatch::Line => band
                    .draw(&PathElement::new(vec![(x, y), (x + 20, y)], entry.color.stroke_width(3)))
                    .map_err(|e| err(&e))?,
                Swatch::Dot => band.draw(&Circle::new((x + 10, y), 5, entry.color.filled())).map_err(|e| err(&e))?,
            }
            band.draw(&Text::new(entry.label.to_owned(), (x + SWATCH_PX, y), label_style.clone()))
                .map_err(|e| err(&e))?;
            x += w + ENTRY_GAP_PX;
        }
    }
    Ok(rest)
}

/// A labelled line of a plot: legend label, (x, y) points, colour.
pub type LabelledLine<'a> = (&'a str, Vec<(f64, f64)>, RGBColor);

/// Line-swatch legend entries of labelled lines, in order.
pub fn line_legend<'a>(lines: &'a [LabelledLine<'a>]) -> Vec<LegendEntry<'a>> {
    lines.iter().map(|(label, _, color)| LegendEntry { label, color: *color, swatch: Swatch::Line }).collect()
}

/// Writes a line chart with a legend above the plot area to `path` as SVG.
pub fn write_line_chart(path: &Path, labels: ChartLabels<'_>, series: &[Series<'_>]) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| anyhow!("chart {}: {e}", path.display());
    let root = SVGBackend::new(path, (900, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let ((x0, x1), (y0, y1)) = bounds(series);
    let legend: Vec<LegendEntry<'_>> =
        series.iter().map(|s| LegendEntry { label: s.label, color: s.color, swatch: Swatch::Line }).collect();
    let plot_area = title_and_legend(&root, labels.title, &legend)?;
    let mut chart = ChartBuilder::on(&plot_area)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| err(&e))?;
    chart.configure_mesh().x_desc(labels.x).y_desc(labels.y).draw().map_err(|e| err(&e))?;
    for s in series {
        let color = s.color;
        let pts = s.points.iter().copied().filter(|(x, y)| x.is_finite() && y.is_finite());
        chart.draw_series(LineSeries::new(pts, color.stroke_width(2))).map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Draws each labelled line as a line on an f64 × f64 chart whose legend
/// [`title_and_legend`] drew above it (from [`line_legend`] of the same lines): the one way the
/// audit and metro plots draw their curves.
pub fn draw_lines<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    lines: &[LabelledLine<'_>],
) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| anyhow!("chart: {e}");
    for (_, points, color) in lines {
        chart.draw_series(LineSeries::new(points.iter().copied(), color.stroke_width(2))).map_err(|e| err(&e))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attr(element: &str, name: &str) -> Option<f64> {
        let key = format!(" {name}=\"");
        let at = element.find(&key)? + key.len();
        element[at..].split('"').next()?.parse().ok()
    }

    /// The legend's swatches and labels lie in the band above the data rectangle (the top of the
    /// mesh), in the order given, and nothing of the legend is drawn over the data.
    #[test]
    fn legend_lies_above_the_data_rectangle() {
        let path = std::env::temp_dir().join(format!("pbm-report-legend-{}.svg", std::process::id()));
        let rising: Vec<(f64, f64)> = (0..50).map(|i| (f64::from(i), f64::from(i) * 0.1)).collect();
        let falling: Vec<(f64, f64)> = rising.iter().map(|&(x, y)| (x, 5.0 - y)).collect();
        let series = [
            Series { label: "rising series", points: rising, color: OKABE_ITO[0] },
            Series { label: "falling series", points: falling, color: OKABE_ITO[1] },
        ];
        write_line_chart(&path, ChartLabels { title: "legend test", x: "x", y: "y" }, &series).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        let _ = std::fs::remove_file(&path);
        let elements: Vec<&str> = svg.split('<').collect();
        // The mesh: faint grid lines across the data rectangle.
        let data_top = elements
            .iter()
            .filter(|e| e.starts_with("line ") && attr(e, "opacity").is_some_and(|o| o < 0.5))
            .filter_map(|e| Some(attr(e, "y1")?.min(attr(e, "y2")?)))
            .fold(f64::INFINITY, f64::min);
        assert!(data_top.is_finite() && data_top > 40.0, "no mesh found, or no band above it: {data_top}");
        let label_y = |label: &str| {
            let i = elements.iter().position(|e| e.starts_with("text ") && e.contains(label)).expect(label);
            attr(elements[i], "y").unwrap()
        };
        for label in ["rising series", "falling series"] {
            assert!(
                label_y(label) < data_top,
                "{label} at y {} is not above the data (top {data_top})",
                label_y(label)
            );
        }
        // Each label's swatch in its colour is in the band too, and the legend draws no box.
        for c in ["#0072B2", "#D55E00"] {
            let swatch = elements.iter().find(|e| e.starts_with("polyline ") && e.contains(c)).expect(c);
            let y = swatch.split("points=\"").nth(1).and_then(|p| p.split([',', ' ']).nth(1)).unwrap();
            assert!(y.parse::<f64>().unwrap() < data_top, "swatch {c} at {y} not above {data_top}");
        }
        assert_eq!(elements.iter().filter(|e| e.starts_with("rect ")).count(), 1, "only the background is a box");
    }

    /// Legend entries that do not fit one row wrap onto further rows; the band grows with them.
    #[test]
    fn long_legends_wrap_into_rows() {
        let mut one = String::new();
        let mut many = String::new();
        let entry = LegendEntry { label: "a fairly long legend label", color: OKABE_ITO[2], swatch: Swatch::Dot };
        let height = |buf: &mut String, n: usize| {
            let root = SVGBackend::with_string(buf, (400, 300)).into_drawing_area();
            let rest = title_and_legend(&root, "t", &vec![entry; n]).unwrap();
            rest.dim_in_pixel().1
        };
        let (h1, h4) = (height(&mut one, 1), height(&mut many, 4));
        assert!(h4 + 3 * 20 <= h1 + 1, "4 long entries in 400 px should take 4 rows: {h1} vs {h4}");
        assert_eq!(many.matches("a fairly long legend label").count(), 4);
    }
}
