//! Data sets of SPEC §7: a directory with `manifest.csv` (`file,label,locomotive,split`) and
//! the traces it names (paths relative to the directory). Generated sets also carry
//! `truth.csv`, the ground-truth parameters of every trace.
//!
//! [`Dataset`] is the one way the host tools reach a data set's traces: a manifest path must be
//! relative without `..`, must stay inside the data set once symbolic links are resolved, and
//! must be a regular file; anything else is a [`FileError`] for that trace alone.

use crate::error::{FileError, Skipped};
use crate::files::{check_relative, ensure_inside};
use crate::table::{read_rows_checked, CsvFile};
use crate::trace::{Trace, TraceReader};
use serde::{Deserialize, Serialize};
use std::io::BufReader;
use std::path::{Path, PathBuf};

/// File name of the manifest inside a data set directory.
pub const MANIFEST: &str = "manifest.csv";
/// File name of the ground-truth side file inside a generated data set directory.
pub const TRUTH: &str = "truth.csv";
/// The manifest's columns, exactly and in this order (SPEC §7).
pub const MANIFEST_COLUMNS: [&str; 4] = ["file", "label", "locomotive", "split"];

/// One manifest row.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ManifestRow {
    /// Trace path relative to the data set directory.
    pub file: String,
    /// Fault class label (SPEC §4), or whatever the recorder wrote for real data.
    pub label: String,
    /// Locomotive name.
    pub locomotive: String,
    /// `train` or `test` (other values are kept as written).
    pub split: String,
}

/// Reads `DIR/manifest.csv` strictly: a malformed manifest or any refused row is an error
/// naming its line ([`Dataset::open`] with no row refused).
pub fn read_manifest(dir: &Path) -> Result<Vec<ManifestRow>, FileError> {
    let data = Dataset::open(dir)?;
    match data.refused.into_iter().next() {
        Some(e) => Err(e),
        None => Ok(data.rows),
    }
}

/// Parses manifest text; `name` is used in errors. Strict: any bad row is an error.
pub fn parse_manifest(name: &str, text: impl std::io::BufRead) -> Result<Vec<ManifestRow>, FileError> {
    parse_manifest_lines(name, text)?.into_iter().map(|(_, r)| r).collect()
}

/// A manifest row, or why it is refused.
type CheckedRow = Result<ManifestRow, FileError>;

/// Parses manifest text into rows with their lines: the file's structure (header, columns,
/// quoting) must be right, and a row whose content is wrong (a path leaving the data set, an
/// empty field) comes back as that row's error.
fn parse_manifest_lines(name: &str, text: impl std::io::BufRead) -> Result<Vec<(usize, CheckedRow)>, FileError> {
    let rows: Vec<(usize, ManifestRow)> = read_rows_checked(name, text, |header| {
        if header.iter().eq(MANIFEST_COLUMNS) {
            Ok(())
        } else {
            Err(format!("header must be `{}`", MANIFEST_COLUMNS.join(",")))
        }
    })?;
    Ok(rows
        .into_iter()
        .map(|(line, r)| {
            let checked = check_relative(&r.file).map_err(|m| FileError::new(name, line, m)).and_then(|()| {
                if r.label.is_empty() || r.locomotive.is_empty() || r.split.is_empty() {
                    Err(FileError::new(name, line, "empty label, locomotive or split"))
                } else {
                    Ok(r)
                }
            });
            (line, checked)
        })
        .collect())
}

/// Writes `rows` as a manifest (fields quoted where needed).
pub fn write_manifest(path: &Path, rows: &[ManifestRow]) -> anyhow::Result<()> {
    let mut f = CsvFile::create(path)?;
    f.record(MANIFEST_COLUMNS)?;
    for r in rows {
        f.record([&r.file, &r.label, &r.locomotive, &r.split])?;
    }
    f.finish()
}

