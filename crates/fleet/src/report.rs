//! `fleet report`: self-contained HTML pages of the fleet (inline SVG, no script, no network),
//! built with the report crate's page model and checked by its structural checker.
//!
//! `index.html` is the fleet table: one row per locomotive (releases, latest verdict, the
//! calibrated confidence the monitor sent with it and whether the recent releases agree, the
//! verdict mix, current estimates, warnings, a sparkline of the parameter that matters most),
//! each locomotive linked to its own page next to it (`loco-….html`): its release curves
//! (measured pressure against the twin's, for the latest release and for the release where a
//! warning began), the trend of each estimate against its fault edge, and the fault reports the
//! cab decoded from its CAN frames. Text is for a brake engineer: words and physical units, no
//! code names. Plot text is 12 px at the plot's own size (the plots are narrower than the page,
//! so they are never scaled down); colours are from the Okabe–Ito palette (distinguishable with
//! the common colour-vision deficiencies); legends sit above the plot area.

use crate::db::{FleetDb, StoredCanReport, StoredRelease};
use crate::record::{ReleaseCurve, ReleaseRecord};
use crate::status::{followed, status, trend_series, LocoStatus};
use crate::trend::{cusum, Parameter, WarningRule};
use anyhow::{Context, Result};
use pbm::FaultClass;
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
    let _ =
        write!(svg, "<polyline fill=\"none\" stroke=\"{POINTS}\" stroke-width=\"1.2\" points=\"{}\"/>", line.join(" "));
    // The latest value, marked.
    if let Some(&(x, y)) = pts.last() {
        let _ = write!(svg, "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2.5\" fill=\"{POINTS}\"/>", sx(x), sy(y));
    }
    svg.push_str("</svg>");
    svg
}

/// The frame both charts of a locomotive page draw in: the SVG's size, the plot area's margins,
/// the axes, the axis titles and the legend row above the plot area (outside the data), all in
/// 12 px text.
#[derive(Debug, Clone, Copy)]
struct SvgFrame {
    w: f64,
    h: f64,
    left: f64,
    right: f64,
    top: f64,
    bottom: f64,
}

impl SvgFrame {
    /// The opening tag and a white background.
    fn open(&self) -> String {
        let (w, h) = (self.w, self.h);
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\" font-size=\"12\"><rect x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\" fill=\"#ffffff\"/>"
        )
    }

    /// The x and y axes.
    fn axes(&self, s: &mut String) {
        let _ = write!(
            s,
            "<line x1=\"{l}\" y1=\"{b}\" x2=\"{r}\" y2=\"{b}\" stroke=\"#333\"/><line x1=\"{l}\" y1=\"{t}\" x2=\"{l}\" y2=\"{b}\" stroke=\"#333\"/>",
            l = self.left,
            t = self.top,
            b = self.h - self.bottom,
            r = self.w - self.right
        );
    }

    /// The axis titles (plain text, escaped here).
    fn titles(&self, s: &mut String, x_title: &str, y_title: &str) {
        let _ = write!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text><text transform=\"translate(16 {:.1}) rotate(-90)\" text-anchor=\"middle\">{}</text>",
            self.left + (self.w - self.left - self.right) / 2.0,
            self.h - 8.0,
            escape(x_title),
            self.top + (self.h - self.top - self.bottom) / 2.0,
            escape(y_title)
        );
    }

    /// The legend: a colour swatch and a label per entry, in a row above the plot area.
    fn legend(&self, s: &mut String, items: &[(&str, &str)]) {
        let mut lx = self.left;
        for (color, label) in items {
            let _ = write!(
                s,
                "<rect x=\"{lx:.1}\" y=\"12\" width=\"12\" height=\"12\" fill=\"{color}\"/><text x=\"{:.1}\" y=\"22\">{}</text>",
                lx + 16.0,
                escape(label)
            );
            lx += 28.0 + 6.6 * label.chars().count() as f64;
        }
    }
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
    let frame = SvgFrame { w: 640.0, h: 260.0, left: 64.0, right: 16.0, top: 40.0, bottom: 44.0 };
    let SvgFrame { w, h, left, right, top, bottom } = frame;
    let (x0, x1) = x_span(&pts);
    let (y0, y1) = span(pts.iter().map(|q| q.1).chain([p.threshold()]));
    let sx = |x: f64| left + (x - x0) / (x1 - x0) * (w - left - right);
    let sy = |y: f64| h - bottom - (y - y0) / (y1 - y0) * (h - top - bottom);
    let mut s = frame.open();
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
    frame.axes(&mut s);
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
    frame.titles(&mut s, "release number", &format!("{}, {}", p.name(), p.unit()));
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
    frame.legend(
        &mut s,
        &[
            (POINTS, "estimate per release"),
            (EDGE, "fault edge"),
            (BAND, "own baseline ± 2 σ"),
            (WARN, "early warning"),
        ],
    );
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

