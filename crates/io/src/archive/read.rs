//! [`ArchiveReader`]: the releases of an archive, one row group at a time.

use super::{check_samples, parse_meta_json, ArchivedRelease, COLUMNS, VERSION, VERSION_KEY};
use crate::error::FileError;
use parquet::basic::{ConvertedType, LogicalType, Repetition, Type as PhysicalType};
use parquet::data_type::{ByteArray, ByteArrayType, DataType, DoubleType, Int32Type};
use parquet::errors::ParquetError;
use parquet::file::reader::{ChunkReader, FileReader, Length, RowGroupReader};
use parquet::file::serialized_reader::SerializedFileReader;
use pbm::sensor::ADC_FULL_SCALE;
use std::collections::HashMap;
use std::fs::File;
use std::io::Read;
use std::path::Path;
use std::sync::Arc;

/// Most samples one release may hold (8 Mi: 23 h at 100 Hz); a row group claiming more is
/// refused before anything of it is read.
pub const MAX_RELEASE_SAMPLES: usize = 1 << 23;

/// Rows decoded per call while a column is read.
const BATCH_ROWS: usize = 8192;

/// The archive file, read at explicit offsets (`pread`), so that several threads can read
/// row groups at once: the parquet crate's reader of a `File` clones the handle, and the
/// clones share one cursor, so concurrent reads would race (they did: a parallel replay read
/// pages of another row group).
struct PositionedFile(Arc<File>);

/// A reader of [`PositionedFile`] from an offset on.
struct PositionedRead {
    file: Arc<File>,
    pos: u64,
}

#[cfg(unix)]
fn read_at(file: &File, buf: &mut [u8], pos: u64) -> std::io::Result<usize> {
    std::os::unix::fs::FileExt::read_at(file, buf, pos)
}

#[cfg(windows)]
fn read_at(file: &File, buf: &mut [u8], pos: u64) -> std::io::Result<usize> {
    std::os::windows::fs::FileExt::seek_read(file, buf, pos)
}

impl Read for PositionedRead {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = read_at(&self.file, buf, self.pos)?;
        self.pos += n as u64;
        Ok(n)
    }
}

impl Length for PositionedFile {
    fn len(&self) -> u64 {
        self.0.metadata().map_or(0, |m| m.len())
    }
}

impl ChunkReader for PositionedFile {
    type T = std::io::BufReader<PositionedRead>;

    fn get_read(&self, start: u64) -> Result<Self::T, ParquetError> {
        Ok(std::io::BufReader::new(PositionedRead { file: self.0.clone(), pos: start }))
    }

    fn get_bytes(&self, start: u64, length: usize) -> Result<bytes::Bytes, ParquetError> {
        // A footer may claim any length: check it against the file before allocating.
        let end = start.checked_add(length as u64).filter(|&end| end <= self.len());
        if end.is_none() {
            return Err(ParquetError::EOF(format!("{length} bytes at offset {start} lie beyond the end of the file")));
        }
        let mut buf = vec![0u8; length];
        let mut done = 0;
        while done < length {
            let n = read_at(&self.0, &mut buf[done..], start + done as u64)?;
            if n == 0 {
                return Err(ParquetError::EOF(format!("file ended after {done} of {length} bytes at offset {start}")));
            }
            done += n;
        }
        Ok(buf.into())
    }
}

/// Runs a call into the parquet crate, turning a panic into an error: the crate asserts on
/// some damaged footers instead of returning an error (found by flipping bytes of an archive:
/// `tests/archive_corrupt.rs`). The panic's message still reaches stderr through the panic
/// hook; the run goes on.
fn guarded<T>(f: impl FnOnce() -> Result<T, String>) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        let why = payload
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        Err(format!("the Parquet decoder failed on damaged data: {why}"))
    })
}

/// `true` when `path` is a regular file that starts with the Parquet magic `PAR1`.
pub fn is_archive(path: &Path) -> bool {
    let Ok(mut f) = crate::files::open_regular(path) else { return false };
    let mut magic = [0u8; 4];
    f.read_exact(&mut magic).is_ok() && &magic == b"PAR1"
}

