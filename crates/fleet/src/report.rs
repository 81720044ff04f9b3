//! `fleet report`: a self-contained HTML page of the fleet (inline SVG, no script, no network),
//! built with the report crate's page model and checked by its structural checker.
//!
//! It leads with one row per locomotive (releases, latest verdict and confidence, verdict mix,
//! current estimates, warnings, a sparkline of the parameter that matters most), then one
//! section per locomotive with the trend of each estimate against its fault edge. Text is for a
//! brake engineer: words and physical units, no code names. Plot text is 12 px; colours are
//! from the Okabe–Ito palette (distinguishable with the common colour-vision deficiencies).

use crate::db::FleetDb;
use crate::record::ReleaseRecord;
use crate::status::{status, trend_series, LocoStatus};
use crate::trend::{cusum, Parameter, WarningRule};
use anyhow::{Context, Result};
use pbm_report::report_html::{check, escape, render, Block, Cell, Page, Section, Table};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Okabe–Ito colours: estimate points, fault edge, baseline band, warning marker.
const POINTS: &str = "#0072B2";
const EDGE: &str = "#D55E00";
const BAND: &str = "#56B4E9";
const WARN: &str = "#E69F00";

/// Words for a stored verdict label.
fn verdict_words(v: &str) -> &str {
    match v {
        "normal" => "healthy",
        "air_leak" => "air leak",
        "orifice_block" => "blocked orifice",
        "leak_and_block" => "leak and blocked orifice",
        "low_supply" => "low supply",
        "orifice_missing" => "orifice missing",
        "cannot_diagnose" => "no diagnosis",
        _ => "no verdict",
    }
}

fn parameter_words(p: Parameter) -> &'static str {
    match p {
        Parameter::Leak => "leak (equivalent orifice)",
        Parameter::Orifice => "release orifice",
        Parameter::Supply => "supply pressure",
    }
}

/// The parameter a locomotive's sparkline shows: the first one warned about, else the leak.
fn key_parameter(s: &LocoStatus) -> Parameter {
    s.warnings.first().map_or(Parameter::Leak, |w| w.parameter)
}

/// The release-number span of the points (no padding: releases are whole numbers, ticks too).
fn x_span(pts: &[(f64, f64)]) -> (f64, f64) {
    let lo = pts.iter().map(|q| q.0).fold(f64::INFINITY, f64::min);
    let hi = pts.iter().map(|q| q.0).fold(f64::NEG_INFINITY, f64::max);
    if lo.is_finite() {
        (lo, hi.max(lo + 1.0))
    } else {
        (0.0, 1.0)
    }
}

fn points(records: &[ReleaseRecord], p: Parameter) -> Vec<(f64, f64)> {
    records.iter().filter_map(|r| p.of(r).map(|v| (r.release_no as f64, v))).collect()
}

fn span(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.08).max(1e-3);
    (lo - pad, hi + pad)
}

/// A sparkline: the estimate over the releases and the fault edge, 160 × 32 px, no text.
fn sparkline(records: &[ReleaseRecord], p: Parameter) -> String {
    let pts = points(records, p);
    let (w, h) = (160.0, 32.0);
    let (x0, x1) = x_span(&pts);
    let (y0, y1) = span(pts.iter().map(|q| q.1).chain([p.threshold()]));
    let sx = |x: f64| 2.0 + (x - x0) / (x1 - x0) * (w - 4.0);
    let sy = |y: f64| h - 2.0 - (y - y0) / (y1 - y0) * (h - 4.0);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" role=\"img\"><title>{} over the releases</title>",
        parameter_words(p)
    );
    let _ = write!(
        svg,
        "<line x1=\"0\" x2=\"{w}\" y1=\"{e:.1}\" y2=\"{e:.1}\" stroke=\"{EDGE}\" stroke-dasharray=\"3 2\"/>",
        e = sy(p.threshold())
    );
    let line: Vec<String> = pts.iter().map(|&(x, y)| format!("{:.1},{:.1}", sx(x), sy(y))).collect();
    let _ = write!(
        svg,
        "<polyline fill=\"none\" stroke=\"{POINTS}\" stroke-width=\"1.2\" points=\"{}\"/></svg>",
        line.join(" ")
    );
    svg
}