/// Releases over which a locomotive's recent verdicts are compared.
pub const RECENT_RELEASES: usize = 10;
/// Share of the recent diagnosed releases that must name the latest verdict's class for the
/// fleet table to show that verdict as settled; below it the table says the releases disagree.
pub const AGREEMENT_SHARE: f64 = 0.8;

/// How a locomotive's recent releases were judged: the classes named over its last
/// [`RECENT_RELEASES`] followed releases, and how many named the latest release's class.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecentVerdicts {
    /// Releases looked at (at most [`RECENT_RELEASES`]).
    pub releases: usize,
    /// Of those, releases the monitor named a class for.
    pub diagnosed: usize,
    /// Class label and count, most frequent first.
    pub classes: Vec<(String, usize)>,
    /// Of the diagnosed ones, releases that named the latest diagnosed release's class.
    pub agree: usize,
}

impl RecentVerdicts {
    /// The recent verdicts of a locomotive's stored releases (the releases its trends follow).
    pub fn of(stored: &[StoredRelease]) -> Self {
        let all: Vec<&StoredRelease> = followed(stored).collect();
        let recent = &all[all.len().saturating_sub(RECENT_RELEASES)..];
        let named: Vec<&str> = recent
            .iter()
            .filter(|r| FaultClass::from_label(&r.verdict).is_some())
            .map(|r| r.verdict.as_str())
            .collect();
        let mut classes: Vec<(String, usize)> = Vec::new();
        for v in &named {
            match classes.iter_mut().find(|(c, _)| c == v) {
                Some(c) => c.1 += 1,
                None => classes.push(((*v).to_owned(), 1)),
            }
        }
        classes.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
        let agree = named.last().map_or(0, |l| named.iter().filter(|v| *v == l).count());
        Self { releases: recent.len(), diagnosed: named.len(), classes, agree }
    }

    /// Whether the recent diagnosed releases disagree: fewer than [`AGREEMENT_SHARE`] of them
    /// name the latest one's class.
    pub fn disagree(&self) -> bool {
        self.diagnosed > 0 && (self.agree as f64) < AGREEMENT_SHARE * self.diagnosed as f64
    }

    /// The classes in words, e.g. `air leak 6, healthy 4`.
    pub fn mix_words(&self) -> String {
        self.classes.iter().map(|(c, n)| format!("{} {n}", verdict_words(c))).collect::<Vec<_>>().join(", ")
    }
}

/// The fleet table's confidence cell of a locomotive: the calibrated probability the monitor
/// sent with its latest verdict, and whether the recent releases back it up.
pub fn confidence_cell(s: &LocoStatus, recent: &RecentVerdicts) -> Cell {
    let latest = s.latest_verdict.as_ref();
    let named = latest.and_then(|(v, c)| FaultClass::from_label(v).map(|_| (v, *c)));
    if recent.disagree() {
        let latest_text = named.map_or_else(String::new, |(v, c)| {
            format!("; latest {}{}", verdict_words(v), c.map_or_else(String::new, |c| format!(" {c} %")))
        });
        return Cell::strong(format!(
            "releases disagree: {} of the last {} diagnosed{latest_text}",
            recent.mix_words(),
            recent.diagnosed
        ))
        .with_background((0xff, 0xf2, 0xb3));
    }
    match (latest, named) {
        (_, Some((v, Some(c)))) => {
            Cell::text(format!("{c} % {}; {} of the last {} agree", verdict_words(v), recent.agree, recent.diagnosed))
        }
        (Some((v, _)), _) if v == crate::record::CANNOT_DIAGNOSE => {
            Cell::text("none: the latest release was not diagnosed".to_owned())
        }
        _ => Cell::text("–".to_owned()),
    }
}