/// An opened data set: its directory and manifest.
#[derive(Debug, Clone)]
pub struct Dataset {
    dir: PathBuf,
    root: PathBuf,
    rows: Vec<ManifestRow>,
    /// Manifest line of each row.
    lines: Vec<usize>,
    /// Rows refused when the manifest was read, with why.
    refused: Vec<FileError>,
}

impl Dataset {
    /// Reads the manifest of the data set in `dir`. A manifest that cannot be read as a whole
    /// (missing, bad header, wrong column count, an unclosed quote) is an error; a row whose
    /// path or fields are wrong is refused alone ([`Self::refused`]).
    pub fn open(dir: &Path) -> Result<Self, FileError> {
        let root =
            std::fs::canonicalize(dir).map_err(|e| FileError::new(dir.display(), 0, format!("cannot read: {e}")))?;
        if !root.is_dir() {
            return Err(FileError::new(dir.display(), 0, "not a directory"));
        }
        let path = dir.join(MANIFEST);
        let name = path.display().to_string();
        ensure_inside(&root, MANIFEST, &path)?;
        let file = crate::files::open_regular(&path)?;
        let (mut rows, mut lines, mut refused) = (Vec::new(), Vec::new(), Vec::new());
        for (line, row) in parse_manifest_lines(&name, BufReader::new(file))? {
            match row {
                Ok(r) => {
                    rows.push(r);
                    lines.push(line);
                }
                Err(e) => refused.push(e),
            }
        }
        Ok(Self { dir: dir.to_owned(), rows, lines, refused, root })
    }

    /// Manifest rows refused when it was read (each with its manifest line).
    pub fn refused(&self) -> &[FileError] {
        &self.refused
    }

    /// The path of a side file of the data set (e.g. [`TRUTH`]), refused if it leaves it.
    pub fn side_file(&self, name: &str) -> Result<PathBuf, FileError> {
        let path = self.dir.join(name);
        ensure_inside(&self.root, name, &path)?;
        Ok(path)
    }

    /// The directory as given.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The manifest rows in file order.
    pub fn rows(&self) -> &[ManifestRow] {
        &self.rows
    }

    /// Whether `dir` holds a manifest (is a data set rather than a trace or another directory).
    pub fn is_dataset(dir: &Path) -> bool {
        // Whatever `manifest.csv` is: a special file or a link leaving the set is then refused
        // by [`Self::open`] with that reason, not taken for a missing manifest.
        std::fs::symlink_metadata(dir.join(MANIFEST)).is_ok()
    }

    /// The path of a row's trace, refused if it leaves the data set (symbolic links resolved)
    /// or does not exist; the error names the manifest line of the row.
    pub fn trace_path(&self, row: &ManifestRow) -> Result<PathBuf, FileError> {
        let path = self.dir.join(&row.file);
        ensure_inside(&self.root, &row.file, &path).map_err(|e| {
            let line = self.rows.iter().position(|r| std::ptr::eq(r, row)).and_then(|i| self.lines.get(i).copied());
            match line {
                Some(line) => {
                    FileError::new(self.dir.join(MANIFEST).display(), line, format!("{}: {}", row.file, e.message))
                }
                None => e,
            }
        })?;
        Ok(path)
    }

    /// Opens a row's trace for streaming.
    pub fn open_trace(&self, row: &ManifestRow) -> Result<TraceReader<BufReader<std::fs::File>>, FileError> {
        let path = self.trace_path(row)?;
        TraceReader::open(&path).map_err(FileError::from)
    }

    /// Reads a row's whole trace, checking its 100 Hz clock ([`crate::trace::read_release_trace`]).
    pub fn read_trace(&self, row: &ManifestRow) -> Result<Trace, FileError> {
        let path = self.trace_path(row)?;
        crate::trace::read_release_trace(&path).map_err(FileError::from)
    }
}

