//! Trends of a locomotive's estimates over its releases, and the early warning.
//!
//! # The fault edges
//!
//! Taken from the SPEC §4 class ranges as the generator draws them
//! ([`pbm_lab::generate`]): a leak is a fault from [`LEAK_MM`]`.0` = 0.5 mm up, a release
//! orifice is blocked from [`BLOCK_MM`]`.1` = 1.0 mm down, the supply is low from
//! [`LOW_SUPPLY_BAR_G`]`.1` = 7.2 bar g down.
//!
//! # The warning rule
//!
//! Per locomotive and parameter, a one-sided CUSUM on the standardised estimate, in the
//! direction of the fault (leak up; orifice and supply down):
//!
//! - **baseline**: the first [`WarningRule::baseline`] releases with an estimate give the
//!   locomotive's own level μ (mean) and spread σ (sample standard deviation, not below
//!   [`WarningRule::sigma_floor`]). Per locomotive, because the manufacturing spread of SPEC §5
//!   moves the estimates more between locomotives than a slowly starting fault does. Mean and
//!   standard deviation rather than median and MAD: the healthy leak estimate is mostly exactly
//!   0 with a tail of small values, for which the MAD is 0 and would call every tail value an
//!   alarm.
//! - **followed releases**: only releases the monitor named a class for
//!   ([`ReleaseRecord::diagnosed`]); a release declined for a sensor fault, as unfamiliar or too
//!   short, or closed without a diagnosis, is not evidence about the brake.
//! - **statistic**: z = d/σ for the shift toward the edge d = ±(x − μ), less a dead band of the
//!   physical allowance a (d − a beyond it, 0 inside it, d itself away from the edge); a =
//!   [`WarningRule::min_shift`] (supply: the regulator's setting tolerance
//!   [`SUPPLY_SETTING_TOLERANCE_BAR`]; leak [`LEAK_ALLOWANCE_MM`], orifice
//!   [`ORIFICE_ALLOWANCE_MM`]), clipped to ±[`WarningRule::z_clip`]
//!   so one wild release cannot raise an alarm alone; S₀ = 0, Sₙ = max(0, Sₙ₋₁ + zₙ − k).
//! - **alarm**: a release with Sₙ > h. Defaults k = 0.5 (tuned to a shift of 1 σ), h = 12.
//! - **evidence**: from the onset (first release of the run of S > 0 that ended in the alarm):
//!   drifting, step or intermittent ([`EvidenceKind`]).
//! - **clearing**: after [`WarningRule::clear_after`] = 10 consecutive followed releases inside
//!   the baseline band (none more than [`SHIFTED_SIGMA`] σ beyond the allowance toward the
//!   edge) the warning clears and S restarts from 0; a later shift raises a new warning.
//!
//! False-alarm rate. For independent Gaussian estimates with a known baseline the in-control
//! average run length of this CUSUM (Siegmund's approximation, [`arl0`]) is ≈ 10⁶ releases per
//! parameter, far below one false warning per 1000 releases. That model is optimistic: the
//! baseline is estimated from 20 releases and the healthy leak estimate is mostly 0 with a long
//! tail (at h = 8, where the model promises 0.05 per 1000 per parameter, 1.5 per 1000 were
//! measured on healthy simulated locomotives). h = 12 was chosen on one healthy fleet (seed 202:
//! 0 false warnings in 2600 releases) and the rate is *stated as measured* on fleets not used
//! for the choice: at most 2 false warnings per 1000 healthy releases is the asserted bound
//! (`tests/warning.rs`; figures in the README, [`crate::measure`]).

use crate::record::ReleaseRecord;
pub use pbm_lab::generate::{BLOCK_MM, LEAK_MM, LOW_SUPPLY_BAR_G};

/// A parameter the estimator follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Parameter {
    /// Leak as an equivalent orifice, mm: a fault when it grows.
    Leak,
    /// Release orifice, mm: a fault when it shrinks.
    Orifice,
    /// Supply pressure, bar g: a fault when it falls.
    Supply,
}

impl Parameter {
    /// All three, in display order.
    pub const ALL: [Self; 3] = [Self::Leak, Self::Orifice, Self::Supply];