/// File name of each locomotive's page, in `statuses` order: `loco-` and the name's letters and
/// digits, `.html`, made unique.
pub fn page_names(statuses: &[LocoStatus]) -> Vec<String> {
    let mut taken = std::collections::HashSet::new();
    statuses.iter().map(|s| format!("{}.html", unique_id(&s.locomotive, &mut taken))).collect()
}

/// The fleet table as a page section (id `fleet`), each locomotive linked to `page_names`.
pub fn fleet_section(db: &FleetDb, rule: &WarningRule, statuses: &[LocoStatus], pages: &[String]) -> Result<Section> {
    let mut fleet = Section::new("fleet", "Fleet");
    fleet.push(Block::Para(format!(
        "{} locomotives, {} releases. One row per locomotive: what the monitor said about its latest release and the \
         probability it gave that verdict (calibrated on releases held out of training, so that of the releases given \
         90 %, about 90 % are right), whether its recent releases agree, how its releases were judged so far, the \
         brake's current estimated leak, release orifice and supply pressure, and an early warning when one of them \
         has moved toward a fault, or a sensor warning when the monitor found the pressure transducer at fault. The \
         locomotive's name opens its own page: release curves, trends and the reports the cab received.",
        statuses.len(),
        statuses.iter().map(|s| s.releases).sum::<usize>()
    )));
    let mut table = Table::new(
        "Locomotives",
        &[
            "Locomotive",
            "Releases",
            "Latest verdict",
            "Calibrated confidence",
            "Verdict mix (all releases)",
            "Leak, mm",
            "Orifice, mm",
            "Supply, bar g",
            "Warnings",
            "Trend",
        ],
    );
    for (s, page) in statuses.iter().zip(pages) {
        let stored = db.releases(&s.locomotive)?;
        let records = trend_series(&stored);
        let recent = RecentVerdicts::of(&stored);
        let latest = |p: Parameter| s.trends[p as usize].map(|t| t.latest);
        let verdict = match (s.latest_verdict.as_ref(), followed(&stored).last()) {
            (Some((v, _)), Some(r)) if FaultClass::from_label(v).is_none() => match r.no_diagnosis.as_deref() {
                Some(why) => format!("not diagnosed: {}", why.split(" (").next().unwrap_or(why)),
                None => verdict_words(v).to_owned(),
            },
            (Some((v, _)), _) => verdict_words(v).to_owned(),
            (None, _) => "–".to_owned(),
        };
        let mix: Vec<String> = s.verdicts.iter().map(|(v, n)| format!("{} {n}", verdict_words(v))).collect();
        let mut warnings: Vec<String> = s.undiagnosed.iter().filter(|u| u.sensor).map(|u| u.describe()).collect();
        warnings.extend(s.warnings.iter().map(|w| match s.doubt(w) {
            Some(why) => format!("cannot tell: {} — {why}", w.describe()),
            None => w.describe(),
        }));
        let key = key_parameter(s);
        let mut quiet: Vec<String> = s.cleared.iter().map(|w| format!("earlier: {}", w.describe())).collect();
        quiet.extend(s.undiagnosed.iter().filter(|u| !u.sensor).map(|u| u.describe()));
        let warn_cell = if warnings.is_empty() {
            Cell::text(if quiet.is_empty() { "none".to_owned() } else { format!("none; {}", quiet.join("; ")) })
        } else {
            warnings.extend(quiet);
            Cell::strong(warnings.join("; ")).with_background((0xfc, 0xe4, 0xc4))
        };
        table.row(vec![
            Cell::strong(s.locomotive.clone()).with_link(page.clone()),
            Cell::text(s.releases.to_string()),
            Cell::text(verdict),
            confidence_cell(s, &recent),
            Cell::text(mix.join(", ")),
            Cell::text(fmt_opt(latest(Parameter::Leak), 3)),
            Cell::text(fmt_opt(latest(Parameter::Orifice), 3)),
            Cell::text(fmt_opt(latest(Parameter::Supply), 3)),
            warn_cell,
            Cell::text(key.name()).with_svg(sparkline(&records, key)),
        ]);
    }
    if statuses.is_empty() {
        fleet.push(Block::Para("Nothing stored yet: no release has been ingested into this fleet history.".to_owned()));
    } else {
        fleet.push(Block::Table(table));
    }
    fleet.push(Block::Note(format!(
        "The trend column shows the leak, or the parameter warned about, over the releases, with its fault edge dashed. Fault edges: leak from {:.1} mm, release orifice below {:.1} mm, supply below {:.1} bar g. A warning is raised when the estimate has moved toward its edge by more than the locomotive's own release-to-release scatter (and, for the supply, by more than the regulator's setting tolerance of {:.2} bar) for long enough (a cumulative-sum test over the locomotive's first {} diagnosed releases as its baseline); it says whether the estimate is drifting, stepped or shifted only on some releases, and clears after {} releases back at the baseline. Releases the monitor did not diagnose (sensor fault, unfamiliar release) are not followed. The releases agree when at least {:.0} % of the last {} diagnosed ones name the latest verdict.",
        Parameter::Leak.threshold(),
        Parameter::Orifice.threshold(),
        Parameter::Supply.threshold(),
        crate::trend::SUPPLY_SETTING_TOLERANCE_BAR,
        rule.baseline,
        rule.clear_after,
        100.0 * AGREEMENT_SHARE,
        RECENT_RELEASES
    )));
    Ok(fleet)
}

