//! Plots (SVG, plotters) and the self-contained HTML page of `host-sim audit`.

use crate::audit::{audit, load_dataset, AuditData, AuditOptions, AuditOutcome, AuditRunOptions, CurveSet};
use anyhow::Context as _;
use anyhow::{anyhow, Result};
use pbm_io::error::Skipped;
use pbm_report::chart::{draw_lines, line_legend, title_and_legend, LegendEntry, Swatch, OKABE_ITO};
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

fn span(values: &[&[f64]], min_span: f64) -> std::ops::Range<f64> {
    pbm_report::plot::range(values.iter().flat_map(|v| v.iter()), min_span)
}

fn points(y: &[f64]) -> Vec<(f64, f64)> {
    y.iter().enumerate().filter(|(_, v)| v.is_finite()).map(|(i, &v)| (i as f64 * 0.01, v)).collect()
}

/// Okabe–Ito colours of the audit plots: measurement, base twin, extended twin, phase marks.
const MEASURED: RGBColor = OKABE_ITO[7];
const BASE: RGBColor = OKABE_ITO[1];
const EXTENDED: RGBColor = OKABE_ITO[0];
const MARK: RGBColor = OKABE_ITO[2];

fn e<E: std::fmt::Display>(err: E) -> anyhow::Error {
    anyhow!("plot: {err}")
}

/// Measured mean vs base twin vs extended twin.
pub fn curves_svg(out: &AuditOutcome, c: &CurveSet) -> Result<String> {
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (1000, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let t_end = c.measured.len() as f64 * 0.01;
        let lines = [
            ("measured (mean)", points(&c.measured), MEASURED),
            ("base twin", points(&c.base), BASE),
            ("extended twin", points(&c.extended), EXTENDED),
        ];
        let plot_area =
            title_and_legend(&root, &format!("measured vs base vs extended ({})", out.cause), &line_legend(&lines))?;
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..t_end, span(&[&c.measured, &c.base, &c.extended], 0.5))
            .map_err(e)?;
        chart.configure_mesh().x_desc("t, s").y_desc("pressure, bar g").draw().map_err(e)?;
        draw_lines(&mut chart, &lines)?;
        root.present().map_err(e)?;
    }
    Ok(buf)
}

/// Residuals of base and extended twin against time, with the phase boundaries.
pub fn residual_svg(out: &AuditOutcome, c: &CurveSet) -> Result<String> {
    let rb: Vec<f64> = c.measured.iter().zip(&c.base).map(|(m, b)| m - b).collect();
    let re: Vec<f64> = c.measured.iter().zip(&c.extended).map(|(m, b)| m - b).collect();
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (1000, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let t_end = c.measured.len() as f64 * 0.01;
        let yr = span(&[&rb, &re], 0.02);
        let lines = [("base", points(&rb), BASE), ("extended", points(&re), EXTENDED)];
        let mut legend = line_legend(&lines);
        legend.push(LegendEntry { label: "phase boundary", color: MARK, swatch: Swatch::Line });
        let plot_area = title_and_legend(&root, &format!("residual measured − twin (cause: {})", out.cause), &legend)?;
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_end, yr.clone())
            .map_err(e)?;
        chart.configure_mesh().x_desc("t, s").y_desc("residual, bar").draw().map_err(e)?;
        // Phase boundaries from the base twin's travel.
        let stroke = c.base_travel.iter().copied().fold(0.0, f64::max);
        let first_move = c.base_travel.iter().position(|&x| x > 1e-6);
        let end_stop = c.base_travel.iter().position(|&x| stroke > 0.0 && x >= stroke - 1e-3);
        for idx in [first_move, end_stop].into_iter().flatten() {
            let t = idx as f64 * 0.01;
            chart.draw_series(LineSeries::new(vec![(t, yr.start), (t, yr.end)], MARK.stroke_width(2))).map_err(e)?;
        }
        draw_lines(&mut chart, &lines)?;
        root.present().map_err(e)?;
    }
    Ok(buf)
}