    /// Name in words.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Leak => "leak",
            Self::Orifice => "orifice",
            Self::Supply => "supply",
        }
    }

    /// Unit of the estimate.
    pub const fn unit(self) -> &'static str {
        match self {
            Self::Leak | Self::Orifice => "mm",
            Self::Supply => "bar g",
        }
    }

    /// The SPEC §4 fault edge of the parameter.
    pub const fn threshold(self) -> f64 {
        match self {
            Self::Leak => LEAK_MM.0,
            Self::Orifice => BLOCK_MM.1,
            Self::Supply => LOW_SUPPLY_BAR_G.1,
        }
    }

    /// +1 when the fault lies above (leak), −1 when below (orifice, supply).
    pub const fn direction(self) -> f64 {
        match self {
            Self::Leak => 1.0,
            Self::Orifice | Self::Supply => -1.0,
        }
    }

    /// The estimate of this parameter in a release.
    pub fn of(self, r: &ReleaseRecord) -> Option<f64> {
        match self {
            Self::Leak => r.leak_mm,
            Self::Orifice => r.orifice_mm,
            Self::Supply => r.supply_bar_g,
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// The regulator's setting tolerance, bar (SPEC: ±0.03 bar). A supply estimate that moved by
/// less than this from the locomotive's baseline is within what the regulator itself (or a
/// transducer zero offset of −0.01 … −0.02 bar) can do and is not evidence of a supply fault.
pub const SUPPLY_SETTING_TOLERANCE_BAR: f64 = 0.03;

/// Leak allowance, mm: the healthy leak estimate is mostly 0 with a tail of small values; on 80
/// healthy `generate` locomotives (10 400 releases) the tail alone raised 6 leak warnings
/// (shifts of ≈ +0.13 mm on a few releases) without an allowance and none with this one. It
/// costs 4–9 releases of lead time on the slow-leak scenario (README).
pub const LEAK_ALLOWANCE_MM: f64 = 0.05;

/// Release orifice allowance, mm: a transducer zero offset still within what the plausibility
/// screen accepts moved the orifice estimate by ≈ −0.011 mm (a tester's offset drift to
/// +0.15 bar, before the monitor stopped diagnosing), which raised an orifice warning. It costs
/// ≈ 3 releases of lead time on the clogging scenario.
pub const ORIFICE_ALLOWANCE_MM: f64 = 0.015;

/// The CUSUM early-warning rule (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarningRule {
    /// Releases (with an estimate) that set a locomotive's baseline.
    pub baseline: usize,
    /// Reference value k, in σ.
    pub k: f64,
    /// Decision interval h, in σ.
    pub h: f64,
    /// Largest |z| one release contributes.
    pub z_clip: f64,
    /// Smallest σ per parameter (leak mm, orifice mm, supply bar): below the estimator's
    /// resolution a baseline's spread means nothing.
    pub sigma_floor: [f64; 3],
    /// Per parameter, the physical shift toward the edge that is not evidence of a fault (in the
    /// parameter's unit): the CUSUM only accumulates what lies beyond it (supply:
    /// [`SUPPLY_SETTING_TOLERANCE_BAR`]).
    pub min_shift: [f64; 3],
    /// A raised warning clears after this many consecutive followed releases back at the
    /// baseline (none of them shifted: each within [`SHIFTED_SIGMA`] σ of the baseline level,
    /// beyond the allowance); the sum then restarts from 0.
    pub clear_after: usize,
}

impl Default for WarningRule {
    fn default() -> Self {
        Self {
            baseline: 20,
            k: 0.5,
            h: 12.0,
            z_clip: 4.0,
            sigma_floor: [0.01, 0.005, 0.01],
            min_shift: [LEAK_ALLOWANCE_MM, ORIFICE_ALLOWANCE_MM, SUPPLY_SETTING_TOLERANCE_BAR],
            clear_after: 10,
        }
    }
}

impl WarningRule {
    /// In-control average run length (releases between false alarms) of this rule per
    /// parameter, for independent Gaussian estimates with a known baseline ([`arl0`]).
    pub fn arl0(&self) -> f64 {
        arl0(self.k, self.h)
    }
}

/// Siegmund's approximation of a one-sided CUSUM's in-control average run length, for
/// standard normal increments, reference `k` and decision interval `h` (in σ):
/// ARL₀ ≈ (e^{2kb} − 2kb − 1) / (2k²), b = h + 1.166.
pub fn arl0(k: f64, h: f64) -> f64 {
    let b = h + 1.166;
    let a = 2.0 * k * b;
    (a.exp() - a - 1.0) / (2.0 * k * k)
}

/// A parameter's baseline on one locomotive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Baseline {
    /// Level μ (mean of the baseline releases).
    pub mean: f64,
    /// Spread σ (sample standard deviation, floored).
    pub sigma: f64,
}

