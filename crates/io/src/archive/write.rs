//! [`ArchiveWriter`]: releases in, one row group each, written out as they come.

use super::{ArchivedRelease, COLUMNS, SCHEMA, VERSION, VERSION_KEY};
use anyhow::{bail, Context, Result};
use parquet::basic::{Compression, Encoding, ZstdLevel};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int32Type};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::{EnabledStatistics, WriterProperties};
use parquet::file::writer::{SerializedColumnWriter, SerializedFileWriter};
use parquet::schema::parser::parse_message_type;
use parquet::schema::types::ColumnPath;
use std::io::Write;
use std::path::Path;
use std::sync::Arc;

/// Writes a fleet archive one release at a time. Each [`add`](Self::add) writes the release
/// as its own row group to the output before returning, so memory holds one release (plus
/// the footer's few hundred bytes per release). Releases must come sorted by (locomotive,
/// release), each key once; [`finish`](Self::finish) writes the footer.
pub struct ArchiveWriter<W: Write + Send> {
    name: String,
    writer: SerializedFileWriter<W>,
    last: Option<(String, String)>,
    releases: usize,
    samples: u64,
}

/// The writer's properties: the version key; the sample index and the counts delta-encoded
/// (consecutive indices differ by 1, consecutive counts by the noise), the ids dictionary-
/// encoded (one value per release), zstd level 1 over all (pyarrow, polars, DuckDB and Spark
/// read it by default); statistics on, so that a reader can pick a locomotive's row groups
/// from the footer.
fn properties() -> Result<WriterProperties> {
    let delta = |props: parquet::file::properties::WriterPropertiesBuilder, column: &str| {
        props
            .set_column_dictionary_enabled(ColumnPath::from(column), false)
            .set_column_encoding(ColumnPath::from(column), Encoding::DELTA_BINARY_PACKED)
    };
    let props = WriterProperties::builder()
        .set_created_by("parking brake monitor fleet archive".into())
        .set_key_value_metadata(Some(vec![KeyValue::new(VERSION_KEY.to_owned(), VERSION.to_owned())]))
        .set_compression(Compression::ZSTD(ZstdLevel::try_new(1)?))
        // Statistics per column chunk only: per-page statistics (the page index) would keep
        // kilobytes per release in the writer until the footer is written, for no use here.
        .set_statistics_enabled(EnabledStatistics::Chunk)
        .set_column_dictionary_enabled(ColumnPath::from("t_s"), false)
        .set_column_encoding(ColumnPath::from("t_s"), Encoding::BYTE_STREAM_SPLIT);
    Ok(delta(delta(props, "sample"), "adc").build())
}

impl ArchiveWriter<std::io::BufWriter<std::fs::File>> {
    /// Creates (or truncates) the archive file `path`.
    pub fn create(path: &Path) -> Result<Self> {
        let file = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        Self::new(std::io::BufWriter::new(file), &path.display().to_string())
    }
}

impl<W: Write + Send> ArchiveWriter<W> {
    /// An archive written to `sink`; `name` names it in errors.
    pub fn new(sink: W, name: &str) -> Result<Self> {
        let schema = Arc::new(parse_message_type(SCHEMA)?);
        let writer = SerializedFileWriter::new(sink, schema, Arc::new(properties()?))
            .with_context(|| format!("cannot write {name}"))?;
        Ok(Self { name: name.to_owned(), writer, last: None, releases: 0, samples: 0 })
    }

    /// Releases written so far.
    pub fn releases(&self) -> usize {
        self.releases
    }

    /// Samples written so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Writes `r` as the next row group. Refused (nothing written) when the release breaks
    /// the format ([`ArchivedRelease::check`]) or does not sort after the previous one.
    pub fn add(&mut self, r: &ArchivedRelease) -> Result<()> {
        let what = |m: String| anyhow::anyhow!("{}: release {} of {}: {m}", self.name, r.release, r.locomotive);
        r.check().map_err(what)?;
        if let Some((loco, release)) = &self.last {
            if (loco.as_str(), release.as_str()) >= (r.locomotive.as_str(), r.release.as_str()) {
                return Err(what(format!(
                    "comes after release {release} of {loco}: releases must be added sorted by (locomotive, release), \
                     each once"
                )));
            }
        }
        let n = r.t_s.len();
        let mut group = self.writer.next_row_group()?;
        let mut index = 0;
        while let Some(mut col) = group.next_column()? {
            match COLUMNS.get(index).copied() {
                Some("locomotive") => write_text(&mut col, Some(&r.locomotive), n, true)?,
                Some("release") => write_text(&mut col, Some(&r.release), n, true)?,
                Some("label") => write_text(&mut col, r.label.as_deref(), n, false)?,
                Some("split") => write_text(&mut col, r.split.as_deref(), n, false)?,
                Some("sample") => {
                    // `check` has bounded `n` to the i32 range.
                    let v: Vec<i32> = (0..n).map(|i| i32::try_from(i).unwrap_or(i32::MAX)).collect();
                    col.typed::<Int32Type>().write_batch(&v, None, None)?;
                }
                Some("t_s") => {
                    col.typed::<DoubleType>().write_batch(&r.t_s, None, None)?;
                }
                Some("adc") => {
                    let v: Vec<i32> = r.adc.iter().map(|&c| i32::from(c)).collect();
                    col.typed::<Int32Type>().write_batch(&v, None, None)?;
                }
                Some("meta") => {
                    let mut def = vec![0i16; n];
                    def[0] = 1;
                    let v = [ByteArray::from(r.meta_json().into_bytes())];
                    col.typed::<ByteArrayType>().write_batch(&v, Some(&def), None)?;
                }
                other => bail!("archive writer: no column {other:?} at position {index}"),
            }
            col.close()?;
            index += 1;
        }
        group.close().with_context(|| format!("cannot write {}", self.name))?;
        self.last = Some((r.locomotive.clone(), r.release.clone()));
        self.releases += 1;
        self.samples += n as u64;
        Ok(())
    }

    /// Writes the footer, flushes and returns the sink.
    pub fn finish(self) -> Result<W> {
        let name = self.name;
        let mut sink = self.writer.into_inner().with_context(|| format!("cannot write {name}"))?;
        sink.flush().with_context(|| format!("cannot write {name}"))?;
        Ok(sink)
    }
}

/// A text column of one release: `value` on each of its `n` rows (null when `None`).
fn write_text(col: &mut SerializedColumnWriter<'_>, value: Option<&str>, n: usize, required: bool) -> Result<()> {
    let values: Vec<ByteArray> = match value {
        Some(v) => {
            let one = ByteArray::from(v.as_bytes().to_vec());
            vec![one; n]
        }
        None => Vec::new(),
    };
    let def = vec![i16::from(value.is_some()); n];
    col.typed::<ByteArrayType>().write_batch(&values, (!required).then_some(&def[..]), None)?;
    Ok(())
}