/// Autocorrelation of the base and extended residuals (every 5th sample), with the ±1.96/√n band.
pub fn acf_svg(out: &AuditOutcome) -> Result<String> {
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (700, 360)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let legend = [
            LegendEntry { label: "base", color: BASE, swatch: Swatch::Line },
            LegendEntry { label: "extended", color: EXTENDED, swatch: Swatch::Line },
            LegendEntry { label: "±1.96/√n", color: MARK, swatch: Swatch::Line },
        ];
        let plot_area = title_and_legend(&root, "residual autocorrelation (lag in 50 ms steps)", &legend)?;
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(40)
            .build_cartesian_2d(0.0..21.0, -1.0..1.0)
            .map_err(e)?;
        chart.configure_mesh().x_desc("lag").y_desc("acf").draw().map_err(e)?;
        let n: usize = out.curves.iter().map(|c| c.measured.len() / 5).sum();
        let band = 1.96 / (n.max(1) as f64).sqrt();
        for b in [band, -band] {
            chart.draw_series(LineSeries::new(vec![(0.0, b), (21.0, b)], MARK.stroke_width(2))).map_err(e)?;
        }
        for (acf, color, dx) in [(&out.diagnostics.acf, BASE, -0.15), (&out.chosen_diagnostics.acf, EXTENDED, 0.15)] {
            chart
                .draw_series(acf.iter().enumerate().map(|(k, &r)| {
                    let x = (k + 1) as f64 + dx;
                    PathElement::new(vec![(x, 0.0), (x, r)], color.stroke_width(3))
                }))
                .map_err(e)?;
        }
        root.present().map_err(e)?;
    }
    Ok(buf)
}

