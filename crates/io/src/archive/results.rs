//! Replay results as Parquet: one row per release, the fields of the replay table
//! (`host-sim replay … --results-parquet FILE`; columns in `docs/archive.md`).

use anyhow::{bail, Context, Result};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int32Type, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::{SerializedColumnWriter, SerializedFileWriter};
use parquet::schema::parser::parse_message_type;
use pbm::report::Verdict;
use std::path::Path;
use std::sync::Arc;

/// The Parquet schema of a results file.
pub const SCHEMA: &str = "
message pbm_replay_results {
    optional binary locomotive (STRING);
    required binary release (STRING);
    optional binary label (STRING);
    optional int64 samples;
    optional double nmse_pct;
    optional double max_abs_residual_bar;
    optional int64 sensor_fault_samples;
    optional double final_bar_g;
    optional double est_orifice_mm;
    optional double est_leak_mm;
    optional double est_supply_bar_g;
    optional binary verdict (STRING);
    optional int32 confidence_pct;
    optional binary no_diagnosis (STRING);
    optional binary diagnosis (STRING);
    optional binary error (STRING);
}";

/// The columns of a results file, in order.
pub const COLUMNS: [&str; 16] = [
    "locomotive",
    "release",
    "label",
    "samples",
    "nmse_pct",
    "max_abs_residual_bar",
    "sensor_fault_samples",
    "final_bar_g",
    "est_orifice_mm",
    "est_leak_mm",
    "est_supply_bar_g",
    "verdict",
    "confidence_pct",
    "no_diagnosis",
    "diagnosis",
    "error",
];

/// The verdict column of a release the monitor declined to name a class for.
pub const CANNOT_DIAGNOSE: &str = "cannot_diagnose";
/// The verdict column of a release that closed without any diagnosis.
pub const NO_VERDICT: &str = "none";

/// A verdict as the results file and the fleet history store it: the class label,
/// [`CANNOT_DIAGNOSE`], or [`NO_VERDICT`].
pub fn verdict_label(v: Option<&Verdict>) -> String {
    match v {
        Some(Verdict::Class { class, .. }) => class.label().to_owned(),
        Some(Verdict::CannotDiagnose(_)) => CANNOT_DIAGNOSE.to_owned(),
        None => NO_VERDICT.to_owned(),
    }
}

/// Rows per row group of a results file.
const GROUP_ROWS: usize = 65_536;

/// One release's replay result. A release that could not be replayed has only its ids and
/// `error`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ResultRow {
    /// Locomotive, when known.
    pub locomotive: Option<String>,
    /// Release id (the trace's name in the table).
    pub release: String,
    /// True class, when known.
    pub label: Option<String>,
    /// Samples replayed.
    pub samples: Option<i64>,
    /// NMSE of the twin against the measurement, %.
    pub nmse_pct: Option<f64>,
    /// Largest |measured − twin| over valid samples, bar.
    pub max_abs_residual_bar: Option<f64>,
    /// Samples the plausibility checks found a sensor fault on.
    pub sensor_fault_samples: Option<i64>,
    /// Mean measured pressure over the last second of valid samples, bar g.
    pub final_bar_g: Option<f64>,
    /// Estimated release orifice at the end, mm.
    pub est_orifice_mm: Option<f64>,
    /// Estimated leak (equivalent orifice) at the end, mm.
    pub est_leak_mm: Option<f64>,
    /// Estimated supply at the end, bar g.
    pub est_supply_bar_g: Option<f64>,
    /// The class named, `cannot_diagnose`, or `none` (closed without a diagnosis).
    pub verdict: Option<String>,
    /// Calibrated confidence of a named class, %.
    pub confidence_pct: Option<i32>,
    /// Why no class was named, when the monitor declined.
    pub no_diagnosis: Option<String>,
    /// The diagnosis as the replay table prints it.
    pub diagnosis: Option<String>,
    /// Why the release could not be replayed.
    pub error: Option<String>,
}