/// The physical type and annotation a column must have.
#[derive(Clone, Copy)]
enum ColumnType {
    Text,
    Int32,
    Double,
}

/// Each column's type and whether it may hold nulls.
const TYPES: [(ColumnType, bool); 8] = [
    (ColumnType::Text, false),
    (ColumnType::Text, false),
    (ColumnType::Text, true),
    (ColumnType::Text, true),
    (ColumnType::Int32, false),
    (ColumnType::Double, false),
    (ColumnType::Int32, false),
    (ColumnType::Text, true),
];

/// Who a row group holds, or why it cannot be read.
type GroupKey = Result<(String, String), String>;

/// Reads a fleet archive one release (row group) at a time; see the [module](super) docs.
/// Opening reads the footer, checks the schema and version, and finds each row group's
/// release (from the footer's statistics when they are exact, else from the two key columns);
/// iterating reads one row group per release and yields it, or the error that names the file
/// and the release, and goes on with the next.
pub struct ArchiveReader {
    name: String,
    file: SerializedFileReader<PositionedFile>,
    keys: Vec<GroupKey>,
    next: usize,
    locomotive: Option<String>,
}

impl std::fmt::Debug for ArchiveReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ArchiveReader").field("name", &self.name).field("releases", &self.keys.len()).finish()
    }
}

impl ArchiveReader {
    /// Opens the archive `path`. A file that is not a fleet archive of this version is an
    /// error naming the file and what is wrong.
    pub fn open(path: &Path) -> Result<Self, FileError> {
        let name = path.display().to_string();
        let whole = |m: String| FileError::new(&name, 0, m);
        let file = crate::files::open_regular(path)?;
        let file = guarded(|| {
            SerializedFileReader::new(PositionedFile(Arc::new(file)))
                .map_err(|e| format!("not a Parquet file (a fleet archive is one): {e}"))
        })
        .map_err(whole)?;
        let meta = file.metadata().file_metadata();
        let version = meta.key_value_metadata().and_then(|kv| kv.iter().find(|k| k.key == VERSION_KEY));
        match version.and_then(|k| k.value.as_deref()) {
            Some(VERSION) => {}
            Some(other) => return Err(whole(format!("archive version {other}; this build reads version {VERSION}"))),
            None => return Err(whole(format!("not a fleet archive: no `{VERSION_KEY}` key in the file metadata"))),
        }
        check_schema(file.metadata().file_metadata().schema_descr()).map_err(whole)?;
        let mut keys: Vec<GroupKey> = (0..file.num_row_groups())
            .map(|i| guarded(|| group_key(&file, i)).map_err(|m| format!("row group {i}: {m}")))
            .collect();
        // A release found in two row groups: both are refused (which rows are the release?).
        let mut first: HashMap<(String, String), usize> = HashMap::new();
        let mut split: Vec<(usize, usize)> = Vec::new();
        for (i, k) in keys.iter().enumerate() {
            if let Ok(key) = k {
                if let Some(&j) = first.get(key) {
                    split.push((j, i));
                } else {
                    first.insert(key.clone(), i);
                }
            }
        }
        for (a, b) in split {
            for i in [a, b] {
                if let Some(Ok((loco, release))) = keys.get(i) {
                    let m = format!(
                        "release {release} of {loco}: split over row groups {a} and {b} (a release must be one row \
                         group)"
                    );
                    keys[i] = Err(m);
                }
            }
        }
        Ok(Self { name, file, keys, next: 0, locomotive: None })
    }

    /// From now on, yields only the releases of `locomotive`; the others' row groups are not
    /// read.
    pub fn only_locomotive(mut self, locomotive: &str) -> Self {
        self.locomotive = Some(locomotive.to_owned());
        self
    }

    /// The archive as named in errors.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Row groups in the file (one per release).
    pub fn row_groups(&self) -> usize {
        self.keys.len()
    }

    /// The (locomotive, release) of row group `i`, or why it cannot be read (known from the
    /// footer or the key columns, before its samples are read).
    pub fn key(&self, i: usize) -> Option<Result<(&str, &str), &str>> {
        self.keys.get(i).map(|k| match k {
            Ok((l, r)) => Ok((l.as_str(), r.as_str())),
            Err(m) => Err(m.as_str()),
        })
    }