/// A trend chart of one parameter of one locomotive: estimates, the baseline band (± 2 σ), the
/// fault edge and the warning, with axes labelled in 12 px text and the legend above the plot.
fn trend_chart(records: &[ReleaseRecord], p: Parameter, rule: &WarningRule) -> Option<String> {
    let pts = points(records, p);
    if pts.is_empty() {
        return None;
    }
    let (baseline, path) = cusum(records, p, rule);
    let warning = path.iter().find(|&&(_, s)| s > rule.h).map(|&(i, _)| records[i].release_no as f64);
    let (w, h) = (640.0, 260.0);
    let (left, right, top, bottom) = (64.0, 16.0, 40.0, 44.0);
    let (x0, x1) = x_span(&pts);
    let (y0, y1) = span(pts.iter().map(|q| q.1).chain([p.threshold()]));
    let sx = |x: f64| left + (x - x0) / (x1 - x0) * (w - left - right);
    let sy = |y: f64| h - bottom - (y - y0) / (y1 - y0) * (h - top - bottom);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\" font-size=\"12\">"
    );
    let _ = write!(s, "<rect x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\" fill=\"#ffffff\"/>");
    if let Some(b) = baseline {
        let (a, c) = (sy((b.mean + 2.0 * b.sigma).min(y1)), sy((b.mean - 2.0 * b.sigma).max(y0)));
        let _ = write!(
            s,
            "<rect x=\"{left}\" y=\"{a:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"{BAND}\" fill-opacity=\"0.25\"/>",
            w - left - right,
            (c - a).max(0.5)
        );
    }
    // Axes and ticks.
    let _ = write!(
        s,
        "<line x1=\"{left}\" y1=\"{b}\" x2=\"{r}\" y2=\"{b}\" stroke=\"#333\"/><line x1=\"{left}\" y1=\"{top}\" x2=\"{left}\" y2=\"{b}\" stroke=\"#333\"/>",
        b = h - bottom,
        r = w - right
    );
    for i in 0..=4 {
        let y = y0 + (y1 - y0) * f64::from(i) / 4.0;
        let _ = write!(
            s,
            "<line x1=\"{:.1}\" x2=\"{left}\" y1=\"{py:.1}\" y2=\"{py:.1}\" stroke=\"#333\"/><text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{y:.2}</text>",
            left - 4.0,
            left - 6.0,
            sy(y) + 4.0,
            py = sy(y)
        );
        let x = x0 + (x1 - x0) * f64::from(i) / 4.0;
        let _ = write!(
            s,
            "<line x1=\"{px:.1}\" x2=\"{px:.1}\" y1=\"{b}\" y2=\"{:.1}\" stroke=\"#333\"/><text x=\"{px:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{x:.0}</text>",
            h - bottom + 4.0,
            h - bottom + 18.0,
            px = sx(x),
            b = h - bottom
        );
    }
    let _ = write!(
        s,
        "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">release number</text>",
        left + (w - left - right) / 2.0,
        h - 8.0
    );
    let _ = write!(
        s,
        "<text transform=\"translate(18 {:.1}) rotate(-90)\" text-anchor=\"middle\">{}, {}</text>",
        top + (h - top - bottom) / 2.0,
        escape(p.name()),
        escape(p.unit())
    );
    let _ = write!(
        s,
        "<line x1=\"{left}\" x2=\"{:.1}\" y1=\"{e:.1}\" y2=\"{e:.1}\" stroke=\"{EDGE}\" stroke-width=\"1.5\" stroke-dasharray=\"6 4\"/>",
        w - right,
        e = sy(p.threshold())
    );
    if let Some(x) = warning {
        let _ = write!(
            s,
            "<line x1=\"{px:.1}\" x2=\"{px:.1}\" y1=\"{top}\" y2=\"{:.1}\" stroke=\"{WARN}\" stroke-width=\"2\"/>",
            h - bottom,
            px = sx(x)
        );
    }
    for &(x, y) in &pts {
        let _ = write!(s, "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2\" fill=\"{POINTS}\"/>", sx(x), sy(y));
    }
    // Legend above the plot area, outside the data.
    let items =
        [(POINTS, "estimate per release"), (EDGE, "fault edge"), (BAND, "own baseline ± 2 σ"), (WARN, "early warning")];
    let mut lx = left;
    for (color, label) in items {
        let _ = write!(
            s,
            "<rect x=\"{lx:.1}\" y=\"12\" width=\"12\" height=\"12\" fill=\"{color}\"/><text x=\"{:.1}\" y=\"22\">{label}</text>",
            lx + 16.0
        );
        lx += 28.0 + 7.0 * label.len() as f64;
    }
    s.push_str("</svg>");
    Some(s)
}