/// The baseline of `values` (the first `rule.baseline` of them); `None` with fewer.
pub fn baseline(values: &[f64], p: Parameter, rule: &WarningRule) -> Option<Baseline> {
    if rule.baseline < 2 || values.len() < rule.baseline {
        return None;
    }
    let b = &values[..rule.baseline];
    let n = b.len() as f64;
    let mean = b.iter().sum::<f64>() / n;
    let var = b.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let sigma = var.sqrt().max(rule.sigma_floor[p.index()]);
    Some(Baseline { mean, sigma })
}

/// What the estimates did between a warning's onset and its end (cleared, or the latest
/// release).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EvidenceKind {
    /// The estimate moves toward the edge release after release (slope toward the edge at least
    /// twice its standard error).
    Drifting,
    /// The estimate jumped and stays shifted, without a significant trend.
    Step,
    /// Only some releases are shifted (fewer than [`INTERMITTENT_FRACTION`] of them).
    Intermittent,
}

/// A release counts as shifted when it lies this many σ beyond the allowance toward the edge
/// (outside the baseline's ± 2 σ band).
pub const SHIFTED_SIGMA: f64 = 2.0;

/// Below this fraction of shifted releases since the onset, the evidence is intermittent.
pub const INTERMITTENT_FRACTION: f64 = 0.6;

/// The evidence behind a warning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Evidence {
    /// Drifting, step or intermittent.
    pub kind: EvidenceKind,
    /// Followed releases from the onset to the end.
    pub releases: usize,
    /// Of those, releases shifted toward the edge (more than [`SHIFTED_SIGMA`] beyond the
    /// allowance).
    pub shifted: usize,
    /// Mean shift of the shifted releases from the baseline level (parameter unit, signed).
    pub shift: f64,
    /// Least-squares slope over those releases, unit per release.
    pub slope: f64,
    /// Its standard error (`NaN` with fewer than 3 releases).
    pub slope_se: f64,
    /// Release number where the step happened: the first of three shifted releases in a row
    /// (else the first shifted one); meaningful for [`EvidenceKind::Step`].
    pub step_release_no: i64,
}

/// An early warning: a parameter of a locomotive shifted toward its fault edge.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    /// The parameter.
    pub parameter: Parameter,
    /// Index (in the releases given) of the release that raised it.
    pub release_index: usize,
    /// That release's number.
    pub release_no: i64,
    /// Release number where the shift began: the first release of the cumulative sum's run
    /// that ended in the alarm.
    pub onset_release_no: i64,
    /// The baseline it moved from.
    pub baseline: Baseline,
    /// The estimate at that release.
    pub value: f64,
    /// What the estimates did from the onset to the end of the warning.
    pub evidence: Evidence,
    /// Release number at which the warning cleared (`None`: still raised).
    pub cleared_release_no: Option<i64>,
}

impl Warning {
    /// The warning in words, for the status line and the fleet page.
    pub fn describe(&self) -> String {
        let p = self.parameter;
        let e = &self.evidence;
        let edge = format!("{:.1} {}", p.threshold(), p.unit());
        let se = if e.slope_se.is_finite() { format!(" ± {:.4}", e.slope_se) } else { String::new() };
        let trend = format!("trend {:+.4}{se} {}/release", e.slope, p.unit());
        let what = match e.kind {
            EvidenceKind::Drifting => {
                format!("{} drifting toward {edge} since release {}", p.name(), self.onset_release_no)
            }
            EvidenceKind::Step => format!(
                "{} stepped {:+.3} {} toward {edge} at release {}",
                p.name(),
                e.shift,
                p.unit(),
                e.step_release_no.max(self.onset_release_no)
            ),
            EvidenceKind::Intermittent => format!(
                "{} intermittently toward {edge}: {} of {} releases since release {} shifted {:+.3} {}",
                p.name(),
                e.shifted,
                e.releases,
                self.onset_release_no,
                e.shift,
                p.unit()
            ),
        };
        match self.cleared_release_no {
            None => format!("{what} (warned at release {}); {trend}", self.release_no),
            Some(c) => format!("{what} (warned at release {}) cleared at release {c}", self.release_no),
        }
    }
}

