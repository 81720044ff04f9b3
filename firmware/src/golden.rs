//! Golden checkpoints of the nominal release: the fixed-point twin's exact state at a few
//! instants, computed on the host and compared bit for bit on the target.
//!
//! File `tests/golden/nominal_checkpoints.csv` (written by the core test `tests/golden_twin.rs`,
//! regenerated with `UPDATE_GOLDEN=1`): optional `#` comment lines, the header [`HEADER`], then
//! one row per checkpoint, all integers:
//!
//! - `updates`: `Twin::update(true)` calls since the release command (10 ms each; 100 = 1 s),
//!   strictly increasing;
//! - `p_q24`: chamber pressure, Q7.24 bar absolute (`PressureQ24`);
//! - `x_q32`: piston travel, Q32 m.
//!
//! This module uses `core` only: the host test includes the same source file, so the host and
//! the firmware read the file with one parser.

use core::fmt;

/// Header line of the checkpoint file.
pub const HEADER: &str = "updates,p_q24,x_q32";
/// Most checkpoints a file may hold.
pub const MAX_CHECKPOINTS: usize = 16;
/// Where the host takes checkpoints, in updates since the release command
/// (t = 1, 5, 10, 15, 20, 22, 25, 30, 60 s: breakaway, stroke, end stop, plateau).
pub const CHECKPOINT_UPDATES: [u32; 9] = [100, 500, 1000, 1500, 2000, 2200, 2500, 3000, 6000];

/// The twin's state after `updates` samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Checkpoint {
    /// Twin updates (10 ms samples) since the release command.
    pub updates: u32,
    /// Chamber pressure, Q7.24 bar absolute.
    pub p_q24: i32,
    /// Piston travel, Q32 m.
    pub x_q32: i32,
}

/// Why a checkpoint file was rejected; `line` is 1-based.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GoldenError {
    /// No header line before the first data row (or no lines at all).
    MissingHeader,
    /// A row does not have exactly three comma-separated fields.
    FieldCount {
        /// Line number.
        line: usize,
    },
    /// A field is not a decimal integer of its type.
    BadNumber {
        /// Line number.
        line: usize,
    },
    /// `updates` is zero or not greater than the previous row's.
    NotIncreasing {
        /// Line number.
        line: usize,
    },
    /// More than [`MAX_CHECKPOINTS`] rows.
    TooMany {
        /// Line number.
        line: usize,
    },
    /// A header but no rows.
    Empty,
}

impl fmt::Display for GoldenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::MissingHeader => write!(f, "missing header `{HEADER}`"),
            Self::FieldCount { line } => write!(f, "line {line}: expected 3 fields `{HEADER}`"),
            Self::BadNumber { line } => write!(f, "line {line}: field is not an integer in range"),
            Self::NotIncreasing { line } => write!(f, "line {line}: `updates` must be > 0 and increasing"),
            Self::TooMany { line } => write!(f, "line {line}: more than {MAX_CHECKPOINTS} checkpoints"),
            Self::Empty => write!(f, "no checkpoints after the header"),
        }
    }
}

/// Parsed checkpoints, in file order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Checkpoints {
    items: [Checkpoint; MAX_CHECKPOINTS],
    len: usize,
}

impl Checkpoints {
    /// The checkpoints.
    pub fn as_slice(&self) -> &[Checkpoint] {
        self.items.get(..self.len).unwrap_or(&[])
    }

    /// Mutable access (used by the firmware's self-test that corrupts one value).
    pub fn as_mut_slice(&mut self) -> &mut [Checkpoint] {
        self.items.get_mut(..self.len).unwrap_or(&mut [])
    }
}

/// Parses a checkpoint file; never panics, whatever the text.
pub fn parse(text: &str) -> Result<Checkpoints, GoldenError> {
    let mut out = Checkpoints { items: [Checkpoint::default(); MAX_CHECKPOINTS], len: 0 };
    let mut seen_header = false;
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        let row = raw.trim();
        if row.is_empty() || row.starts_with('#') {
            continue;
        }
        if !seen_header {
            if row != HEADER {
                return Err(GoldenError::MissingHeader);
            }
            seen_header = true;
            continue;
        }
        let mut fields = row.split(',');
        let (Some(a), Some(b), Some(c), None) = (fields.next(), fields.next(), fields.next(), fields.next()) else {
            return Err(GoldenError::FieldCount { line });
        };
        let bad = GoldenError::BadNumber { line };
        let cp = Checkpoint {
            updates: a.trim().parse().map_err(|_| bad)?,
            p_q24: b.trim().parse().map_err(|_| bad)?,
            x_q32: c.trim().parse().map_err(|_| bad)?,
        };
        let previous = out.as_slice().last().map_or(0, |p| p.updates);
        if cp.updates <= previous {
            return Err(GoldenError::NotIncreasing { line });
        }
        let Some(slot) = out.items.get_mut(out.len) else {
            return Err(GoldenError::TooMany { line });
        };
        *slot = cp;
        out.len += 1;
    }
    if !seen_header {
        return Err(GoldenError::MissingHeader);
    }
    if out.len == 0 {
        return Err(GoldenError::Empty);
    }
    Ok(out)
}

/// Writes a checkpoint file (the inverse of [`parse`]), with `comment` lines first.
pub fn write_csv(w: &mut impl fmt::Write, comment: &[&str], rows: &[Checkpoint]) -> fmt::Result {
    for c in comment {
        writeln!(w, "# {c}")?;
    }
    writeln!(w, "{HEADER}")?;
    for r in rows {
        writeln!(w, "{},{},{}", r.updates, r.p_q24, r.x_q32)?;
    }
    Ok(())
}