    /// The row groups a run takes: all, or those of the locomotive asked for (a row group
    /// whose key could not be read is kept, so that its error is reported).
    pub fn selected(&self) -> Vec<usize> {
        (0..self.keys.len())
            .filter(|&i| match (&self.locomotive, &self.keys[i]) {
                (Some(want), Ok((loco, _))) => loco == want,
                _ => true,
            })
            .collect()
    }

    /// Reads row group `i` as a release; the error names the file and the release. Can be
    /// called from several threads at once.
    pub fn read(&self, i: usize) -> Result<ArchivedRelease, FileError> {
        let err = |m: String| FileError::new(&self.name, 0, m);
        let (loco, release) = match self.keys.get(i) {
            Some(Ok(k)) => k.clone(),
            Some(Err(m)) => return Err(err(m.clone())),
            None => return Err(err(format!("no row group {i}"))),
        };
        let at = format!("release {release} of {loco} (row group {i})");
        guarded(|| read_release(&self.file, i, loco, release)).map_err(|m| {
            // `read_release` names the release itself; a caught panic does not.
            if m.starts_with("release ") {
                err(m)
            } else {
                err(format!("{at}: {m}"))
            }
        })
    }
}

impl Iterator for ArchiveReader {
    type Item = Result<ArchivedRelease, FileError>;

    fn next(&mut self) -> Option<Self::Item> {
        while self.next < self.keys.len() {
            let i = self.next;
            self.next += 1;
            if let (Some(want), Ok((loco, _))) = (&self.locomotive, &self.keys[i]) {
                if loco != want {
                    continue;
                }
            }
            return Some(self.read(i));
        }
        None
    }
}

/// Checks the file's columns against the format: names in order, physical types, string
/// annotations, no repeated or nested fields. An optional column where the format says
/// required is accepted (writers such as pyarrow make every column nullable unless told); a
/// null in it is an error of that release.
fn check_schema(schema: &parquet::schema::types::SchemaDescriptor) -> Result<(), String> {
    let found: Vec<&str> = schema.columns().iter().map(|c| c.name()).collect();
    for (i, want) in COLUMNS.iter().enumerate() {
        match found.get(i) {
            Some(name) if name == want => {}
            Some(name) if COLUMNS.contains(name) => {
                return Err(format!(
                    "column {} is `{name}`, expected `{want}` (the columns are {} in this order)",
                    i + 1,
                    COLUMNS.join(", ")
                ))
            }
            Some(name) => return Err(format!("column {} is `{name}`, expected `{want}`", i + 1)),
            None => return Err(format!("column `{want}` missing (the columns are {})", COLUMNS.join(", "))),
        }
    }
    if found.len() > COLUMNS.len() {
        return Err(format!("unexpected column `{}` after `meta`", found[COLUMNS.len()]));
    }
    for (i, ((kind, _), column)) in TYPES.iter().zip(schema.columns()).enumerate() {
        let name = COLUMNS[i];
        if column.path().parts().len() != 1 || column.max_rep_level() != 0 {
            return Err(format!("column `{name}` is nested or repeated; it must be a plain column"));
        }
        let repetition = column.self_type().get_basic_info().repetition();
        if repetition == Repetition::REPEATED {
            return Err(format!("column `{name}` is repeated; it must be a plain column"));
        }
        let physical = column.physical_type();
        let logical = column.logical_type_ref();
        let ok = match kind {
            ColumnType::Text => {
                physical == PhysicalType::BYTE_ARRAY
                    && (matches!(logical, Some(LogicalType::String)) || column.converted_type() == ConvertedType::UTF8)
            }
            ColumnType::Int32 => {
                physical == PhysicalType::INT32
                    && matches!(logical, None | Some(LogicalType::Integer { bit_width: 32, is_signed: true }))
            }
            ColumnType::Double => physical == PhysicalType::DOUBLE && logical.is_none(),
        };
        if !ok {
            let want = match kind {
                ColumnType::Text => "BYTE_ARRAY annotated UTF8 (a string)",
                ColumnType::Int32 => "INT32",
                ColumnType::Double => "DOUBLE",
            };
            let annotation = logical.map_or_else(|| format!("{:?}", column.converted_type()), |l| format!("{l:?}"));
            return Err(format!("column `{name}` is {physical} ({annotation}); the format says {want}"));
        }
    }
    Ok(())
}

