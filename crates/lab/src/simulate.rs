//! Noise-free simulation of one release with either engine, sampled at 100 Hz.

use crate::reference::ReferenceTwin;
use pbm::twin::SAMPLE_PERIOD_S;
use pbm::{ParamError, Twin, TwinParams};

/// Which implementation of the twin to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Engine {
    /// The fixed-point core twin (what the controller runs).
    Fixed,
    /// The independent f64 reference.
    F64,
}

/// One 100 Hz sample of a simulated release.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimSample {
    /// Time since the release command, s.
    pub t_s: f64,
    /// Chamber pressure, bar g.
    pub p_bar: f64,
    /// Piston travel, mm.
    pub x_mm: f64,
}

/// Number of 100 Hz samples in `duration_s` seconds.
pub fn sample_count(duration_s: f64) -> usize {
    (duration_s / SAMPLE_PERIOD_S).round().max(0.0) as usize
}

/// Simulates a release of `duration_s` seconds (valve open from t = 0). Sample `i` is the
/// state at `t = i · 10 ms`, so the first row is the vented chamber at the release command.
pub fn simulate(engine: Engine, params: &TwinParams, duration_s: f64) -> Result<Vec<SimSample>, ParamError> {
    let n = sample_count(duration_s);
    let mut out = Vec::with_capacity(n);
    match engine {
        Engine::Fixed => {
            let mut twin = Twin::new(params)?;
            let mut sample = twin_sample_now(&twin);
            for i in 0..n {
                out.push(SimSample { t_s: i as f64 * SAMPLE_PERIOD_S, p_bar: sample.0, x_mm: sample.1 });
                let s = twin.update(true);
                sample = (s.pressure.to_bar_g().0, s.travel.to_mm());
            }
        }
        Engine::F64 => {
            let mut twin = ReferenceTwin::new(params)?;
            for i in 0..n {
                out.push(SimSample {
                    t_s: i as f64 * SAMPLE_PERIOD_S,
                    p_bar: twin.sensor_bar_g(),
                    x_mm: twin.state.x * 1e3,
                });
                twin.advance(SAMPLE_PERIOD_S, true);
            }
        }
    }
    Ok(out)
}

fn twin_sample_now(twin: &Twin) -> (f64, f64) {
    let s = twin.state();
    (s.p.to_bar_g().0, s.x.to_mm())
}

/// First time (s) the pressure reaches `level` bar g, linearly interpolated between samples.
pub fn time_to_reach(trace: &[SimSample], level: f64) -> Option<f64> {
    trace.windows(2).find(|w| w[0].p_bar < level && w[1].p_bar >= level).map(|w| {
        let f = (level - w[0].p_bar) / (w[1].p_bar - w[0].p_bar);
        w[0].t_s + f * (w[1].t_s - w[0].t_s)
    })
}

/// Pressure (bar g) when the piston travel first exceeds `travel_mm`.
pub fn pressure_at_travel(trace: &[SimSample], travel_mm: f64) -> Option<f64> {
    trace.iter().find(|s| s.x_mm > travel_mm).map(|s| s.p_bar)
}

/// First time (s) the piston reaches its end stop (`stroke_mm` within 1 µm).
pub fn time_at_end_stop(trace: &[SimSample], stroke_mm: f64) -> Option<f64> {
    trace.iter().find(|s| s.x_mm >= stroke_mm - 1e-3).map(|s| s.t_s)
}

/// Writes a trace as SPEC §7 CSV: metadata comments, then `t_s,p_bar,x_mm` rows (csv crate).
pub fn write_csv(w: &mut impl std::io::Write, trace: &[SimSample], meta: &[(&str, String)]) -> anyhow::Result<()> {
    pbm_io::trace::write_metadata(w, meta)?;
    let mut out = csv::Writer::from_writer(w);
    out.write_record(["t_s", "p_bar", "x_mm"])?;
    for s in trace {
        out.write_record([format!("{:.2}", s.t_s), format!("{:.6}", s.p_bar), format!("{:.4}", s.x_mm)])?;
    }
    out.flush()?;
    Ok(())
}