/// One trace to work on: where it is, its name for outputs and messages, what the manifest
/// says of it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TraceItem {
    /// Path of the trace file (inside its data set, if it has one).
    pub path: PathBuf,
    /// Name used in summaries and for output files (the relative path in a data set).
    pub name: String,
    /// Label from the manifest, if any.
    pub label: Option<String>,
    /// Locomotive from the manifest, if any.
    pub locomotive: Option<String>,
}

impl TraceItem {
    /// The item of a manifest row whose trace passes the data set's checks.
    pub fn from_row(data: &Dataset, row: &ManifestRow) -> Result<Self, FileError> {
        Ok(Self {
            path: data.trace_path(row)?,
            name: row.file.clone(),
            label: Some(row.label.clone()),
            locomotive: Some(row.locomotive.clone()),
        })
    }
}

/// Which traces of a data set to take.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Selection {
    /// Only this split (`train`, `test`); `None`: all.
    pub split: Option<String>,
    /// At most this many traces per label, in manifest order (0 = all).
    pub per_label: usize,
}

/// The traces under `path`: the file itself, or the selected rows of the data set in the
/// directory `path`. Rows whose trace is refused (a path leaving the data set, a missing or
/// special file) come back as skipped.
pub fn select(path: &Path, selection: &Selection) -> anyhow::Result<(Vec<TraceItem>, Skipped)> {
    let mut skipped = Skipped::none();
    if !path.is_dir() {
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        return Ok((vec![TraceItem { path: path.to_owned(), name, label: None, locomotive: None }], skipped));
    }
    if !Dataset::is_dataset(path) {
        anyhow::bail!("{} is a directory without {MANIFEST}", path.display());
    }
    let data = Dataset::open(path)?;
    for e in data.refused() {
        skipped.push(e.clone());
    }
    let mut per_label = std::collections::HashMap::<&str, usize>::new();
    let mut items = Vec::new();
    for row in data.rows() {
        if selection.split.as_deref().is_some_and(|s| row.split != s) {
            continue;
        }
        let n = per_label.entry(&row.label).or_default();
        *n += 1;
        if selection.per_label != 0 && *n > selection.per_label {
            continue;
        }
        match TraceItem::from_row(&data, row) {
            Ok(item) => items.push(item),
            Err(e) => skipped.push(e),
        }
    }
    Ok((items, skipped))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manifest_errors_name_the_line() {
        let ok =
            parse_manifest("m.csv", "file,label,locomotive,split\n\na.csv,\"normal, really\",l1,test\n".as_bytes())
                .unwrap();
        assert_eq!(ok[0].label, "normal, really");
        let e = parse_manifest("m.csv", "file,label,split\n".as_bytes()).unwrap_err();
        assert_eq!(e.to_string(), "m.csv:1: header must be `file,label,locomotive,split`");
        let e = parse_manifest("m.csv", "file,label,locomotive,split\na.csv,x,y\n".as_bytes()).unwrap_err();
        assert_eq!(e.line, 2);
        let e = parse_manifest("m.csv", "file,label,locomotive,split\n\n../a.csv,x,y,z\n".as_bytes()).unwrap_err();
        assert!(e.to_string().starts_with("m.csv:3: file `../a.csv` must be a relative path"), "{e}");
        let e = parse_manifest("m.csv", "file,label,locomotive,split\n/etc/passwd,x,y,z\n".as_bytes()).unwrap_err();
        assert_eq!(e.line, 2);
    }

    #[test]
    fn manifest_round_trips_fields_with_commas_and_quotes() {
        let dir = tempfile::tempdir().unwrap();
        let rows = vec![ManifestRow {
            file: "t,1.csv".into(),
            label: "a \"b\"".into(),
            locomotive: "loco,7".into(),
            split: "test".into(),
        }];
        write_manifest(&dir.path().join(MANIFEST), &rows).unwrap();
        assert_eq!(read_manifest(dir.path()).unwrap(), rows);
    }
}
