//! `pbm._pbm`: the Python extension module of the parking brake monitor (the package `pbm`
//! re-exports it; `python/pbm/__init__.pyi` has the types).
//!
//! Every function is a thin call into the Rust crates the CLI uses (`pbm`, `pbm-io`, `pbm-lab`,
//! `pbm-fleet`): the Python results are those of `host-sim`, bit for bit, because the code is the
//! same. Inputs are checked here (dtype, shape, range, finiteness) and every error reaches Python
//! as a `ValueError` (bad input) or `OSError` (a file that cannot be read or written) carrying the
//! Rust message; nothing panics across the FFI boundary on bad input.

use numpy::{PyArray1, PyReadonlyArray1, PyUntypedArrayMethods};
use pbm::mechanism::Mechanism;
use pbm::TwinParams;
use pbm_lab::can_cmd::{confidence_pct, decode_log, verdict_label, CabDisplay, DecodeFormat};
use pbm_lab::replay::{
    release_identity, replay_samples, write_can_log_to, ReplayError, ReplaySample, Summariser, PERIOD_TOLERANCE_S,
};
use pbm_lab::simulate::{simulate as simulate_release, Engine};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;

/// A `ValueError` with the full chain of an error's messages (what `host-sim` prints).
fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// `anyhow` error → `OSError` when it is an I/O failure at its root, else `ValueError`.
fn anyhow_error(e: anyhow::Error) -> PyErr {
    let text = format!("{e:#}");
    if e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some()) {
        PyOSError::new_err(text)
    } else {
        PyValueError::new_err(text)
    }
}

/// Largest count of the 12-bit ADC.
const ADC_MAX: u16 = 4095;

/// The nominal sample clock (s) the monitor assumes: sample `i` at `i` × 10 ms.
fn default_times(n: usize) -> Vec<f64> {
    (0..n).map(|i| i as f64 * pbm::twin::SAMPLE_PERIOD_S).collect()
}

/// Checks sample times as the trace reader does: finite and 10 ms apart within ±1 ms.
fn check_times(t_s: &[f64]) -> PyResult<()> {
    if let Some(i) = t_s.iter().position(|t| !t.is_finite()) {
        return Err(value_error(format!("t_s[{i}] is {} (sample times must be finite)", t_s[i])));
    }
    for (i, w) in t_s.windows(2).enumerate() {
        let dt = w[1] - w[0];
        if (dt - pbm::twin::SAMPLE_PERIOD_S).abs() > PERIOD_TOLERANCE_S {
            return Err(value_error(format!(
                "t_s[{}]: sample interval {dt} s, expected {} s ± {} s (the monitor runs at 100 Hz)",
                i + 1,
                pbm::twin::SAMPLE_PERIOD_S,
                PERIOD_TOLERANCE_S
            )));
        }
    }
    Ok(())
}

/// `None` → NaN, for numpy columns.
fn nan_of(v: Option<f32>) -> f64 {
    v.map_or(f64::NAN, f64::from)
}

/// Per-sample columns of a replay (what the results CSV of `host-sim replay --out` holds).
#[derive(Default)]
struct Columns {
    measured_bar: Vec<f64>,
    twin_bar: Vec<f64>,
    residual_bar: Vec<f64>,
    twin_travel_mm: Vec<f64>,
    sensor_fault: Vec<bool>,
    est_orifice_mm: Vec<f64>,
    est_leak_mm: Vec<f64>,
    est_supply_bar_g: Vec<f64>,
    est_plateau_bar_g: Vec<f64>,
}

impl Columns {
    fn push(&mut self, s: &ReplaySample) {
        self.measured_bar.push(s.measured_bar());
        self.twin_bar.push(s.twin_bar());
        self.residual_bar.push(s.residual_bar());
        self.twin_travel_mm.push(s.step.twin.travel.to_mm());
        self.sensor_fault.push(s.step.measured.is_err());
        let e = &s.step.estimates;
        self.est_orifice_mm.push(nan_of(e.orifice_mm));
        self.est_leak_mm.push(nan_of(e.leak_mm));
        self.est_supply_bar_g.push(nan_of(e.supply_bar_g));
        self.est_plateau_bar_g.push(nan_of(e.plateau_bar_g));
    }
}

