//! One error type for every input file, and the record of inputs a run skipped.
//!
//! The policy of every host tool that reads many files: a bad file is reported with its name and
//! line and skipped, the rest of the run completes and writes its outputs, and the tool's exit
//! status says that something was skipped ([`SKIPPED_EXIT_CODE`]).

use std::fmt;

/// Exit status of a run that completed but skipped at least one bad input (0: nothing skipped,
/// 1: the run failed; 2 is taken by command-line usage errors).
pub const SKIPPED_EXIT_CODE: u8 = 3;

/// Exit status of a check that ran to its end on readable input and found what it checks for
/// wrong (`can decode --strict`: a flagged, lost or stale frame, or no frame at all). Distinct
/// from 1 so that a CI job can tell "the link is bad" from "the log could not be read".
pub const CHECK_FAILED_EXIT_CODE: u8 = 4;

/// The error of a check that failed ([`CHECK_FAILED_EXIT_CODE`]): what it found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CheckFailed(pub String);

impl fmt::Display for CheckFailed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CheckFailed {}

/// A problem with an input file: the file, the 1-based line (0 when it concerns the whole file)
/// and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FileError {
    /// The file as named by the caller.
    pub file: String,
    /// 1-based line, 0 when the problem is not about one line.
    pub line: usize,
    /// What is wrong, in words.
    pub message: String,
}

impl FileError {
    /// A problem of `file` at `line` (0 = the whole file).
    pub fn new(file: impl fmt::Display, line: usize, message: impl fmt::Display) -> Self {
        Self { file: file.to_string(), line, message: message.to_string() }
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_located(f, &self.file, self.line, &self.message)
    }
}

/// Writes `file:line: what` (`file: what` for line 0): how every input error of the project
/// names its place.
pub fn write_located(f: &mut fmt::Formatter<'_>, file: &str, line: usize, what: &dyn fmt::Display) -> fmt::Result {
    if line == 0 {
        write!(f, "{file}: {what}")
    } else {
        write!(f, "{file}:{line}: {what}")
    }
}

impl std::error::Error for FileError {}

/// The inputs a run skipped, each with why.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Skipped(Vec<FileError>);

impl Skipped {
    /// Nothing skipped.
    pub fn none() -> Self {
        Self::default()
    }
    /// The given errors as skipped inputs.
    pub fn of(errors: &[FileError]) -> Self {
        Self(errors.to_vec())
    }
    /// Records a skipped input.
    pub fn push(&mut self, e: impl Into<FileError>) {
        self.0.push(e.into());
    }
    /// Adds another run's skipped inputs.
    pub fn extend(&mut self, other: Skipped) {
        self.0.extend(other.0);
    }
    /// True when nothing was skipped.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
    /// How many inputs were skipped.
    pub fn len(&self) -> usize {
        self.0.len()
    }
    /// The skipped inputs in the order they were found.
    pub fn errors(&self) -> &[FileError] {
        &self.0
    }
}

impl fmt::Display for Skipped {
    /// One line per skipped input, then a count.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for e in &self.0 {
            writeln!(f, "skipped: {e}")?;
        }
        write!(f, "{} input(s) skipped", self.0.len())
    }
}