/// The unmodelled flow of group `i` (the reconstruction of the audit, block means, g/s)
/// against time, with its ± significance band, and against the measured pressure.
pub fn missing_flow_svg(out: &AuditOutcome, i: usize) -> Result<String> {
    use crate::missing_flow::Z_SIGNIFICANT;
    let Some(m) = out.missing.get(i) else { return Ok(String::new()) };
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (1000, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let (left, right) = root.split_horizontally(620);
        let flows: Vec<f64> = m.blocks.iter().map(|b| b.flow_g_s).collect();
        let band: Vec<f64> =
            m.blocks.iter().flat_map(|b| [Z_SIGNIFICANT * b.sigma_g_s, -Z_SIGNIFICANT * b.sigma_g_s]).collect();
        let yr = span(&[&flows, &band], 0.2);
        let t_end = m.blocks.last().map_or(1.0, |b| b.t_s + 0.125);
        let sig = |b: &crate::missing_flow::Block| b.z().abs() >= Z_SIGNIFICANT;
        {
            let mut chart = ChartBuilder::on(&left)
                .caption("unmodelled air flow vs time", ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(55)
                .build_cartesian_2d(0.0..t_end, yr.clone())
                .map_err(e)?;
            chart.configure_mesh().x_desc("t, s").y_desc("flow, g/s (+ in, − out)").draw().map_err(e)?;
            for sign in [1.0, -1.0] {
                let line: Vec<(f64, f64)> =
                    m.blocks.iter().map(|b| (b.t_s, sign * Z_SIGNIFICANT * b.sigma_g_s)).collect();
                chart.draw_series(LineSeries::new(line, GREEN.mix(0.7))).map_err(e)?;
            }
            chart.draw_series(LineSeries::new(m.blocks.iter().map(|b| (b.t_s, b.flow_g_s)), BLACK)).map_err(e)?;
            chart
                .draw_series(
                    m.blocks.iter().filter(|b| sig(b)).map(|b| Circle::new((b.t_s, b.flow_g_s), 3, RED.filled())),
                )
                .map_err(e)?;
        }
        {
            let p_hi = m.blocks.iter().map(|b| b.pressure_bar).fold(1.0, f64::max) + 0.2;
            let mut chart = ChartBuilder::on(&right)
                .caption("… vs measured pressure", ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(45)
                .build_cartesian_2d(-0.2..p_hi, yr)
                .map_err(e)?;
            chart.configure_mesh().x_desc("pressure, bar g").draw().map_err(e)?;
            chart
                .draw_series(m.blocks.iter().map(|b| {
                    let c = if sig(b) { RED.filled() } else { BLACK.mix(0.4).filled() };
                    Circle::new((b.pressure_bar, b.flow_g_s), 2, c)
                }))
                .map_err(e)?;
        }
        root.present().map_err(e)?;
    }
    Ok(buf)
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// Every plot as `(file name, SVG text)`: `curves_N.svg`, `residual_N.svg` and
/// `missing_flow_N.svg` per configuration group N, then `acf.svg`.
pub fn svgs(out: &AuditOutcome) -> Result<Vec<(String, String)>> {
    let mut v = Vec::new();
    for (i, c) in out.curves.iter().enumerate() {
        v.push((format!("curves_{i}.svg"), curves_svg(out, c)?));
        v.push((format!("residual_{i}.svg"), residual_svg(out, c)?));
        v.push((format!("missing_flow_{i}.svg"), missing_flow_svg(out, i)?));
    }
    v.push(("acf.svg".to_owned(), acf_svg(out)?));
    Ok(v)
}

/// A readable, self-contained HTML page (inline SVG, no external resources).
pub fn html_report(out: &AuditOutcome) -> Result<String> {
    Ok(format!(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>Model-discrepancy audit</title>\
         <style>body{{font-family:sans-serif;max-width:1050px;margin:auto}}table{{border-collapse:collapse}}\
         td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}th{{background:#eee}}\
         td:first-child{{text-align:left}}</style></head><body>{}</body></html>\n",
        html_section(out)?
    ))
}

/// The report's body as one `<section>` (headings h2/h3, tables, inline SVG), for embedding in
/// another page.
pub fn html_section(out: &AuditOutcome) -> Result<String> {
    let d = &out.diagnostics;
    let mut h = String::new();
    let _ = write!(
        h,
        "<section class=\"audit\"><h2>Model-discrepancy audit</h2><p>Data: <code>{}</code></p>",
        esc(&out.source)
    );
    let terms = out.chosen.terms_named(|name| format!("<b>{name}</b>"));
    let cause = if terms.is_empty() { format!("<b>{}</b>", esc(&out.cause)) } else { terms.join(" and ") };
    let _ = write!(
        h,
        "<h3>Verdict</h3><p>Cause: {cause}.</p><p>{}</p><p>NMSE (SPEC §6, mean measured trace) base <b>{:.3} %</b> → \
         extended <b>{:.3} %</b> (ratio {:.1}). Per trace: {:.3} % → {:.3} %.</p>",
        esc(&out.verdict_text()),
        out.base.nmse_pct,
        out.chosen.nmse_pct,
        out.base.nmse_pct / out.chosen.nmse_pct,
        out.nmse_per_trace.0,
        out.nmse_per_trace.1
    );
    let _ = write!(
        h,
        "<h3>What the base twin gets wrong</h3><p>Noise σ estimated from the data: {:.4} bar per trace, \
         {:.4} bar for the mean trace. Base RMS residual {:.4} bar. Ljung–Box Q(20) = {:.1} \
         (white noise below 31.4). Worst 1 s window at {:.0} s (RMS {:.4} bar). Largest \
         cross-correlation with the twin's pressure rate {:+.2} at lag {} samples.</p>",
        d.sigma_trace_bar,
        d.sigma_mean_bar,
        d.rms_bar,
        d.ljung_box_q,
        d.worst_window.0,
        d.worst_window.1,
        d.ccf_rate.0,
        d.ccf_rate.1
    );
    let _ = write!(h, "<table><tr><th>phase</th><th>samples</th><th>RMS, bar</th><th>bias, bar</th><th>share of SSE</th><th>corr. with phase</th></tr>");
    for p in &d.phases {
        let c = d.ccf_phase.iter().find(|(n, _)| *n == p.phase).map_or("".to_owned(), |(_, c)| format!("{c:+.2}"));
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{:.4}</td><td>{:+.4}</td><td>{:.1} %</td><td>{}</td></tr>",
            p.phase, p.samples, p.rms_bar, p.bias_bar, p.sse_share_pct, c
        );
    }
    let _ = write!(h, "</table>");
    for (i, m) in out.missing.iter().enumerate() {
        let _ = write!(h, "<h3>What is missing: the unmodelled air flow</h3><p>{}</p>", esc(&m.description));
        if !m.segments.is_empty() {
            let _ = write!(h, "<ul>");
            for s in &m.segments {
                let _ = write!(h, "<li>{}</li>", esc(&crate::missing_flow::segment_text(s)));
            }
            let _ = write!(h, "</ul>");
        }
        h.push_str(&missing_flow_svg(out, i)?);
        let _ = write!(
            h,
            "<p>The air flow the chamber must have received to follow the measured pressure, minus what the base \
             model lets in at that pressure, in 0.25 s blocks; green: the significance band (± 4 σ of the noise), \
             red: significant blocks. During the stroke a force the model lacks shows as a flow too.</p>"
        );
    }
    let _ = write!(
        h,
        "<h3>Candidates</h3><p>Each is the base twin plus the mechanism(s), or one base parameter beyond its tolerance, \
         all refitted. ΔBIC uses n_eff = {:.0} of n = {} samples (from the noise's own correlation); a cause needs \
         ΔBIC &gt; 10, an RSS cut ≥ 1.5× and a magnitude inside the range searched.</p>\
         <table><tr><th>model</th><th>ΔBIC</th><th>RSS base / model</th><th>NMSE</th><th>magnitudes (±1σ)</th></tr>",
        out.n_eff, out.n
    );
    for c in &out.ranking {
        let m = c
            .terms_text()
            .into_iter()
            .chain(c.flag.iter().map(|f| format!("(not credible: {f})")))
            .collect::<Vec<_>>()
            .join(", ");
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{:.1}</td><td>{:.2}</td><td>{:.3} %</td><td>{}</td></tr>",
            c.name,
            c.delta_bic,
            out.base.rss / c.rss,
            c.nmse_pct,
            esc(&m)
        );
    }
    let _ = write!(h, "</table><h3>Curves</h3>");
    for c in &out.curves {
        h.push_str(&curves_svg(out, c)?);
        h.push_str(&residual_svg(out, c)?);
    }
    h.push_str(&acf_svg(out)?);
    let _ =
        write!(h, "<p>Red: base, blue: extended; green lines: phase boundaries (breakaway, end stop).</p></section>");
    Ok(h)
}

/// Audits the data set in `path` (the summary on stdout) and writes the outputs of `a`;
/// returns the traces skipped.
pub fn run(path: &Path, a: &AuditRunOptions) -> Result<Skipped> {
    let start = std::time::Instant::now();
    let (data, skipped) = load_dataset(path)?;
    for w in &data.warnings {
        eprintln!("warning: {w}");
    }
    let out = audit_loaded(&data, &skipped, a.pairs)?;
    print!("{}", out.summary());
    eprintln!(
        "audit of {} traces in {:.1} s",
        data.groups.iter().map(|g| g.files.len()).sum::<usize>(),
        start.elapsed().as_secs_f64()
    );
    write_outputs(&out, a.json.as_deref(), a.plot.as_deref(), a.report.as_deref())?;
    Ok(skipped)
}

/// The audit of a loaded data set as `host-sim audit` computes it (`pairs`: also try pairs of
/// mechanisms); the traces `skipped` while loading are named in the outcome's warnings, so the
/// JSON says them too, not only stderr and the exit code.
pub fn audit_loaded(data: &AuditData, skipped: &Skipped, pairs: bool) -> Result<AuditOutcome> {
    let mut out = audit(data, AuditOptions { pairs, ..AuditOptions::default() })?;
    out.warnings.extend(skipped.errors().iter().map(|e| format!("skipped: {e}")));
    Ok(out)
}

/// [`audit_loaded`] of the data set directory `path`: the audit `host-sim audit PATH --json`
/// writes (the Python package calls it).
pub fn audit_path(path: &Path, pairs: bool) -> Result<(AuditOutcome, Skipped)> {
    let (data, skipped) = load_dataset(path)?;
    let out = audit_loaded(&data, &skipped, pairs)?;
    Ok((out, skipped))
}

/// Writes the JSON verdict, the plots (`curves_N.svg`, `residual_N.svg` per configuration group,
/// `acf.svg`) and the HTML report, each only when its path is given.
pub fn write_outputs(
    out: &AuditOutcome,
    json: Option<&Path>,
    plot: Option<&Path>,
    report: Option<&Path>,
) -> Result<()> {
    if let Some(p) = json {
        pbm_io::table::write_json(p, &out.to_json())?;
    }
    if let Some(dir) = plot {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        for (name, svg) in svgs(out)? {
            let p = dir.join(name);
            std::fs::write(&p, svg).with_context(|| format!("cannot write {}", p.display()))?;
        }
    }
    if let Some(p) = report {
        std::fs::write(p, html_report(out)?).with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(())
}