/// Replays one release of ADC counts through the monitor pipeline the firmware runs (monitor,
/// diagnosis policy, CAN schedule), exactly as `host-sim replay TRACE --can-log LOG` does.
///
/// `adc` is a 1-D numpy uint16 array of 12-bit counts (0..=4095) sampled at 100 Hz from the
/// release command on. `t_s` (float64, same length) are the sample times, checked to be 10 ms
/// apart within ±1 ms like a trace file's; by default `i` × 10 ms. `locomotive` is the trace's
/// `locomotive` metadata (its trailing digits give the locomotive number in the CAN frames;
/// `"-"` when unknown, as the CLI uses), `earlier_releases` the number of recorded releases the
/// locomotive's monitor saw before this one (0 for a single trace).
///
/// Returns a dict: `diagnosis` (the verdict as the CLI's summary shows it, `"-"` if none was
/// closed), `verdict` (the DBC label, e.g. `air_leak`, or `None`), `confidence_pct` (float or
/// `None`), `samples`, `sensor_faults`, `nmse_pct`, `max_abs_residual_bar`, `final_bar`, the final
/// estimates `orifice_mm`, `leak_mm`, `supply_bar_g`, `plateau_bar_g` (float or `None`), the
/// per-sample float64 arrays `t_s`, `measured_bar`, `twin_bar`, `residual_bar` (NaN on a sensor
/// fault), `twin_travel_mm`, `est_orifice_mm`, `est_leak_mm`, `est_supply_bar_g`,
/// `est_plateau_bar_g` (NaN until estimated), the bool array `sensor_fault`, and `can_log`: the
/// CAN frames as candump lines (no newline), byte for byte the lines of the CLI's `--can-log`.
#[pyfunction]
#[pyo3(signature = (adc, t_s = None, locomotive = "-", earlier_releases = 0))]
fn replay<'py>(
    py: Python<'py>,
    adc: &Bound<'py, PyAny>,
    t_s: Option<&Bound<'py, PyAny>>,
    locomotive: &str,
    earlier_releases: u32,
) -> PyResult<Bound<'py, PyDict>> {
    let adc: PyReadonlyArray1<'py, u16> = adc.extract().map_err(|_| {
        let dtype = adc.getattr("dtype").map_or_else(|_| adc.get_type().to_string(), |d| d.to_string());
        value_error(format!("adc must be a 1-D numpy array of dtype uint16 (ADC counts), got {dtype}"))
    })?;
    if adc.len() == 0 {
        return Err(value_error("adc is empty: a release needs at least one sample"));
    }
    // `as_array` follows strides: a non-contiguous view (`adc[::2]`) is read, not refused.
    let counts: Vec<u16> = adc.as_array().iter().copied().collect();
    if let Some(i) = counts.iter().position(|&c| c > ADC_MAX) {
        return Err(value_error(format!("adc[{i}] = {} is outside the 12-bit range 0..={ADC_MAX}", counts[i])));
    }
    let times = match t_s {
        None => default_times(counts.len()),
        Some(t) => {
            let t: PyReadonlyArray1<'py, f64> =
                t.extract().map_err(|_| value_error("t_s must be a 1-D numpy array of dtype float64 (seconds)"))?;
            let t: Vec<f64> = t.as_array().iter().copied().collect();
            if t.len() != counts.len() {
                return Err(value_error(format!("t_s has {} samples, adc has {}", t.len(), counts.len())));
            }
            check_times(&t)?;
            t
        }
    };
    let identity = release_identity(locomotive, earlier_releases).map_err(value_error)?;
    let run = py.detach(|| {
        let mut columns = Columns::default();
        let mut summariser = Summariser::default();
        let samples = times.iter().copied().zip(counts.iter().copied()).map(Ok);
        let replayed = replay_samples(samples, true, identity, |s| {
            columns.push(s);
            summariser.push(s);
            Ok(())
        });
        let replayed = match replayed {
            Ok(r) => r,
            Err(ReplayError::Input(e)) => return Err(anyhow::Error::from(e)),
            Err(ReplayError::Output(e)) => return Err(e),
        };
        let mut log = Vec::new();
        write_can_log_to(&mut log, [&replayed])?;
        let summary = summariser.finish("<array>", "-", locomotive, replayed.diagnosis);
        Ok((columns, summary, log))
    });
    let (columns, summary, log) = run.map_err(anyhow_error)?;
    let out = PyDict::new(py);
    let verdict = summary.diagnosis.map(|r| r.verdict);
    out.set_item("diagnosis", summary.diagnosis.map_or_else(|| "-".to_owned(), |r| r.verdict.to_string()))?;
    out.set_item("verdict", verdict.as_ref().map(verdict_label))?;
    out.set_item("confidence_pct", verdict.as_ref().and_then(confidence_pct))?;
    out.set_item("samples", summary.samples)?;
    out.set_item("sensor_faults", summary.sensor_faults)?;
    out.set_item("nmse_pct", summary.nmse_pct)?;
    out.set_item("max_abs_residual_bar", summary.max_abs_residual_bar)?;
    out.set_item("final_bar", summary.final_bar)?;
    let last = summary.last.map(|l| l.estimates);
    out.set_item("orifice_mm", last.and_then(|e| e.orifice_mm).map(f64::from))?;
    out.set_item("leak_mm", last.and_then(|e| e.leak_mm).map(f64::from))?;
    out.set_item("supply_bar_g", last.and_then(|e| e.supply_bar_g).map(f64::from))?;
    out.set_item("plateau_bar_g", last.and_then(|e| e.plateau_bar_g).map(f64::from))?;
    out.set_item("t_s", PyArray1::from_vec(py, times))?;
    let Columns {
        measured_bar,
        twin_bar,
        residual_bar,
        twin_travel_mm,
        sensor_fault,
        est_orifice_mm,
        est_leak_mm,
        est_supply_bar_g,
        est_plateau_bar_g,
    } = columns;
    for (name, v) in [
        ("measured_bar", measured_bar),
        ("twin_bar", twin_bar),
        ("residual_bar", residual_bar),
        ("twin_travel_mm", twin_travel_mm),
        ("est_orifice_mm", est_orifice_mm),
        ("est_leak_mm", est_leak_mm),
        ("est_supply_bar_g", est_supply_bar_g),
        ("est_plateau_bar_g", est_plateau_bar_g),
    ] {
        out.set_item(name, PyArray1::from_vec(py, v))?;
    }
    out.set_item("sensor_fault", PyArray1::from_vec(py, sensor_fault))?;
    let text = String::from_utf8(log).map_err(value_error)?;
    out.set_item("can_log", PyList::new(py, text.lines())?)?;
    Ok(out)
}