/// The (locomotive, release) of row group `i`: from the footer's statistics when both key
/// columns have exact, equal minimum and maximum and no null; else read from the key columns.
fn group_key(file: &SerializedFileReader<PositionedFile>, i: usize) -> Result<(String, String), String> {
    let meta = file.metadata().row_group(i);
    if meta.num_rows() <= 0 {
        return Err("no rows".to_owned());
    }
    // Where each column chunk lies, checked before anything reads it (the parquet crate
    // asserts on a negative offset or length).
    for c in meta.columns() {
        let start = c.dictionary_page_offset().unwrap_or_else(|| c.data_page_offset());
        if start < 0 || c.compressed_size() < 0 {
            return Err(format!("column `{}` has a negative offset or length (damaged file)", c.column_descr().name()));
        }
    }
    let from_stats = |c: usize| -> Option<String> {
        let s = meta.column(c).statistics()?;
        let (min, max) = (s.min_bytes_opt()?, s.max_bytes_opt()?);
        let exact = s.min_is_exact() && s.max_is_exact() && min == max && s.null_count_opt() == Some(0);
        exact.then(|| String::from_utf8(min.to_vec()).ok()).flatten()
    };
    if let (Some(loco), Some(release)) = (from_stats(0), from_stats(1)) {
        return Ok((loco, release));
    }
    let group = file.get_row_group(i).map_err(|e| format!("cannot read: {e}"))?;
    let rows = rows_of(group.as_ref())?;
    let one = |c: usize| -> Result<String, String> {
        let (values, _) = read_column::<ByteArrayType>(group.as_ref(), c, rows)?;
        let name = COLUMNS[c];
        let first = values.first().ok_or_else(|| format!("`{name}` has no value"))?;
        if let Some(k) = values.iter().position(|v| v != first) {
            return Err(format!(
                "two releases in one row group (`{name}` is {} on row 0 and {} on row {k}); each release must be its \
                 own row group",
                text(first).unwrap_or_default(),
                text(&values[k]).unwrap_or_default()
            ));
        }
        text(first).map_err(|()| format!("`{name}` is not UTF-8"))
    };
    Ok((one(0)?, one(1)?))
}

/// The row count of a row group, refused above [`MAX_RELEASE_SAMPLES`].
fn rows_of(group: &dyn RowGroupReader) -> Result<usize, String> {
    let rows = group.metadata().num_rows();
    match usize::try_from(rows) {
        Ok(n) if n > 0 && n <= MAX_RELEASE_SAMPLES => Ok(n),
        Ok(0) => Err("no rows".to_owned()),
        _ => Err(format!("{rows} rows: more than the {MAX_RELEASE_SAMPLES} samples a release may hold")),
    }
}

fn text(v: &ByteArray) -> Result<String, ()> {
    std::str::from_utf8(v.data()).map(str::to_owned).map_err(|_| ())
}

/// Reads column `c` of a row group whole: its non-null values and, for a column declared
/// optional, the definition level of each row (empty for a required column). More or fewer
/// rows than the footer says is an error, and so is a null in a column the format requires.
fn read_column<T: DataType>(
    group: &dyn RowGroupReader,
    c: usize,
    rows: usize,
) -> Result<(Vec<T::T>, Vec<i16>), String> {
    let name = COLUMNS[c];
    let reader = group.get_column_reader(c).map_err(|e| format!("cannot read column `{name}`: {e}"))?;
    let mut reader =
        T::get_column_reader(reader).ok_or_else(|| format!("column `{name}` is not of the type the format says"))?;
    let nullable = group.metadata().column(c).column_descr().max_def_level() > 0;
    let (mut values, mut def) = (Vec::new(), Vec::new());
    let mut read = 0usize;
    loop {
        let want = BATCH_ROWS.min(rows + 1 - read);
        let (records, _, _) = reader
            .read_records(want, nullable.then_some(&mut def), None, &mut values)
            .map_err(|e| format!("cannot decode column `{name}`: {e}"))?;
        if records == 0 {
            break;
        }
        read += records;
        if read > rows {
            return Err(format!("column `{name}` holds more rows than the row group's {rows}"));
        }
    }
    if read != rows {
        return Err(format!("column `{name}` holds {read} rows, the row group {rows}"));
    }
    if !TYPES[c].1 && values.len() != rows {
        return Err(format!("`{name}` is null on some rows; the format requires it on every row"));
    }
    Ok((values, def))
}

