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