fn fmt_opt(v: Option<f64>, decimals: usize) -> String {
    v.map_or_else(|| "–".to_owned(), |x| format!("{x:.decimals$}"))
}

/// An HTML id for a locomotive's section, unique on the page: `loco-` and the name's letters
/// and digits, with `-2`, `-3`, … when names that differ only in other characters (`loco 7`,
/// `loco-7`) would share it.
fn unique_id(name: &str, taken: &mut std::collections::HashSet<String>) -> String {
    let id = format!("loco-{}", name.chars().filter(char::is_ascii_alphanumeric).collect::<String>());
    let mut candidate = id.clone();
    let mut n = 2;
    while !taken.insert(candidate.clone()) {
        candidate = format!("{id}-{n}");
        n += 1;
    }
    candidate
}

/// Builds the page from the database.
pub fn page(db: &FleetDb, rule: &WarningRule) -> Result<(Page, Vec<String>)> {
    let statuses = status(db, rule)?;
    let mut sparks = Vec::new();
    let mut fleet = Section::new("fleet", "Fleet");
    fleet.push(Block::Para(format!(
        "{} locomotives, {} releases. One row per locomotive: what the monitor said about its latest release and how sure it was, how its releases were judged so far, the brake's current estimated leak, release orifice and supply pressure, and an early warning when one of them has moved toward a fault, and a sensor warning when the monitor found the pressure transducer at fault.",
        statuses.len(),
        statuses.iter().map(|s| s.releases).sum::<usize>()
    )));
    let mut table = Table::new(
        "Locomotives",
        &[
            "Locomotive",
            "Releases",
            "Latest verdict",
            "Confidence",
            "Verdict mix",
            "Leak, mm",
            "Orifice, mm",
            "Supply, bar g",
            "Warnings",
            "Trend",
        ],
    );
    let mut per_loco = Vec::new();
    for s in &statuses {
        let stored = db.releases(&s.locomotive)?;
        let records = trend_series(&stored);
        let latest = |p: Parameter| s.trends[p as usize].map(|t| t.latest);
        let (verdict, conf) = match &s.latest_verdict {
            Some((v, c)) => (verdict_words(v).to_owned(), c.map_or_else(|| "–".to_owned(), |c| format!("{c} %"))),
            None => ("–".to_owned(), "–".to_owned()),
        };
        let mix: Vec<String> = s.verdicts.iter().map(|(v, n)| format!("{} {n}", verdict_words(v))).collect();
        let mut warnings: Vec<String> = s.undiagnosed.iter().filter(|u| u.sensor).map(|u| u.describe()).collect();
        warnings.extend(s.warnings.iter().map(|w| match s.doubt(w) {
            Some(why) => format!("cannot tell: {} — {why}", w.describe()),
            None => w.describe(),
        }));
        let key = key_parameter(s);
        sparks.push(sparkline(&records, key));
        let mut quiet: Vec<String> = s.cleared.iter().map(|w| format!("earlier: {}", w.describe())).collect();
        quiet.extend(s.undiagnosed.iter().filter(|u| !u.sensor).map(|u| u.describe()));
        let warn_cell = if warnings.is_empty() {
            Cell::text(if quiet.is_empty() { "none".to_owned() } else { format!("none; {}", quiet.join("; ")) })
        } else {
            warnings.extend(quiet);
            Cell::strong(warnings.join("; ")).with_background((0xfc, 0xe4, 0xc4))
        };
        table.row(vec![
            Cell::strong(s.locomotive.clone()),
            Cell::text(s.releases.to_string()),
            Cell::text(verdict),
            Cell::text(conf),
            Cell::text(mix.join(", ")),
            Cell::text(fmt_opt(latest(Parameter::Leak), 3)),
            Cell::text(fmt_opt(latest(Parameter::Orifice), 3)),
            Cell::text(fmt_opt(latest(Parameter::Supply), 3)),
            warn_cell,
            Cell::text(format!("SPARKLINE-{}", sparks.len() - 1)),
        ]);
        per_loco.push((s, records));
    }
    if statuses.is_empty() {
        fleet.push(Block::Para("Nothing stored yet: no release has been ingested into this fleet history.".to_owned()));
    } else {
        fleet.push(Block::Table(table));
    }
    fleet.push(Block::Note(format!(
        "The trend column shows the leak, or the parameter warned about, over the releases, with its fault edge dashed. Fault edges: leak from {:.1} mm, release orifice below {:.1} mm, supply below {:.1} bar g. A warning is raised when the estimate has moved toward its edge by more than the locomotive's own release-to-release scatter (and, for the supply, by more than the regulator's setting tolerance of {:.2} bar) for long enough (a cumulative-sum test over the locomotive's first {} diagnosed releases as its baseline); it says whether the estimate is drifting, stepped or shifted only on some releases, and clears after {} releases back at the baseline. Releases the monitor did not diagnose (sensor fault, unfamiliar release) are not followed.",
        crate::trend::SUPPLY_SETTING_TOLERANCE_BAR,
        Parameter::Leak.threshold(),
        Parameter::Orifice.threshold(),
        Parameter::Supply.threshold(),
        rule.baseline,
        rule.clear_after
    )));
    let mut sections = vec![fleet];
    let mut ids = std::collections::HashSet::new();
    for (s, records) in per_loco {
        let id = unique_id(&s.locomotive, &mut ids);
        let mut sec = Section::new(&id, s.locomotive.clone());
        let mut any = false;
        for p in Parameter::ALL {
            if let Some(svg) = trend_chart(&records, p, rule) {
                let t = s.trends[p as usize];
                let slope = t.map_or_else(String::new, |t| {
                    let se = if t.slope_se.is_finite() { format!(" ± {:.4}", t.slope_se) } else { String::new() };
                    format!(" Over the last {} releases it moves by {:+.4}{se} {} per release.", t.n, t.slope, p.unit())
                });
                let eta = t.and_then(|t| t.releases_to_edge).map_or_else(String::new, |n| {
                    format!(" At that rate it reaches the fault edge in about {n:.0} releases.")
                });
                sec.push(Block::Figure {
                    svg,
                    caption: format!("Estimated {} of every release.{slope}{eta}", parameter_words(p)),
                });
                any = true;
            }
        }
        if !any {
            sec.push(Block::Para("No estimates stored for this locomotive.".to_owned()));
        }
        for u in &s.undiagnosed {
            sec.push(Block::Para(format!("{}.", u.describe())));
        }
        for w in s.warnings.iter().chain(&s.cleared) {
            sec.push(Block::Para(format!("Warning: {}.", w.describe())));
        }
        sections.push(sec);
    }
    Ok((
        Page {
            title: "Parking brake fleet".to_owned(),
            subtitle: "Per-locomotive verdicts, estimates, trends and early warnings from the stored releases"
                .to_owned(),
            sections,
        },
        sparks,
    ))
}

/// Renders the page, puts the sparklines in their cells and checks the result.
pub fn html(db: &FleetDb, rule: &WarningRule) -> Result<String> {
    let (page, sparks) = page(db, rule)?;
    let mut html = render(&page);
    // The page model escapes all cell text; the sparklines go in after rendering, last first
    // so that `SPARKLINE-1` is not found inside `SPARKLINE-10`.
    for (i, svg) in sparks.iter().enumerate().rev() {
        html = html.replace(&format!(">SPARKLINE-{i}<"), &format!(">{svg}<"));
    }
    let required: Vec<&str> = vec!["fleet"];
    check(&html, &required).map_err(|e| anyhow::anyhow!("the fleet page failed its check: {e}"))?;
    Ok(html)
}

/// Writes `DIR/index.html`; returns its path.
pub fn write(db: &FleetDb, out: &Path, rule: &WarningRule) -> Result<PathBuf> {
    let html = html(db, rule)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let path = out.join("index.html");
    std::fs::write(&path, html).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path)
}