/// Simulates one noise-free release (valve open from t = 0) at 100 Hz, as `host-sim simulate`
/// does: sample `i` is the state at `i` × 10 ms.
///
/// `engine` is `"fixed"` (the fixed-point core twin the controller runs) or `"f64"` (the
/// independent reference). `mechanisms` maps mechanism names (`pbm.MECHANISMS`, e.g.
/// `{"valve_lag": 0.05}`) to values in their units; they extend the nominal twin as in the audit.
/// Returns a dict of float64 arrays `t_s`, `p_bar` (chamber gauge pressure) and `x_mm` (piston
/// travel). Raises `ValueError` for parameters the twin refuses.
#[pyfunction]
#[pyo3(signature = (
    orifice_mm = TwinParams::NOMINAL_ORIFICE_MM,
    leak_mm = 0.0,
    supply_bar = TwinParams::NOMINAL_SUPPLY_BAR_G,
    duration_s = 60.0,
    engine = "fixed",
    mechanisms = None,
))]
fn simulate<'py>(
    py: Python<'py>,
    orifice_mm: f64,
    leak_mm: f64,
    supply_bar: f64,
    duration_s: f64,
    engine: &str,
    mechanisms: Option<std::collections::BTreeMap<String, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    let engine = match engine {
        "fixed" => Engine::Fixed,
        "f64" => Engine::F64,
        other => return Err(value_error(format!("engine must be \"fixed\" or \"f64\", got {other:?}"))),
    };
    pbm_lab::simulate::check_duration(duration_s).map_err(anyhow_error)?;
    let mut params =
        TwinParams::nominal().with_orifice_mm(orifice_mm).with_leak_mm(leak_mm).with_supply_bar_g(supply_bar);
    for (name, value) in mechanisms.unwrap_or_default() {
        let m = Mechanism::from_name(&name).ok_or_else(|| {
            let known: Vec<&str> = Mechanism::ALL.iter().map(|m| m.name()).collect();
            value_error(format!("unknown mechanism {name:?} (known: {})", known.join(", ")))
        })?;
        if !value.is_finite() {
            return Err(value_error(format!("mechanism {name}: value {value} is not finite")));
        }
        params.ext = params.ext.with(m, value);
    }
    let trace = py
        .detach(|| simulate_release(engine, &params, duration_s))
        .map_err(|e| value_error(format!("invalid parameters: {e}")))?;
    let out = PyDict::new(py);
    out.set_item("t_s", PyArray1::from_iter(py, trace.iter().map(|s| s.t_s)))?;
    out.set_item("p_bar", PyArray1::from_iter(py, trace.iter().map(|s| s.p_bar)))?;
    out.set_item("x_mm", PyArray1::from_iter(py, trace.iter().map(|s| s.x_mm)))?;
    Ok(out)
}