/// A parameter's releases the trends follow: those the monitor named a class for
/// ([`ReleaseRecord::diagnosed`]) with an estimate, as (index in `records`, estimate).
pub fn followed(records: &[ReleaseRecord], p: Parameter) -> Vec<(usize, f64)> {
    records.iter().enumerate().filter(|(_, r)| r.diagnosed()).filter_map(|(i, r)| p.of(r).map(|v| (i, v))).collect()
}

/// The CUSUM of one parameter over `records` (timeline order): its baseline, its path (per
/// followed release after the baseline: index in `records`, Sₙ; the sum restarts at 0 when a
/// warning clears) and every warning raised, in order.
pub fn track(
    records: &[ReleaseRecord],
    p: Parameter,
    rule: &WarningRule,
) -> (Option<Baseline>, Vec<(usize, f64)>, Vec<Warning>) {
    let with = followed(records, p);
    let values: Vec<f64> = with.iter().map(|&(_, v)| v).collect();
    let Some(b) = baseline(&values, p, rule) else { return (None, Vec::new(), Vec::new()) };
    let allowance = rule.min_shift[p.index()];
    // How far a release lies toward the edge, in σ, with a dead band of the allowance: a shift
    // toward the edge counts only beyond it, one away from the edge counts as it is (so the
    // allowance does not make healthy releases wipe out an intermittent fault).
    let excess = |v: f64| {
        let d = p.direction() * (v - b.mean);
        (if d > allowance {
            d - allowance
        } else if d > 0.0 {
            0.0
        } else {
            d
        }) / b.sigma
    };
    let mut s = 0.0f64;
    let mut path = Vec::new();
    let mut out = Vec::new();
    let mut run_start = rule.baseline;
    // (position in `with` of the alarm, of the onset), consecutive calm releases.
    let mut active: Option<(usize, usize)> = None;
    let mut calm = 0usize;
    let finish = |alarm: usize, onset: usize, end: usize, cleared: bool| {
        let (i, v) = with[alarm];
        Warning {
            parameter: p,
            release_index: i,
            release_no: records[i].release_no,
            onset_release_no: records[with[onset].0].release_no,
            baseline: b,
            value: v,
            // The evidence is what the estimates did while shifted: a cleared warning's calm
            // releases at the end are left out.
            evidence: evidence(
                records,
                &with[onset..=if cleared { end.saturating_sub(rule.clear_after).max(onset) } else { end }],
                p,
                &b,
                rule,
            ),
            cleared_release_no: cleared.then(|| records[with[end].0].release_no),
        }
    };
    for (j, &(i, v)) in with.iter().enumerate().skip(rule.baseline) {
        let inc = excess(v).clamp(-rule.z_clip, rule.z_clip) - rule.k;
        s = (s + inc).max(0.0);
        match active {
            None => {
                if s > rule.h {
                    active = Some((j, run_start));
                    calm = 0;
                } else if s == 0.0 {
                    run_start = j + 1;
                }
            }
            Some((alarm, onset)) => {
                calm = if excess(v) <= SHIFTED_SIGMA { calm + 1 } else { 0 };
                if calm >= rule.clear_after {
                    out.push(finish(alarm, onset, j, true));
                    active = None;
                    s = 0.0;
                    run_start = j + 1;
                }
            }
        }
        path.push((i, s));
    }
    if let Some((alarm, onset)) = active {
        out.push(finish(alarm, onset, with.len() - 1, false));
    }
    (Some(b), path, out)
}

