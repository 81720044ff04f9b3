//! CSV and JSON files through one implementation each: the `csv` crate (quoting, `\r\n`, BOM)
//! and `serde_json`. Readers keep the file and line of every error; writers name the file.

use crate::error::FileError;
use crate::files::open_regular;
use crate::lines::{CsvLines, Line};
use anyhow::{Context, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::fs::File;
use std::io::{BufRead, BufWriter, Write};
use std::path::{Path, PathBuf};

/// Reads every row of CSV text into `T` (columns matched by header name), each with its 1-based
/// line; `name` labels errors. The first record is the header; `#` lines and blank lines are
/// skipped; every row must be as wide as the header.
pub fn read_rows_from<T: DeserializeOwned, R: BufRead>(name: &str, reader: R) -> Result<Vec<(usize, T)>, FileError> {
    read_rows_checked(name, reader, |_| Ok(()))
}

/// [`read_rows_from`] with a check of the header (its column names, trimmed) before any row.
pub fn read_rows_checked<T: DeserializeOwned, R: BufRead>(
    name: &str,
    reader: R,
    check_header: impl Fn(&csv::StringRecord) -> Result<(), String>,
) -> Result<Vec<(usize, T)>, FileError> {
    let mut lines = CsvLines::new(reader);
    let mut header: Option<csv::StringRecord> = None;
    let mut rows = Vec::new();
    while let Some(next) = lines.next_line() {
        let line = match next.map_err(|(line, e)| FileError::new(name, line, e))? {
            Line::Comment(_) => continue,
            Line::Record(line) => line,
        };
        let record = csv::StringRecord::from_byte_record(lines.record().clone())
            .map_err(|_| FileError::new(name, line, "not valid UTF-8"))?;
        let Some(names) = &header else {
            check_header(&record).map_err(|m| FileError::new(name, line, m))?;
            header = Some(record);
            continue;
        };
        if record.len() != names.len() {
            return Err(FileError::new(
                name,
                line,
                format!("expected {} columns as in the header, found {}", names.len(), record.len()),
            ));
        }
        let row = record.deserialize(Some(names)).map_err(|e| FileError::new(name, line, deserialize_error(&e)))?;
        rows.push((line, row));
    }
    if header.is_none() {
        return Err(FileError::new(name, 0, "empty file: expected a header row"));
    }
    Ok(rows)
}

/// What a row's deserialisation error means, in words (column names and numbers 1-based).
fn deserialize_error(e: &csv::Error) -> String {
    match e.kind() {
        csv::ErrorKind::Deserialize { err, .. } => match err.field() {
            Some(i) => format!("column {}: {}", i + 1, err.kind()),
            None => err.kind().to_string(),
        },
        _ => e.to_string(),
    }
}

/// Reads a CSV file (a regular file only) into rows of `T` with their lines.
pub fn read_rows<T: DeserializeOwned>(path: &Path) -> Result<Vec<(usize, T)>, FileError> {
    let file = open_regular(path)?;
    read_rows_from(&path.display().to_string(), std::io::BufReader::new(file))
}

/// A CSV file being written: header and rows through the `csv` crate, errors naming the file.
pub struct CsvFile {
    path: PathBuf,
    out: csv::Writer<BufWriter<File>>,
}

impl CsvFile {
    /// Creates (truncates) `path` and its parent directories.
    pub fn create(path: &Path) -> Result<Self> {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).with_context(|| format!("cannot create {}", parent.display()))?;
        }
        let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        Ok(Self { path: path.to_owned(), out: csv::Writer::from_writer(BufWriter::new(file)) })
    }

    /// Writes one record of already formatted fields (quoted where needed).
    pub fn record<I, F>(&mut self, fields: I) -> Result<()>
    where
        I: IntoIterator<Item = F>,
        F: AsRef<[u8]>,
    {
        self.out.write_record(fields).with_context(|| format!("cannot write {}", self.path.display()))
    }

    /// Writes one serialisable row (the header comes from the first row's field names).
    pub fn row<T: Serialize>(&mut self, row: &T) -> Result<()> {
        self.out.serialize(row).with_context(|| format!("cannot write {}", self.path.display()))
    }

    /// Flushes the file.
    pub fn finish(mut self) -> Result<()> {
        self.out.flush().with_context(|| format!("cannot write {}", self.path.display()))
    }
}

/// Writes serialisable rows to a CSV file with a header of their field names.
pub fn write_rows<T: Serialize>(path: &Path, rows: impl IntoIterator<Item = T>) -> Result<()> {
    let mut f = CsvFile::create(path)?;
    for r in rows {
        f.row(&r)?;
    }
    f.finish()
}

/// Writes `value` as pretty-printed JSON (non-finite numbers become `null`).
pub fn write_json<T: Serialize + ?Sized>(path: &Path, value: &T) -> Result<()> {
    let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut w = BufWriter::new(file);
    serde_json::to_writer_pretty(&mut w, value).with_context(|| format!("cannot write {}", path.display()))?;
    w.write_all(b"\n").and_then(|()| w.flush()).with_context(|| format!("cannot write {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize, serde::Serialize, PartialEq)]
    struct Row {
        name: String,
        value: f64,
    }

    #[test]
    fn rows_keep_their_lines_and_errors_name_file_and_line() {
        let text = "# comment\nname,value\nloco \"7\",1.5\n\n\"a,b\",2\n";
        let rows: Vec<(usize, Row)> = read_rows_from("t.csv", text.as_bytes()).unwrap();
        assert_eq!(rows[0], (3, Row { name: "loco \"7\"".into(), value: 1.5 }));
        assert_eq!(rows[1], (5, Row { name: "a,b".into(), value: 2.0 }));
        let e = read_rows_from::<Row, _>("t.csv", "name,value\nx,1\ny\n".as_bytes()).unwrap_err();
        assert_eq!((e.line, e.to_string()), (3, "t.csv:3: expected 2 columns as in the header, found 1".into()));
        let e = read_rows_from::<Row, _>("t.csv", "name,value\nx,one\n".as_bytes()).unwrap_err();
        assert!(e.to_string().starts_with("t.csv:2: column 2"), "{e}");
    }

    #[test]
    fn written_fields_with_commas_and_quotes_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.csv");
        let rows = [Row { name: "a,\"b\"".into(), value: 0.5 }];
        write_rows(&p, &rows).unwrap();
        let back: Vec<(usize, Row)> = read_rows(&p).unwrap();
        assert_eq!(back[0].1, rows[0]);
    }

    #[test]
    fn json_escapes_and_writes_null_for_non_finite() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.json");
        write_json(&p, &serde_json::json!({"loco": "a\"b", "nmse": f64::NAN})).unwrap();
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        assert_eq!(v["loco"], "a\"b");
        assert!(v["nmse"].is_null());
    }
}
