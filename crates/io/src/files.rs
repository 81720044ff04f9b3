//! Opening input files safely: only regular files are read (a FIFO, a device or a socket would
//! block or never end), and a file named by a data set must stay inside it, symbolic links
//! included.

use crate::error::FileError;
use std::fs::File;
use std::path::{Component, Path};

/// Opens `path` for reading if it is a regular file (after following symbolic links); anything
/// else is an error naming the file.
pub fn open_regular(path: &Path) -> Result<File, FileError> {
    let shown = path.display();
    let meta = std::fs::metadata(path).map_err(|e| FileError::new(&shown, 0, format!("cannot read: {e}")))?;
    if !meta.is_file() {
        let what = if meta.is_dir() { "a directory" } else { "not a regular file (a pipe, device or socket)" };
        return Err(FileError::new(&shown, 0, format!("{what}: refused")));
    }
    let file = File::open(path).map_err(|e| FileError::new(&shown, 0, format!("cannot read: {e}")))?;
    // The file may have been swapped between the two calls; check what was opened.
    match file.metadata() {
        Ok(m) if m.is_file() => Ok(file),
        Ok(_) => Err(FileError::new(&shown, 0, "not a regular file: refused")),
        Err(e) => Err(FileError::new(&shown, 0, format!("cannot read: {e}"))),
    }
}

/// Checks that `name` (as written in a data set's manifest) is a relative path without `..`.
pub fn check_relative(name: &str) -> Result<(), String> {
    if name.is_empty() {
        return Err("empty file name".to_owned());
    }
    if Path::new(name).components().any(|c| !matches!(c, Component::Normal(_) | Component::CurDir)) {
        return Err(format!("file `{name}` must be a relative path inside the data set (no `..`, not absolute)"));
    }
    Ok(())
}

/// Checks that `name` (relative, as in a manifest) lies inside the directory `root` once every
/// symbolic link is resolved; `root` must already be canonical ([`std::fs::canonicalize`]).
/// `shown` is the path errors name.
pub fn ensure_inside(root: &Path, name: &str, shown: &Path) -> Result<(), FileError> {
    let shown = shown.display();
    check_relative(name).map_err(|m| FileError::new(&shown, 0, m))?;
    let real =
        std::fs::canonicalize(root.join(name)).map_err(|e| FileError::new(&shown, 0, format!("cannot read: {e}")))?;
    if !real.starts_with(root) {
        return Err(FileError::new(&shown, 0, format!("resolves to {} outside the data set: refused", real.display())));
    }
    Ok(())
}

/// Reads a whole text file: a regular file (see [`open_regular`]) of at most `max_bytes`, in
/// UTF-8.
pub fn read_text(path: &Path, max_bytes: u64) -> Result<String, FileError> {
    use std::io::Read;
    let shown = path.display();
    let file = open_regular(path)?;
    let mut text = String::new();
    file.take(max_bytes + 1)
        .read_to_string(&mut text)
        .map_err(|e| FileError::new(&shown, 0, format!("cannot read: {e}")))?;
    if text.len() as u64 > max_bytes {
        return Err(FileError::new(&shown, 0, format!("larger than the {max_bytes}-byte limit: refused")));
    }
    Ok(text)
}

/// Refuses to run when an output file would overwrite one of the run's inputs (for example
/// `replay DATA --out DATA`, or a CAN log written over the manifest): each existing output is
/// compared, symbolic links resolved, with every input. Checked before anything is written, so
/// a refused run changes no file. The error names both.
pub fn refuse_overwriting_inputs<'a>(
    outputs: impl IntoIterator<Item = &'a Path>,
    inputs: impl IntoIterator<Item = &'a Path>,
) -> Result<(), String> {
    let inputs: Vec<(&Path, std::path::PathBuf)> =
        inputs.into_iter().filter_map(|p| std::fs::canonicalize(p).ok().map(|c| (p, c))).collect();
    for out in outputs {
        let Ok(real) = std::fs::canonicalize(out) else { continue };
        if let Some((input, _)) = inputs.iter().find(|(_, c)| *c == real) {
            return Err(format!(
                "output {} would overwrite the input {}: choose an output outside the inputs",
                out.display(),
                input.display()
            ));
        }
    }
    Ok(())
}
