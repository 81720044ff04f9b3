//! Data sets of SPEC §7: a directory with `manifest.csv` (`file,label,locomotive,split`) and
//! the traces it names (paths relative to the directory). Generated sets also carry
//! `truth.csv`, the ground-truth parameters of every trace (see [`pbm_lab::generate`]).

use std::fmt;
use std::path::{Component, Path, PathBuf};

/// File name of the manifest inside a data set directory.
pub const MANIFEST: &str = "manifest.csv";
/// File name of the ground-truth side file inside a generated data set directory.
pub const TRUTH: &str = "truth.csv";
/// The manifest header, exactly (SPEC §7).
pub const MANIFEST_HEADER: &str = "file,label,locomotive,split";
/// Largest manifest accepted, bytes.
pub const MAX_MANIFEST_BYTES: u64 = 64 << 20;

/// One manifest row.
#[derive(Debug, Clone, PartialEq, Eq)]
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

/// A manifest problem: line (1-based, 0 = whole file) and message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ManifestError {
    /// The manifest path.
    pub file: String,
    /// 1-based line, 0 for the whole file.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for ManifestError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", self.file, self.message)
        } else {
            write!(f, "{}:{}: {}", self.file, self.line, self.message)
        }
    }
}

impl std::error::Error for ManifestError {}

/// Reads `DIR/manifest.csv`.
pub fn read_manifest(dir: &Path) -> Result<Vec<ManifestRow>, ManifestError> {
    let path = dir.join(MANIFEST);
    let name = path.display().to_string();
    let err = |line: usize, message: String| ManifestError { file: name.clone(), line, message };
    let meta = std::fs::metadata(&path).map_err(|e| err(0, format!("cannot read: {e}")))?;
    if meta.len() > MAX_MANIFEST_BYTES {
        return Err(err(0, format!("larger than the {MAX_MANIFEST_BYTES}-byte limit")));
    }
    let bytes = std::fs::read(&path).map_err(|e| err(0, format!("cannot read: {e}")))?;
    let text = String::from_utf8(bytes).map_err(|_| err(0, "not valid UTF-8".to_owned()))?;
    parse_manifest(&name, &text)
}

/// Parses manifest text; `name` is used in errors.
pub fn parse_manifest(name: &str, text: &str) -> Result<Vec<ManifestRow>, ManifestError> {
    let err = |line: usize, message: String| ManifestError { file: name.to_owned(), line, message };
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut rows = Vec::new();
    let mut seen_header = false;
    for (index, raw) in text.split('\n').enumerate() {
        let line_no = index + 1;
        let line = raw.strip_suffix('\r').unwrap_or(raw).trim();
        if line.is_empty() {
            continue;
        }
        if !seen_header {
            let names: Vec<&str> = line.split(',').map(str::trim).collect();
            if names.join(",") != MANIFEST_HEADER {
                return Err(err(line_no, format!("header must be `{MANIFEST_HEADER}`")));
            }
            seen_header = true;
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let [file, label, locomotive, split] = fields.as_slice() else {
            return Err(err(line_no, format!("expected 4 columns, found {}", fields.len())));
        };
        check_relative(file).map_err(|m| err(line_no, m))?;
        if label.is_empty() || locomotive.is_empty() || split.is_empty() {
            return Err(err(line_no, "empty label, locomotive or split".to_owned()));
        }
        rows.push(ManifestRow {
            file: (*file).to_owned(),
            label: (*label).to_owned(),
            locomotive: (*locomotive).to_owned(),
            split: (*split).to_owned(),
        });
    }
    if !seen_header {
        return Err(err(0, format!("empty manifest: expected header `{MANIFEST_HEADER}`")));
    }
    Ok(rows)
}

/// A manifest file path must stay inside the data set: relative, no `..`.
fn check_relative(file: &str) -> Result<(), String> {
    let p = Path::new(file);
    if file.is_empty() {
        return Err("empty file name".to_owned());
    }
    if p.components().any(|c| !matches!(c, Component::Normal(_) | Component::CurDir)) {
        return Err(format!("file `{file}` must be a relative path inside the data set (no `..`, not absolute)"));
    }
    Ok(())
}

/// Path of a manifest row's trace.
pub fn trace_path(dir: &Path, row: &ManifestRow) -> PathBuf {
    dir.join(&row.file)
}

/// Writes a manifest.
pub fn write_manifest(w: &mut impl std::io::Write, rows: &[ManifestRow]) -> std::io::Result<()> {
    writeln!(w, "{MANIFEST_HEADER}")?;
    for r in rows {
        writeln!(w, "{},{},{},{}", r.file, r.label, r.locomotive, r.split)?;
    }
    Ok(())
}