/// Decodes a candump log as the cab display of `host-sim can decode` shows it.
///
/// `log` is the log's text (one string) or a list of its lines. `status` also shows status
/// frames, `format` is `"text"` (display lines) or `"csv"` (one row per frame with physical
/// values), `codec_only` checks integrity only, not freshness. Returns a dict: `lines` (what the
/// CLI prints on stdout, one string per line), `summary` (its stderr summary line), and the counts
/// `frames`, `fault_reports`, `status_reports`, `flagged` (total), `lost_status`,
/// `lost_fault_reports`. Bad frames and lines are flagged in the output, not raised.
#[pyfunction]
#[pyo3(signature = (log, status = false, format = "text", codec_only = false))]
fn decode_can<'py>(
    py: Python<'py>,
    log: &Bound<'py, PyAny>,
    status: bool,
    format: &str,
    codec_only: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let text: String = if let Ok(s) = log.extract::<String>() {
        s
    } else if let Ok(lines) = log.extract::<Vec<String>>() {
        lines.iter().map(|l| format!("{}\n", l.trim_end_matches(['\r', '\n']))).collect()
    } else {
        return Err(value_error("log must be a str or a list of str (candump lines)"));
    };
    let format = match format {
        "text" => DecodeFormat::Text,
        "csv" => DecodeFormat::Csv,
        other => return Err(value_error(format!("format must be \"text\" or \"csv\", got {other:?}"))),
    };
    let (out, summary) = py
        .detach(|| -> std::io::Result<_> {
            let mut out = Vec::new();
            let mut display = CabDisplay::new(&mut out, status, format).codec_only(codec_only);
            decode_log(text.as_bytes(), &mut display)?;
            let summary = display.finish()?;
            Ok((out, summary))
        })
        .map_err(|e| PyOSError::new_err(e.to_string()))?;
    let lines = String::from_utf8(out).map_err(value_error)?;
    let d = PyDict::new(py);
    d.set_item("lines", PyList::new(py, lines.lines())?)?;
    d.set_item("summary", summary.to_string())?;
    d.set_item("frames", summary.frames)?;
    d.set_item("fault_reports", summary.fault_reports)?;
    d.set_item("status_reports", summary.status_reports)?;
    d.set_item("flagged", summary.flagged_total())?;
    d.set_item("lost_status", summary.lost_status)?;
    d.set_item("lost_fault_reports", summary.lost_fault_reports)?;
    Ok(d)
}

/// Reads a trace file (SPEC §7 CSV) with the reader the CLI uses.
///
/// Returns a dict: `t_s` (float64 array), `adc` (uint16 array; a `p_bar` trace through the
/// sensor map, no noise, as replay does), `p_bar` (float64 array; an ADC trace through the inverse
/// map), `kind` (`"adc"` or `"p_bar"`) and `meta` (the `# key: value` lines as a dict, file order).
#[pyfunction]
fn read_trace<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let trace = py.detach(|| pbm_io::trace::read_trace(&path)).map_err(|e| match e.kind {
        pbm_io::trace::TraceErrorKind::Io(_) => PyOSError::new_err(e.to_string()),
        _ => value_error(e),
    })?;
    let d = PyDict::new(py);
    d.set_item("t_s", PyArray1::from_slice(py, &trace.t_s))?;
    d.set_item("adc", PyArray1::from_vec(py, trace.adc_counts()))?;
    d.set_item("p_bar", PyArray1::from_vec(py, trace.pressures_bar()))?;
    d.set_item(
        "kind",
        match trace.samples.kind() {
            pbm_io::trace::TraceKind::Adc => "adc",
            pbm_io::trace::TraceKind::PressureBar => "p_bar",
        },
    )?;
    let meta = PyDict::new(py);
    for (k, v) in &trace.metadata {
        meta.set_item(k, v)?;
    }
    d.set_item("meta", meta)?;
    Ok(d)
}