/// What the followed releases `pts` (onset to end of a warning) show.
fn evidence(
    records: &[ReleaseRecord],
    pts: &[(usize, f64)],
    p: Parameter,
    b: &Baseline,
    rule: &WarningRule,
) -> Evidence {
    let allowance = rule.min_shift[p.index()];
    let shifted: Vec<f64> = pts
        .iter()
        .map(|&(_, v)| v)
        .filter(|&v| (p.direction() * (v - b.mean) - allowance) / b.sigma > SHIFTED_SIGMA)
        .collect();
    let shift =
        if shifted.is_empty() { 0.0 } else { shifted.iter().map(|v| v - b.mean).sum::<f64>() / shifted.len() as f64 };
    let xy: Vec<(f64, f64)> = pts.iter().map(|&(i, v)| (records[i].release_no as f64, v)).collect();
    let (slope, slope_se) = line(&xy);
    let n = pts.len();
    // A step (two levels, best split) against a line: whichever leaves the smaller residual.
    let sse_line = {
        let mx = xy.iter().map(|p| p.0).sum::<f64>() / n as f64;
        let my = xy.iter().map(|p| p.1).sum::<f64>() / n as f64;
        xy.iter().map(|p| (p.1 - (my + slope * (p.0 - mx))).powi(2)).sum::<f64>()
    };
    let (sse_step, _) = (1..n)
        .map(|m| {
            let sse = |part: &[(f64, f64)]| {
                let mean = part.iter().map(|p| p.1).sum::<f64>() / part.len() as f64;
                part.iter().map(|p| (p.1 - mean).powi(2)).sum::<f64>()
            };
            (sse(&xy[..m]) + sse(&xy[m..]), m)
        })
        .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a });
    // Where the step is: the first of three shifted releases in a row (a lone outlier of the
    // healthy tail is not the step), else the first shifted release, else the onset.
    let is_shifted: Vec<bool> =
        pts.iter().map(|&(_, v)| (p.direction() * (v - b.mean) - allowance) / b.sigma > SHIFTED_SIGMA).collect();
    let first = is_shifted
        .windows(3)
        .position(|w| w.iter().all(|&x| x))
        .or_else(|| is_shifted.iter().position(|&x| x))
        .unwrap_or(0);
    let step_release_no = pts.get(first).map_or(0, |&(i, _)| records[i].release_no);
    let kind = if n >= 5 && slope * p.direction() > 0.0 && slope.abs() >= 2.0 * slope_se && sse_line <= sse_step {
        EvidenceKind::Drifting
    } else if n >= 6 && (shifted.len() as f64) < INTERMITTENT_FRACTION * n as f64 {
        EvidenceKind::Intermittent
    } else {
        EvidenceKind::Step
    };
    Evidence { kind, releases: n, shifted: shifted.len(), shift, slope, slope_se, step_release_no }
}

/// Least-squares slope and its standard error (`NaN` with fewer than 3 points).
fn line(pts: &[(f64, f64)]) -> (f64, f64) {
    let n = pts.len();
    if n == 0 {
        return (0.0, f64::NAN);
    }
    let nf = n as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / nf;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / nf;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let se = if n >= 3 && sxx > 0.0 {
        let sse: f64 = pts.iter().map(|p| (p.1 - (my + slope * (p.0 - mx))).powi(2)).sum();
        (sse / (nf - 2.0) / sxx).sqrt()
    } else {
        f64::NAN
    };
    (slope, se)
}

/// The CUSUM path of one parameter over `records` (see [`track`]).
pub fn cusum(records: &[ReleaseRecord], p: Parameter, rule: &WarningRule) -> (Option<Baseline>, Vec<(usize, f64)>) {
    let (b, path, _) = track(records, p, rule);
    (b, path)
}

/// Every warning of one locomotive's releases (timeline order), raised and cleared, parameter
/// by parameter.
pub fn episodes(records: &[ReleaseRecord], rule: &WarningRule) -> Vec<Warning> {
    Parameter::ALL.into_iter().flat_map(|p| track(records, p, rule).2).collect()
}

/// The first alarm of every parameter of one locomotive's releases (timeline order), whether
/// it has cleared since or not.
pub fn warnings(records: &[ReleaseRecord], rule: &WarningRule) -> Vec<Warning> {
    Parameter::ALL.into_iter().filter_map(|p| track(records, p, rule).2.into_iter().next()).collect()
}

/// The warnings raised now (not cleared) of one locomotive's releases.
pub fn active_warnings(records: &[ReleaseRecord], rule: &WarningRule) -> Vec<Warning> {
    episodes(records, rule).into_iter().filter(|w| w.cleared_release_no.is_none()).collect()
}