/// Nice tick values between `lo` and `hi` (about `n` of them, steps of 1, 2 or 5 × 10^k).
fn ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let span = (hi - lo).abs().max(1e-9);
    let raw = span / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].into_iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let mut v = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while v <= hi + step * 1e-9 && out.len() < 50 {
        out.push(if v.abs() < step * 1e-9 { 0.0 } else { v });
        v += step;
    }
    out
}

/// The measured pressure of one release against the twin's, 760 × 300 px, 12 px text, the
/// legend above the plot area.
fn curve_chart(curve: &ReleaseCurve) -> Option<String> {
    let n = curve.twin_bar.len();
    if n < 2 {
        return None;
    }
    let t = |i: usize| i as f64 * curve.step_s;
    let values = curve.measured_bar.iter().chain(&curve.twin_bar).map(|&v| f64::from(v)).filter(|v| v.is_finite());
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return None;
    }
    let (y0, y1) = (lo.min(0.0), (hi + 0.3).max(1.0));
    let (x0, x1) = (0.0, t(n - 1).max(1.0));
    let frame = SvgFrame { w: 760.0, h: 300.0, left: 60.0, right: 16.0, top: 40.0, bottom: 44.0 };
    let SvgFrame { w, h, left, right, top, bottom } = frame;
    let sx = |x: f64| left + (x - x0) / (x1 - x0) * (w - left - right);
    let sy = |y: f64| h - bottom - (y - y0) / (y1 - y0) * (h - top - bottom);
    let mut s = frame.open();
    let b = h - bottom;
    for y in ticks(y0, y1, 5) {
        let _ = write!(
            s,
            "<line x1=\"{left}\" x2=\"{:.1}\" y1=\"{py:.1}\" y2=\"{py:.1}\" stroke=\"#e4e8ec\"/><text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{y}</text>",
            w - right,
            left - 6.0,
            sy(y) + 4.0,
            py = sy(y)
        );
    }
    for x in ticks(x0, x1, 6) {
        let _ = write!(
            s,
            "<line x1=\"{px:.1}\" x2=\"{px:.1}\" y1=\"{b}\" y2=\"{:.1}\" stroke=\"#333\"/><text x=\"{px:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{x}</text>",
            b + 4.0,
            b + 18.0,
            px = sx(x)
        );
    }
    frame.axes(&mut s);
    frame.titles(&mut s, "time since the release command, s", "chamber pressure, bar g");
    // Lines, broken where the measured sample was faulty.
    let path = |ys: &[f32]| {
        let mut d = String::new();
        let mut pen_down = false;
        for (i, &v) in ys.iter().enumerate() {
            if v.is_finite() {
                let _ = write!(d, "{}{:.1},{:.1} ", if pen_down { "L" } else { "M" }, sx(t(i)), sy(f64::from(v)));
                pen_down = true;
            } else {
                pen_down = false;
            }
        }
        d
    };
    let _ = write!(
        s,
        "<path d=\"{}\" fill=\"none\" stroke=\"{EDGE}\" stroke-width=\"2\" stroke-dasharray=\"7 4\"/>",
        path(&curve.twin_bar)
    );
    let _ =
        write!(s, "<path d=\"{}\" fill=\"none\" stroke=\"{POINTS}\" stroke-width=\"1.5\"/>", path(&curve.measured_bar));
    frame.legend(
        &mut s,
        &[(POINTS, "measured pressure"), (EDGE, "twin of a healthy brake, same valve command (dashed)")],
    );
    s.push_str("</svg>");
    Some(s)
}