/// Audits a data set directory (manifest.csv + traces of one locomotive's releases) as
/// `host-sim audit DIR --json FILE` does: which unmodelled mechanism, if any, explains the
/// residual. Returns the JSON document of `--json` as a str (`pbm.audit` parses it into a dict
/// and adds `verdict_text`); slow (tens of seconds on 2 cores).
#[pyfunction]
#[pyo3(signature = (path, pairs = true))]
fn audit_json(py: Python<'_>, path: PathBuf, pairs: bool) -> PyResult<(String, String, Vec<String>)> {
    if !path.is_dir() {
        return Err(PyOSError::new_err(format!("{}: no such data set directory", path.display())));
    }
    let (outcome, skipped) = py.detach(|| pbm_lab::audit_plot::audit_path(&path, pairs)).map_err(anyhow_error)?;
    let skipped: Vec<String> = skipped.errors().iter().map(ToString::to_string).collect();
    Ok((outcome.to_json().to_string(), outcome.verdict_text(), skipped))
}

/// Stores releases in a fleet history database (SQLite, created if absent), as
/// `host-sim fleet ingest DB PATH…` does: trace files, data set directories and candump logs.
/// Returns a dict: `files`, `releases`, `new`, `duplicates` (list of str), `skipped` (list of
/// str: inputs refused, with file and line), `summary` (the CLI's line).
#[pyfunction]
#[pyo3(signature = (db, paths, threads = 0))]
fn fleet_ingest<'py>(
    py: Python<'py>,
    db: PathBuf,
    paths: Vec<PathBuf>,
    threads: usize,
) -> PyResult<Bound<'py, PyDict>> {
    if paths.is_empty() {
        return Err(value_error("give at least one trace, data set directory or candump log to ingest"));
    }
    if let Some(p) = paths.iter().find(|p| !p.exists()) {
        return Err(PyOSError::new_err(format!("{}: no such file or directory", p.display())));
    }
    let s = py
        .detach(|| -> anyhow::Result<_> {
            let mut store = pbm_fleet::db::FleetDb::open(&db)?;
            pbm_fleet::ingest::ingest(&mut store, &paths, &pbm_fleet::ingest::IngestOptions { threads })
        })
        .map_err(anyhow_error)?;
    let d = PyDict::new(py);
    d.set_item("files", s.files)?;
    d.set_item("releases", s.releases)?;
    d.set_item("new", s.new)?;
    d.set_item("duplicates", s.duplicates.clone())?;
    d.set_item("skipped", s.skipped.errors().iter().map(ToString::to_string).collect::<Vec<_>>())?;
    d.set_item("summary", s.to_string())?;
    Ok(d)
}

/// The fleet status, one line per locomotive, exactly as `host-sim fleet status DB` prints it
/// (verdicts, trends, early warnings). Raises `OSError` when the database does not exist.
#[pyfunction]
fn fleet_status(py: Python<'_>, db: PathBuf) -> PyResult<Vec<String>> {
    if !db.is_file() {
        return Err(PyOSError::new_err(format!(
            "{}: no fleet database (create one with `fleet ingest`)",
            db.display()
        )));
    }
    py.detach(|| pbm_fleet::commands::status_lines(&db)).map_err(anyhow_error)
}

/// The names of the twin's optional mechanisms (keys of `simulate(mechanisms=…)`).
fn mechanism_names() -> Vec<&'static str> {
    Mechanism::ALL.iter().map(|m| m.name()).collect()
}

/// The extension module.
#[pymodule]
fn _pbm(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(replay, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(decode_can, m)?)?;
    m.add_function(wrap_pyfunction!(read_trace, m)?)?;
    m.add_function(wrap_pyfunction!(audit_json, m)?)?;
    m.add_function(wrap_pyfunction!(fleet_ingest, m)?)?;
    m.add_function(wrap_pyfunction!(fleet_status, m)?)?;
    m.add("MECHANISMS", mechanism_names())?;
    m.add("ADC_MAX", ADC_MAX)?;
    m.add("SAMPLE_PERIOD_S", pbm::twin::SAMPLE_PERIOD_S)?;
    Ok(())
}