/// A parameter's trend over a locomotive's latest releases: least-squares line of the
/// estimate against the release number, with its uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trend {
    /// Releases with an estimate in the window.
    pub n: usize,
    /// The latest estimate.
    pub latest: f64,
    /// Slope, unit per release.
    pub slope: f64,
    /// Standard error of the slope (`NaN` with fewer than 3 points).
    pub slope_se: f64,
    /// The line's value at the latest release.
    pub fitted: f64,
    /// Releases until the line reaches the fault edge, when it heads there at a slope at least
    /// twice its standard error.
    pub releases_to_edge: Option<f64>,
}

/// Releases the trend line is fitted over.
pub const TREND_WINDOW: usize = 30;

/// The trend of `p` over the last [`TREND_WINDOW`] followed releases ([`followed`]).
pub fn trend(records: &[ReleaseRecord], p: Parameter) -> Option<Trend> {
    let pts: Vec<(f64, f64)> =
        followed(records, p).into_iter().map(|(i, v)| (records[i].release_no as f64, v)).collect();
    let pts = &pts[pts.len().saturating_sub(TREND_WINDOW)..];
    let &(x_last, latest) = pts.last()?;
    let n = pts.len();
    let nf = n as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / nf;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / nf;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let fitted = my + slope * (x_last - mx);
    let slope_se = if n >= 3 && sxx > 0.0 {
        let sse: f64 = pts.iter().map(|p| (p.1 - (my + slope * (p.0 - mx))).powi(2)).sum();
        (sse / (nf - 2.0) / sxx).sqrt()
    } else {
        f64::NAN
    };
    let gap = p.threshold() - fitted;
    let heading = slope * p.direction() > 0.0 && gap * p.direction() > 0.0;
    let releases_to_edge = (heading && slope.abs() >= 2.0 * slope_se).then(|| gap / slope);
    Some(Trend { n, latest, slope, slope_se, fitted, releases_to_edge })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Source;

    fn rec(i: i64, leak: f64) -> ReleaseRecord {
        ReleaseRecord {
            locomotive: "loco-01".into(),
            source: Source::Trace,
            origin: "x".into(),
            release_key: i.to_string(),
            release_no: i,
            time_s: None,
            verdict: Some(pbm::report::Verdict::Class { class: pbm::FaultClass::Normal, confidence_pct: 99 }),
            orifice_mm: Some(1.25),
            leak_mm: Some(leak),
            supply_bar_g: Some(7.7),
            label: None,
            content_hash: None,
            numbered: true,
            detail: Default::default(),
        }
    }

    #[test]
    fn arl0_matches_the_tables() {
        // Montgomery's tabular (two-sided) CUSUM, k = 0.5: h = 4 → 168, h = 5 → 465; each
        // one-sided half alarms half as often.
        assert!((arl0(0.5, 4.0) - 2.0 * 168.0).abs() < 6.0, "{}", arl0(0.5, 4.0));
        assert!((arl0(0.5, 5.0) - 2.0 * 465.0).abs() < 16.0, "{}", arl0(0.5, 5.0));
        assert!(WarningRule::default().arl0() > 1e6);
    }

    #[test]
    fn a_steady_level_never_warns_and_a_ramp_does() {
        let rule = WarningRule::default();
        let flat: Vec<_> = (0..200).map(|i| rec(i, 0.1 + 0.01 * ((i * 7) % 5) as f64)).collect();
        assert!(warnings(&flat, &rule).is_empty());
        let ramp: Vec<_> =
            (0..200).map(|i| rec(i, 0.1 + 0.01 * ((i * 7) % 5) as f64 + 0.004 * (i - 50).max(0) as f64)).collect();
        let w = warnings(&ramp, &rule);
        assert_eq!(w.len(), 1);
        assert_eq!(w[0].parameter, Parameter::Leak);
        assert!(w[0].release_no > 50 && w[0].release_no < 100, "{:?}", w[0]);
        let t = trend(&ramp, Parameter::Leak).unwrap();
        assert!((t.slope - 0.004).abs() < 0.001);
        assert!(t.releases_to_edge.is_none(), "already past the edge: {t:?}");
    }
}