fn estimates_words(r: &StoredRelease) -> String {
    let mut parts = Vec::new();
    if let Some(v) = r.leak_mm {
        parts.push(format!("leak {v:.3} mm"));
    }
    if let Some(v) = r.orifice_mm {
        parts.push(format!("release orifice {v:.3} mm"));
    }
    if let Some(v) = r.supply_bar_g {
        parts.push(format!("supply {v:.3} bar g"));
    }
    if parts.is_empty() {
        "no estimates".to_owned()
    } else {
        format!("estimated {}", parts.join(", "))
    }
}

fn verdict_sentence(r: &StoredRelease) -> String {
    match (FaultClass::from_label(&r.verdict), r.confidence_pct, r.no_diagnosis.as_deref()) {
        (Some(_), Some(c), _) => format!("verdict {}, calibrated confidence {c} %", verdict_words(&r.verdict)),
        (Some(_), None, _) => format!("verdict {}", verdict_words(&r.verdict)),
        (None, _, Some(why)) => format!("not diagnosed: {why}"),
        (None, _, None) => "no verdict".to_owned(),
    }
}

/// The releases whose curves a locomotive page shows, with why: the latest, the release where
/// each warning began (and where a sensor fault was first seen), else the first on record.
fn curve_releases<'a>(s: &LocoStatus, rows: &[&'a StoredRelease]) -> Vec<(&'a StoredRelease, String)> {
    let mut wanted: Vec<(i64, String)> = Vec::new();
    if let Some(last) = rows.last() {
        wanted.push((last.release_no, "the latest release".to_owned()));
    }
    for w in s.warnings.iter().chain(&s.cleared) {
        wanted.push((w.onset_release_no, format!("where the {} warning began", w.parameter.name())));
    }
    for u in s.undiagnosed.iter().filter(|u| u.sensor) {
        wanted.push((u.first_release_no, "the first release with the sensor fault".to_owned()));
    }
    if wanted.len() == 1 {
        if let Some(first) = rows.first() {
            wanted.push((first.release_no, "the first release on record, for comparison".to_owned()));
        }
    }
    let mut out: Vec<(&StoredRelease, String)> = Vec::new();
    for (no, why) in wanted {
        if let Some(r) = rows.iter().find(|r| r.release_no == no) {
            if !out.iter().any(|(o, _)| o.id == r.id) {
                out.push((r, why));
            }
        }
    }
    out
}

/// Releases whose decoded CAN reports a locomotive page lists (the latest ones that have any).
pub const CAN_RELEASES_SHOWN: usize = 10;

fn can_row(r: &StoredRelease, c: &StoredCanReport) -> Vec<Cell> {
    let verdict = match (FaultClass::from_label(&c.verdict), c.no_diagnosis.as_deref()) {
        (Some(_), _) => verdict_words(&c.verdict).to_owned(),
        (None, Some(why)) => format!("no diagnosis: {why}"),
        (None, None) => verdict_words(&c.verdict).to_owned(),
    };
    let mut fresh = if c.current { "current".to_owned() } else { "stale: no heartbeat on time".to_owned() };
    if c.lost_before > 0 {
        fresh.push_str(&format!("; {} earlier report(s) lost", c.lost_before));
    }
    let fresh_cell = if c.current && c.lost_before == 0 {
        Cell::text(fresh)
    } else {
        Cell::strong(fresh).with_background((0xfc, 0xe4, 0xc4))
    };
    vec![
        Cell::text(r.release_no.to_string()),
        Cell::text(c.can_release.to_string()),
        Cell::text(format!("{:.2}", c.since_command_s)),
        Cell::strong(verdict),
        Cell::text(c.confidence_pct.map_or_else(|| "–".to_owned(), |p| format!("{p} %"))),
        Cell::text(fmt_opt(c.supply_bar_g, 3)),
        Cell::text(fmt_opt(c.leak_mm, 3)),
        Cell::text(if c.completed { "yes" } else { "not yet" }),
        fresh_cell,
    ]
}

