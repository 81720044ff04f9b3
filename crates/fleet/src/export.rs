//! `fleet export`: the whole history as one Parquet file for analysts (pandas, polars, DuckDB,
//! Spark read it directly).
//!
//! One row per stored release, the columns of the database table ([`COLUMNS`]), nulls where
//! the database has none (e.g. no orifice estimate from a CAN report). Written with the
//! `parquet` crate's low-level writer, uncompressed, as one row group.

use crate::db::{FleetDb, StoredRelease};
use anyhow::{Context, Result};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int32Type, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::{SerializedColumnWriter, SerializedFileWriter};
use parquet::schema::parser::parse_message_type;
use std::path::Path;
use std::sync::Arc;

/// The Parquet schema of the export.
pub const SCHEMA: &str = "
message fleet_release {
    required binary locomotive (STRING);
    required binary source (STRING);
    required binary origin (STRING);
    required binary release_key (STRING);
    required int64 release_no;
    optional double time_s;
    required binary verdict (STRING);
    optional int32 confidence_pct;
    optional binary no_diagnosis (STRING);
    optional double orifice_mm;
    optional double leak_mm;
    optional double supply_bar_g;
    optional binary label (STRING);
}";

/// The exported columns, in file order.
pub const COLUMNS: [&str; 13] = [
    "locomotive",
    "source",
    "origin",
    "release_key",
    "release_no",
    "time_s",
    "verdict",
    "confidence_pct",
    "no_diagnosis",
    "orifice_mm",
    "leak_mm",
    "supply_bar_g",
    "label",
];

/// Values and definition levels of an optional column (level 1: present, 0: null).
fn optional<T: Clone>(values: impl Iterator<Item = Option<T>>) -> (Vec<T>, Vec<i16>) {
    let mut v = Vec::new();
    let mut def = Vec::new();
    for x in values {
        def.push(i16::from(x.is_some()));
        v.extend(x);
    }
    (v, def)
}

fn text(s: &str) -> ByteArray {
    ByteArray::from(s.as_bytes().to_vec())
}

fn write_text(
    col: &mut SerializedColumnWriter<'_>,
    rows: &[StoredRelease],
    f: impl Fn(&StoredRelease) -> Option<&str>,
    required: bool,
) -> Result<()> {
    let (v, def) = optional(rows.iter().map(|r| f(r).map(text)));
    col.typed::<ByteArrayType>().write_batch(&v, (!required).then_some(&def[..]), None)?;
    Ok(())
}

fn write_double(
    col: &mut SerializedColumnWriter<'_>,
    rows: &[StoredRelease],
    f: impl Fn(&StoredRelease) -> Option<f64>,
) -> Result<()> {
    let (v, def) = optional(rows.iter().map(f));
    col.typed::<DoubleType>().write_batch(&v, Some(&def), None)?;
    Ok(())
}

/// Writes every stored release to `path`; returns the number of rows.
pub fn export(db: &FleetDb, path: &Path) -> Result<usize> {
    let mut rows = Vec::new();
    for loco in db.locomotives()? {
        rows.extend(db.releases(&loco)?);
    }
    let schema = Arc::new(parse_message_type(SCHEMA)?);
    let props =
        Arc::new(WriterProperties::builder().set_created_by("parking brake monitor fleet export".into()).build());
    let file = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut writer = SerializedFileWriter::new(file, schema, props)?;
    let mut group = writer.next_row_group()?;
    let mut index = 0;
    while let Some(mut col) = group.next_column()? {
        match COLUMNS.get(index).copied().unwrap_or("(beyond the list)") {
            "locomotive" => write_text(&mut col, &rows, |r| Some(&r.locomotive), true)?,
            "source" => write_text(&mut col, &rows, |r| Some(&r.source), true)?,
            "origin" => write_text(&mut col, &rows, |r| Some(&r.origin), true)?,
            "release_key" => write_text(&mut col, &rows, |r| Some(&r.release_key), true)?,
            "release_no" => {
                let v: Vec<i64> = rows.iter().map(|r| r.release_no).collect();
                col.typed::<Int64Type>().write_batch(&v, None, None)?;
            }
            "time_s" => write_double(&mut col, &rows, |r| r.time_s)?,
            "verdict" => write_text(&mut col, &rows, |r| Some(&r.verdict), true)?,
            "confidence_pct" => {
                let (v, def) = optional(rows.iter().map(|r| r.confidence_pct.and_then(|c| i32::try_from(c).ok())));
                col.typed::<Int32Type>().write_batch(&v, Some(&def), None)?;
            }
            "no_diagnosis" => write_text(&mut col, &rows, |r| r.no_diagnosis.as_deref(), false)?,
            "orifice_mm" => write_double(&mut col, &rows, |r| r.orifice_mm)?,
            "leak_mm" => write_double(&mut col, &rows, |r| r.leak_mm)?,
            "supply_bar_g" => write_double(&mut col, &rows, |r| r.supply_bar_g)?,
            "label" => write_text(&mut col, &rows, |r| r.label.as_deref(), false)?,
            other => anyhow::bail!("export: no writer for column {other}"),
        }
        col.close()?;
        index += 1;
    }
    group.close()?;
    writer.close().with_context(|| format!("cannot write {}", path.display()))?;
    Ok(rows.len())
}