/// One noise-free release to simulate and where to write it.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulateOptions {
    /// Twin implementation.
    pub engine: Engine,
    /// The brake (supply, orifice, leak and the rest).
    pub params: TwinParams,
    /// Duration, s (0 < d ≤ 3600).
    pub duration_s: f64,
    /// Output file (`None`: standard output).
    pub out: Option<std::path::PathBuf>,
    /// Also write an SVG of the release (pressure from both engines, piston travel).
    pub plot: Option<std::path::PathBuf>,
}

impl Default for SimulateOptions {
    fn default() -> Self {
        Self { engine: Engine::Fixed, params: TwinParams::nominal(), duration_s: 60.0, out: None, plot: None }
    }
}

/// Refuses a duration outside (0, 3600] s (what `simulate` accepts from a user).
pub fn check_duration(duration_s: f64) -> anyhow::Result<()> {
    if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 3600.0) {
        anyhow::bail!("the duration must be in (0, 3600] s, got {duration_s}");
    }
    Ok(())
}

/// Simulates one release and writes its trace (and plot).
pub fn run(a: &SimulateOptions) -> anyhow::Result<()> {
    use anyhow::Context as _;
    check_duration(a.duration_s)?;
    let trace = simulate(a.engine, &a.params, a.duration_s).map_err(|e| anyhow::anyhow!("invalid parameters: {e}"))?;
    if let Some(path) = &a.plot {
        write_release_svg(path, &a.params, a.duration_s)?;
    }
    let engine = match a.engine {
        Engine::Fixed => "fixed-point twin",
        Engine::F64 => "f64 reference",
    };
    let meta = [
        ("source", format!("simulated release, {engine}")),
        ("orifice_mm", a.params.orifice.mm().to_string()),
        ("leak_mm", a.params.leak.mm().to_string()),
        ("supply_bar", a.params.supply.0.to_string()),
    ];
    match &a.out {
        Some(path) => {
            let f = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
            let mut w = std::io::BufWriter::new(f);
            write_csv(&mut w, &trace, &meta)?;
            std::io::Write::flush(&mut w).with_context(|| format!("cannot write {}", path.display()))?;
        }
        None => {
            let mut w = std::io::BufWriter::new(std::io::stdout().lock());
            write_csv(&mut w, &trace, &meta)?;
            std::io::Write::flush(&mut w)?;
        }
    }
    Ok(())
}

/// Writes an SVG of one release: chamber pressure from both engines and the piston travel.
pub fn write_release_svg(path: &std::path::Path, params: &TwinParams, duration_s: f64) -> anyhow::Result<()> {
    use pbm_report::chart::{write_line_chart, ChartLabels, Series, OKABE_ITO};
    let invalid = |e: ParamError| anyhow::anyhow!("invalid parameters: {e}");
    let fixed = simulate(Engine::Fixed, params, duration_s).map_err(invalid)?;
    let reference = simulate(Engine::F64, params, duration_s).map_err(invalid)?;
    let series = [
        Series {
            label: "pressure, f64 reference (bar g)",
            points: reference.iter().map(|s| (s.t_s, s.p_bar)).collect(),
            color: OKABE_ITO[7],
        },
        Series {
            label: "pressure, fixed-point twin (bar g)",
            points: fixed.iter().map(|s| (s.t_s, s.p_bar)).collect(),
            color: OKABE_ITO[0],
        },
        Series {
            label: "piston travel, fixed-point twin (cm)",
            points: fixed.iter().map(|s| (s.t_s, s.x_mm / 10.0)).collect(),
            color: OKABE_ITO[1],
        },
    ];
    let title = format!(
        "Spring brake release: orifice {:.2} mm, leak {:.2} mm, supply {:.2} bar g",
        params.orifice.mm(),
        params.leak.mm(),
        params.supply.0
    );
    write_line_chart(path, ChartLabels { title: &title, x: "time since release command (s)", y: "bar g / cm" }, &series)
}