/// One locomotive's page.
pub fn locomotive_page(db: &FleetDb, rule: &WarningRule, s: &LocoStatus, index: &str) -> Result<Page> {
    let stored = db.releases(&s.locomotive)?;
    let rows: Vec<&StoredRelease> = followed(&stored).collect();
    let records = trend_series(&stored);
    let recent = RecentVerdicts::of(&stored);
    let mut sections = Vec::new();

    let mut summary = Section::new("summary", "Summary");
    summary.push(Block::Links(vec![("Back to the fleet".to_owned(), index.to_owned())]));
    let mut t = Table::new(format!("{} at a glance", s.locomotive), &[]);
    let latest =
        rows.last().map_or_else(|| "–".to_owned(), |r| format!("release {}: {}", r.release_no, verdict_sentence(r)));
    t.row(vec![Cell::text("releases followed"), Cell::text(s.releases.to_string())]);
    t.row(vec![Cell::text("latest release"), Cell::strong(latest)]);
    t.row(vec![Cell::text("recent releases"), confidence_cell(s, &recent)]);
    t.row(vec![
        Cell::text("verdict mix, all releases"),
        Cell::text(s.verdicts.iter().map(|(v, n)| format!("{} {n}", verdict_words(v))).collect::<Vec<_>>().join(", ")),
    ]);
    let mut warn: Vec<String> =
        s.undiagnosed.iter().filter(|u| u.sensor).map(|u| format!("{}.", u.describe())).collect();
    warn.extend(s.warnings.iter().map(|w| match s.doubt(w) {
        Some(why) => format!("Cannot tell: {} — {why}.", w.describe()),
        None => format!("Warning: {}.", w.describe()),
    }));
    warn.extend(s.cleared.iter().map(|w| format!("Earlier: {}.", w.describe())));
    warn.extend(s.undiagnosed.iter().filter(|u| !u.sensor).map(|u| format!("{}.", u.describe())));
    t.row(vec![Cell::text("warnings"), Cell::text(if warn.is_empty() { "none".to_owned() } else { warn.join(" ") })]);
    summary.push(Block::Table(t));
    summary.push(Block::Note(
        "What the estimates mean: the leak is the diameter of a round hole that would vent the spring chamber as fast \
         as the brake loses air (0 mm: tight; a fault from 0.5 mm); the release orifice is the diameter of the \
         restriction the release air flows through into the chamber (1.25 mm nominal; blocked below 1.0 mm); the \
         supply is the pressure of the air feeding the brake, in bar above atmosphere (7.7 bar g nominal; low below \
         7.2 bar g)."
            .to_owned(),
    ));
    sections.push(summary);

    let mut curves = Section::new("curves", "Release curves: measured pressure against the twin");
    curves.push(Block::Para(
        "Each plot is one release: the chamber pressure the transducer measured after the release command, and the \
         pressure a healthy brake of this type (the twin) would reach with the same valve command. A leak holds the \
         measured pressure below the twin's at the end; a blocked orifice makes it rise more slowly; a low supply \
         levels it off lower. Gaps in the measured line are samples the monitor found faulty."
            .to_owned(),
    ));
    let mut any_curve = false;
    for (r, why) in curve_releases(s, &rows) {
        let Some(curve) = db.curve(r.id)? else { continue };
        if let Some(svg) = curve_chart(&curve) {
            curves.push(Block::Figure {
                svg,
                caption: format!("Release {} ({why}): {}; {}.", r.release_no, verdict_sentence(r), estimates_words(r)),
            });
            any_curve = true;
        }
    }
    if !any_curve {
        curves.push(Block::Para(
            "No pressure curve is stored for this locomotive: its releases came only from cab CAN logs (which carry \
             reports, not pressures) or were stored before curves were kept; ingesting its recorded traces again \
             stores them."
                .to_owned(),
        ));
    }
    sections.push(curves);

    let mut trends = Section::new("trends", "Trends of the estimates");
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
            trends.push(Block::Figure {
                svg,
                caption: format!("Estimated {} of every diagnosed release.{slope}{eta}", parameter_words(p)),
            });
            any = true;
        }
    }
    if !any {
        trends.push(Block::Para("No estimates stored for this locomotive.".to_owned()));
    }
    sections.push(trends);

    let mut can = Section::new("can", "Fault reports received by the cab");
    can.push(Block::Para(format!(
        "The fault reports the monitor sent on the CAN bus for the latest releases, decoded as the cab display decodes \
         them (checksum, message counter, heartbeat). Release: the locomotive's release number in this history; \
         counter: the release number the frame carries (it counts power-ups and release commands, and wraps at 64). \
         A report is current when a heartbeat of the monitor vouched for it, stale when none came on time; a lost \
         report is one the monitor sent that the cab never received. Up to {CAN_RELEASES_SHOWN} releases are shown."
    )));
    let mut table = Table::new(
        format!("Decoded fault reports of {}", s.locomotive),
        &[
            "Release",
            "Counter",
            "Time since command, s",
            "Verdict",
            "Calibrated confidence",
            "Supply, bar g",
            "Leak, mm",
            "Release completed",
            "Freshness",
        ],
    );
    let mut shown = 0;
    let mut with_reports: Vec<(&StoredRelease, Vec<StoredCanReport>)> = Vec::new();
    for r in stored.iter().rev() {
        if shown == CAN_RELEASES_SHOWN {
            break;
        }
        let reports = db.can_reports(r.id)?;
        if !reports.is_empty() {
            with_reports.push((r, reports));
            shown += 1;
        }
    }
    for (r, reports) in with_reports.iter().rev() {
        for c in reports {
            table.row(can_row(r, c));
        }
    }
    if table.rows.is_empty() {
        can.push(Block::Para(
            "No decoded fault reports are stored for this locomotive (stored before reports were kept; ingest its \
             traces or cab logs again)."
                .to_owned(),
        ));
    } else {
        can.push(Block::Table(table));
    }
    sections.push(can);

    Ok(Page {
        title: format!("Locomotive {}", s.locomotive),
        subtitle: "Parking brake: release curves, trends and the reports the cab received".to_owned(),
        sections,
    })
}