/// A per-release text column (`label`, `split`): the same value on every row, or null on
/// every row.
fn constant_text(group: &dyn RowGroupReader, c: usize, rows: usize) -> Result<Option<String>, String> {
    let name = COLUMNS[c];
    let (values, _) = read_column::<ByteArrayType>(group, c, rows)?;
    if values.is_empty() {
        return Ok(None);
    }
    if values.len() != rows {
        return Err(format!("`{name}` is null on some rows and not on others; it belongs to the whole release"));
    }
    if let Some(k) = values.iter().position(|v| *v != values[0]) {
        return Err(format!("`{name}` changes within the release (row {k}); it belongs to the whole release"));
    }
    text(&values[0]).map(Some).map_err(|()| format!("`{name}` is not UTF-8"))
}

/// Reads and checks the samples and the per-release columns of row group `i`.
fn read_release(
    file: &SerializedFileReader<PositionedFile>,
    i: usize,
    locomotive: String,
    release: String,
) -> Result<ArchivedRelease, String> {
    let at = |m: String| format!("release {release} of {locomotive} (row group {i}): {m}");
    let group = file.get_row_group(i).map_err(|e| at(format!("cannot read: {e}")))?;
    let group = group.as_ref();
    let rows = rows_of(group).map_err(at)?;
    let label = constant_text(group, 2, rows).map_err(at)?;
    let split = constant_text(group, 3, rows).map_err(at)?;
    let (sample, _) = read_column::<Int32Type>(group, 4, rows).map_err(at)?;
    if let Some(k) = sample.iter().enumerate().position(|(k, &s)| usize::try_from(s).ok() != Some(k)) {
        return Err(at(format!(
            "row {k} has sample index {}; a release's rows are its samples 0, 1, 2, … in order",
            sample[k]
        )));
    }
    drop(sample);
    let (t_s, _) = read_column::<DoubleType>(group, 5, rows).map_err(at)?;
    let (counts, _) = read_column::<Int32Type>(group, 6, rows).map_err(at)?;
    let mut adc = Vec::with_capacity(counts.len());
    for (k, &c) in counts.iter().enumerate() {
        match u16::try_from(c) {
            Ok(c) if c <= ADC_FULL_SCALE => adc.push(c),
            _ => return Err(at(format!("sample {k}: adc value {c} outside 0..={ADC_FULL_SCALE}"))),
        }
    }
    drop(counts);
    check_samples(&t_s, &adc).map_err(at)?;
    let (meta, def) = read_column::<ByteArrayType>(group, 7, rows).map_err(at)?;
    // A `meta` column declared required has a value on every row (no levels).
    let extra_row =
        if def.is_empty() { (rows > 1).then_some(1) } else { def.iter().skip(1).position(|&d| d > 0).map(|k| k + 1) };
    if let Some(k) = extra_row {
        return Err(at(format!("`meta` on row {k}: only a release's first row carries its metadata")));
    }
    let metadata = match meta.first() {
        Some(json) if def.first() != Some(&0) => {
            let json = std::str::from_utf8(json.data()).map_err(|_| at("`meta` is not UTF-8".to_owned()))?;
            parse_meta_json(json).map_err(at)?
        }
        _ => Vec::new(),
    };
    Ok(ArchivedRelease { locomotive, release, label, split, metadata, t_s, adc })
}