fn texts<'a>(rows: &'a [ResultRow], f: impl Fn(&'a ResultRow) -> Option<&'a str>) -> (Vec<ByteArray>, Vec<i16>) {
    let mut v = Vec::new();
    let mut def = Vec::with_capacity(rows.len());
    for r in rows {
        let x = f(r);
        def.push(i16::from(x.is_some()));
        v.extend(x.map(|s| ByteArray::from(s.as_bytes().to_vec())));
    }
    (v, def)
}

fn optional<T: Copy>(rows: &[ResultRow], f: impl Fn(&ResultRow) -> Option<T>) -> (Vec<T>, Vec<i16>) {
    let mut v = Vec::new();
    let mut def = Vec::with_capacity(rows.len());
    for r in rows {
        let x = f(r);
        def.push(i16::from(x.is_some()));
        v.extend(x);
    }
    (v, def)
}

fn write_group(col: &mut SerializedColumnWriter<'_>, name: &str, rows: &[ResultRow]) -> Result<()> {
    let text = |col: &mut SerializedColumnWriter<'_>, (v, def): (Vec<ByteArray>, Vec<i16>), required: bool| {
        col.typed::<ByteArrayType>().write_batch(&v, (!required).then_some(&def[..]), None).map(|_| ())
    };
    let double = |col: &mut SerializedColumnWriter<'_>, f: fn(&ResultRow) -> Option<f64>| {
        let (v, def) = optional(rows, f);
        col.typed::<DoubleType>().write_batch(&v, Some(&def), None).map(|_| ())
    };
    let int64 = |col: &mut SerializedColumnWriter<'_>, f: fn(&ResultRow) -> Option<i64>| {
        let (v, def) = optional(rows, f);
        col.typed::<Int64Type>().write_batch(&v, Some(&def), None).map(|_| ())
    };
    match name {
        "locomotive" => text(col, texts(rows, |r| r.locomotive.as_deref()), false)?,
        "release" => text(col, texts(rows, |r| Some(&r.release)), true)?,
        "label" => text(col, texts(rows, |r| r.label.as_deref()), false)?,
        "samples" => int64(col, |r| r.samples)?,
        "nmse_pct" => double(col, |r| r.nmse_pct)?,
        "max_abs_residual_bar" => double(col, |r| r.max_abs_residual_bar)?,
        "sensor_fault_samples" => int64(col, |r| r.sensor_fault_samples)?,
        "final_bar_g" => double(col, |r| r.final_bar_g)?,
        "est_orifice_mm" => double(col, |r| r.est_orifice_mm)?,
        "est_leak_mm" => double(col, |r| r.est_leak_mm)?,
        "est_supply_bar_g" => double(col, |r| r.est_supply_bar_g)?,
        "verdict" => text(col, texts(rows, |r| r.verdict.as_deref()), false)?,
        "confidence_pct" => {
            let (v, def) = optional(rows, |r| r.confidence_pct);
            col.typed::<Int32Type>().write_batch(&v, Some(&def), None)?;
        }
        "no_diagnosis" => text(col, texts(rows, |r| r.no_diagnosis.as_deref()), false)?,
        "diagnosis" => text(col, texts(rows, |r| r.diagnosis.as_deref()), false)?,
        "error" => text(col, texts(rows, |r| r.error.as_deref()), false)?,
        other => bail!("results writer: no column {other}"),
    }
    Ok(())
}

/// Writes `rows` to the Parquet file `path` (uncompressed; row groups of 65 536 rows).
pub fn write_results(path: &Path, rows: &[ResultRow]) -> Result<()> {
    let schema = Arc::new(parse_message_type(SCHEMA)?);
    let props =
        Arc::new(WriterProperties::builder().set_created_by("parking brake monitor replay results".into()).build());
    let file = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut writer = SerializedFileWriter::new(std::io::BufWriter::new(file), schema, props)?;
    for chunk in rows.chunks(GROUP_ROWS) {
        let mut group = writer.next_row_group()?;
        let mut index = 0;
        while let Some(mut col) = group.next_column()? {
            write_group(&mut col, COLUMNS.get(index).copied().unwrap_or("(beyond the list)"), chunk)?;
            col.close()?;
            index += 1;
        }
        group.close()?;
    }
    let mut sink = writer.into_inner().with_context(|| format!("cannot write {}", path.display()))?;
    std::io::Write::flush(&mut sink).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}