/// Section ids every locomotive page has.
pub const LOCOMOTIVE_SECTIONS: [&str; 4] = ["summary", "curves", "trends", "can"];

/// The fleet section and every locomotive's page (file name, checked HTML), the pages linking
/// back to `index`.
pub fn fleet_pages(db: &FleetDb, rule: &WarningRule, index: &str) -> Result<(Section, Vec<(String, String)>)> {
    let statuses = status(db, rule)?;
    let names = page_names(&statuses);
    let section = fleet_section(db, rule, &statuses, &names)?;
    let mut pages = Vec::new();
    for (s, name) in statuses.iter().zip(&names) {
        let html = render(&locomotive_page(db, rule, s, index)?);
        check(&html, &LOCOMOTIVE_SECTIONS)
            .map_err(|e| anyhow::anyhow!("the page of {} failed its check: {e}", s.locomotive))?;
        pages.push((name.clone(), html));
    }
    Ok((section, pages))
}

/// The fleet page (`index.html`): the fleet table.
pub fn html(db: &FleetDb, rule: &WarningRule) -> Result<String> {
    let statuses = status(db, rule)?;
    let names = page_names(&statuses);
    let page = Page {
        title: "Parking brake fleet".to_owned(),
        subtitle: "Per-locomotive verdicts, estimates, trends and early warnings from the stored releases".to_owned(),
        sections: vec![fleet_section(db, rule, &statuses, &names)?],
    };
    let html = render(&page);
    check(&html, &["fleet"]).map_err(|e| anyhow::anyhow!("the fleet page failed its check: {e}"))?;
    Ok(html)
}

/// Writes `DIR/index.html` and every locomotive's page next to it; returns the index's path.
pub fn write(db: &FleetDb, out: &Path, rule: &WarningRule) -> Result<PathBuf> {
    let index = html(db, rule)?;
    let (_, pages) = fleet_pages(db, rule, "index.html")?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    for (name, page) in &pages {
        let path = out.join(name);
        std::fs::write(&path, page).with_context(|| format!("cannot write {}", path.display()))?;
    }
    let path = out.join("index.html");
    std::fs::write(&path, index).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path)
}
