//! Trace files of SPEC §7: reader and ADC writer.
//!
//! A trace is UTF-8 CSV: optional `# key: value` metadata lines, a header whose first two
//! columns are `t_s` and either `p_bar` (gauge pressure, bar) or `adc` (raw 12-bit counts),
//! optional extra numeric columns (such as `x_mm`), then one row per sample with strictly
//! increasing time.
//!
//! The reader never panics: every malformed input is a [`TraceError`] that names the file and
//! the 1-based line (0 when the problem concerns the whole file). Accepted leniencies, so that
//! hand-edited and Windows files load: a UTF-8 byte-order mark, `\r\n` line ends, blank lines,
//! spaces around fields, and `#` lines without the `key: value` form before the header (kept as
//! free comments, not metadata).

use pbm::sensor::ADC_FULL_SCALE;
use std::fmt;
use std::io::Read;
use std::path::Path;

/// Largest trace file the reader accepts, bytes (64 MiB ≈ 7 h of `t_s,adc` at 100 Hz). A 60 s
/// release is about 60 kB; anything near this cap is not a release trace.
pub const MAX_TRACE_BYTES: u64 = 64 << 20;

/// Which quantity the second column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TraceKind {
    /// `p_bar`: gauge pressure, bar.
    PressureBar,
    /// `adc`: raw 12-bit ADC counts.
    Adc,
}

/// The value column of a trace.
#[derive(Debug, Clone, PartialEq)]
pub enum Samples {
    /// Gauge pressure, bar (finite).
    Bar(Vec<f64>),
    /// ADC counts, 0..=4095.
    Adc(Vec<u16>),
}

impl Samples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            Self::Bar(v) => v.len(),
            Self::Adc(v) => v.len(),
        }
    }
    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Which kind of column this is.
    pub fn kind(&self) -> TraceKind {
        match self {
            Self::Bar(_) => TraceKind::PressureBar,
            Self::Adc(_) => TraceKind::Adc,
        }
    }
}

/// A parsed trace.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// Where it came from (file path as given), used in error messages.
    pub source: String,
    /// `# key: value` metadata in file order (keys are unique).
    pub metadata: Vec<(String, String)>,
    /// Sample times, s, strictly increasing.
    pub t_s: Vec<f64>,
    /// The pressure or ADC column.
    pub samples: Samples,
    /// Extra columns after the second: name and values (finite), one value per sample.
    pub extra: Vec<(String, Vec<f64>)>,
    /// 1-based file line of each sample (for errors found after parsing, e.g. sample period).
    pub lines: Vec<usize>,
}

impl Trace {
    /// The value of metadata key `key`, if present.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// Checks that consecutive samples are `period_s` apart within `tolerance_s` (the monitor
    /// assumes a fixed 100 Hz clock); the error names the line of the first offending sample.
    pub fn check_sample_period(&self, period_s: f64, tolerance_s: f64) -> Result<(), TraceError> {
        for (i, w) in self.t_s.windows(2).enumerate() {
            let dt = w[1] - w[0];
            if (dt - period_s).abs() > tolerance_s {
                let line = self.lines.get(i + 1).copied().unwrap_or(0);
                return Err(TraceError::new(
                    &self.source,
                    line,
                    TraceErrorKind::SamplePeriod { expected_s: period_s, found_s: dt },
                ));
            }
        }
        Ok(())
    }
}

/// What is wrong with a trace (small and `Copy`; [`TraceError`] adds file and line).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TraceErrorKind {
    /// The file could not be opened or read.
    Io(std::io::ErrorKind),
    /// The file is larger than [`MAX_TRACE_BYTES`].
    TooLarge {
        /// The cap, bytes.
        limit: u64,
    },
    /// The file holds no bytes (or only blank and comment lines and no header).
    Empty,
    /// The bytes are not UTF-8.
    NotUtf8,
    /// The first non-comment line is data, not a header.
    MissingHeader,
    /// The header does not start with `t_s,p_bar` or `t_s,adc`.
    BadHeader,
    /// A header column name is empty or repeated (1-based column).
    BadColumnName {
        /// 1-based column.
        column: usize,
    },
    /// A metadata key appears twice.
    DuplicateMetadata,
    /// A `#` line after the header (metadata goes before it).
    CommentAfterHeader,
    /// A row has the wrong number of fields.
    ColumnCount {
        /// Columns in the header.
        expected: usize,
        /// Fields in this row.
        found: usize,
    },
    /// A field is not a number (1-based column).
    BadNumber {
        /// 1-based column.
        column: usize,
    },
    /// A field is NaN or infinite (1-based column).
    NotFinite {
        /// 1-based column.
        column: usize,
    },
    /// An `adc` field is not a whole number.
    AdcNotInteger,
    /// An `adc` field is an integer outside 0..=4095.
    AdcOutOfRange {
        /// The value read (saturated to the i64 range).
        value: i64,
    },
    /// Time does not increase from the previous row.
    TimeNotIncreasing {
        /// Time of the previous row, s.
        previous_s: f64,
        /// Time of this row, s.
        found_s: f64,
    },
    /// A header but no rows.
    NoSamples,
    /// Samples are not at the expected fixed period.
    SamplePeriod {
        /// Expected period, s.
        expected_s: f64,
        /// Found interval, s.
        found_s: f64,
    },
}

impl fmt::Display for TraceErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Io(k) => write!(f, "cannot read file: {k}"),
            Self::TooLarge { limit } => write!(f, "file larger than the {limit}-byte limit for a trace"),
            Self::Empty => f.write_str("empty file: expected a `t_s,p_bar` or `t_s,adc` header and samples"),
            Self::NotUtf8 => f.write_str("not valid UTF-8"),
            Self::MissingHeader => {
                f.write_str("missing header: expected `t_s,p_bar` or `t_s,adc` before the first row")
            }
            Self::BadHeader => f.write_str("bad header: must start with `t_s,p_bar` or `t_s,adc`"),
            Self::BadColumnName { column } => write!(f, "bad header: column {column} name is empty or repeated"),
            Self::DuplicateMetadata => f.write_str("metadata key repeated"),
            Self::CommentAfterHeader => f.write_str("`#` line after the header (metadata must come before it)"),
            Self::ColumnCount { expected, found } => write!(f, "expected {expected} columns, found {found}"),
            Self::BadNumber { column } => write!(f, "column {column} is not a number"),
            Self::NotFinite { column } => write!(f, "column {column} is NaN or infinite"),
            Self::AdcNotInteger => f.write_str("adc value is not a whole number of counts"),
            Self::AdcOutOfRange { value } => write!(f, "adc value {value} outside 0..={ADC_FULL_SCALE}"),
            Self::TimeNotIncreasing { previous_s, found_s } => {
                write!(f, "time not increasing: {found_s} s after {previous_s} s")
            }
            Self::NoSamples => f.write_str("header but no samples"),
            Self::SamplePeriod { expected_s, found_s } => {
                write!(f, "sample interval {found_s:.6} s, expected {expected_s} s (fixed 100 Hz clock)")
            }
        }
    }
}

/// A malformed or unreadable trace: file, 1-based line (0 = whole file) and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceError {
    /// The file as named by the caller.
    pub file: String,
    /// 1-based line, 0 when the error is not about one line.
    pub line: usize,
    /// What is wrong.
    pub kind: TraceErrorKind,
}

impl TraceError {
    /// An error about `file` at `line`.
    pub fn new(file: &str, line: usize, kind: TraceErrorKind) -> Self {
        Self { file: file.to_owned(), line, kind }
    }
}

impl fmt::Display for TraceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", self.file, self.kind)
        } else {
            write!(f, "{}:{}: {}", self.file, self.line, self.kind)
        }
    }
}

impl std::error::Error for TraceError {}

/// Reads and parses a trace file (at most [`MAX_TRACE_BYTES`]).
pub fn read_trace(path: &Path) -> Result<Trace, TraceError> {
    let name = path.display().to_string();
    let io_err = |e: std::io::Error| TraceError::new(&name, 0, TraceErrorKind::Io(e.kind()));
    let file = std::fs::File::open(path).map_err(io_err)?;
    let mut bytes = Vec::new();
    // Read one byte past the cap so that a file growing under us is still caught.
    file.take(MAX_TRACE_BYTES + 1).read_to_end(&mut bytes).map_err(io_err)?;
    if bytes.len() as u64 > MAX_TRACE_BYTES {
        return Err(TraceError::new(&name, 0, TraceErrorKind::TooLarge { limit: MAX_TRACE_BYTES }));
    }
    parse_trace(&name, &bytes)
}

/// Parses trace bytes; `source` names the file in errors.
pub fn parse_trace(source: &str, bytes: &[u8]) -> Result<Trace, TraceError> {
    let err = |line: usize, kind: TraceErrorKind| TraceError::new(source, line, kind);
    if bytes.len() as u64 > MAX_TRACE_BYTES {
        return Err(err(0, TraceErrorKind::TooLarge { limit: MAX_TRACE_BYTES }));
    }
    let text = match std::str::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => {
            let line = 1 + bytes.get(..e.valid_up_to()).map_or(0, |b| b.iter().filter(|&&c| c == b'\n').count());
            return Err(err(line, TraceErrorKind::NotUtf8));
        }
    };
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if text.trim().is_empty() {
        return Err(err(0, TraceErrorKind::Empty));
    }

    let mut metadata: Vec<(String, String)> = Vec::new();
    let mut header: Option<(TraceKind, Vec<String>)> = None;
    let mut t_s = Vec::new();
    let mut bar = Vec::new();
    let mut adc = Vec::new();
    let mut extra: Vec<Vec<f64>> = Vec::new();
    let mut lines = Vec::new();

    for (index, raw) in text.split('\n').enumerate() {
        let line_no = index + 1;
        let line = raw.strip_suffix('\r').unwrap_or(raw).trim();
        if line.is_empty() {
            continue;
        }
        if let Some(comment) = line.strip_prefix('#') {
            if header.is_some() {
                return Err(err(line_no, TraceErrorKind::CommentAfterHeader));
            }
            if let Some((key, value)) = comment.split_once(':') {
                let key = key.trim();
                if !key.is_empty() && !key.contains(char::is_whitespace) {
                    if metadata.iter().any(|(k, _)| k == key) {
                        return Err(err(line_no, TraceErrorKind::DuplicateMetadata));
                    }
                    metadata.push((key.to_owned(), value.trim().to_owned()));
                }
            }
            continue;
        }
        let Some((kind, names)) = &header else {
            header = Some(parse_header(line).map_err(|k| err(line_no, k))?);
            if let Some((_, names)) = &header {
                extra = vec![Vec::new(); names.len().saturating_sub(2)];
            }
            continue;
        };
        let mut fields = line.split(',').map(str::trim);
        let found = line.split(',').count();
        if found != names.len() {
            return Err(err(line_no, TraceErrorKind::ColumnCount { expected: names.len(), found }));
        }
        let t = parse_finite(fields.next().unwrap_or(""), 1).map_err(|k| err(line_no, k))?;
        if let Some(&previous_s) = t_s.last() {
            if t <= previous_s {
                return Err(err(line_no, TraceErrorKind::TimeNotIncreasing { previous_s, found_s: t }));
            }
        }
        let value = fields.next().unwrap_or("");
        match kind {
            TraceKind::PressureBar => bar.push(parse_finite(value, 2).map_err(|k| err(line_no, k))?),
            TraceKind::Adc => adc.push(parse_adc(value).map_err(|k| err(line_no, k))?),
        }
        for (i, (field, column)) in fields.zip(extra.iter_mut()).enumerate() {
            column.push(parse_finite(field, i + 3).map_err(|k| err(line_no, k))?);
        }
        t_s.push(t);
        lines.push(line_no);
    }

    let Some((kind, names)) = header else {
        return Err(err(0, TraceErrorKind::Empty));
    };
    if t_s.is_empty() {
        return Err(err(0, TraceErrorKind::NoSamples));
    }
    let samples = match kind {
        TraceKind::PressureBar => Samples::Bar(bar),
        TraceKind::Adc => Samples::Adc(adc),
    };
    let extra = names.into_iter().skip(2).zip(extra).collect();
    Ok(Trace { source: source.to_owned(), metadata, t_s, samples, extra, lines })
}

fn parse_header(line: &str) -> Result<(TraceKind, Vec<String>), TraceErrorKind> {
    let names: Vec<String> = line.split(',').map(|s| s.trim().to_owned()).collect();
    // A row of numbers where the header should be: say so rather than "bad header".
    if names.first().is_some_and(|n| n.parse::<f64>().is_ok()) {
        return Err(TraceErrorKind::MissingHeader);
    }
    let kind = match (names.first().map(String::as_str), names.get(1).map(String::as_str)) {
        (Some("t_s"), Some("p_bar")) => TraceKind::PressureBar,
        (Some("t_s"), Some("adc")) => TraceKind::Adc,
        _ => return Err(TraceErrorKind::BadHeader),
    };
    for (i, name) in names.iter().enumerate() {
        if name.is_empty() || names.get(..i).is_some_and(|before| before.contains(name)) {
            return Err(TraceErrorKind::BadColumnName { column: i + 1 });
        }
    }
    Ok((kind, names))
}

fn parse_finite(field: &str, column: usize) -> Result<f64, TraceErrorKind> {
    let v: f64 = field.parse().map_err(|_| TraceErrorKind::BadNumber { column })?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(TraceErrorKind::NotFinite { column })
    }
}

fn parse_adc(field: &str) -> Result<u16, TraceErrorKind> {
    if !field.is_empty() && field.bytes().all(|b| b.is_ascii_digit()) {
        // All digits: an integer, possibly huge.
        let value = field.parse::<i64>().unwrap_or(i64::MAX);
        return u16::try_from(value)
            .ok()
            .filter(|&c| c <= ADC_FULL_SCALE)
            .ok_or(TraceErrorKind::AdcOutOfRange { value });
    }
    if let Some(digits) = field.strip_prefix('-') {
        if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) {
            let value = field.parse::<i64>().unwrap_or(i64::MIN);
            return Err(TraceErrorKind::AdcOutOfRange { value });
        }
    }
    match field.parse::<f64>() {
        Ok(v) if !v.is_finite() => Err(TraceErrorKind::NotFinite { column: 2 }),
        Ok(_) => Err(TraceErrorKind::AdcNotInteger),
        Err(_) => Err(TraceErrorKind::BadNumber { column: 2 }),
    }
}

/// Time column text `i · 10 ms` with two decimals, as written by the generator
/// (exact decimal text, no float formatting drift).
pub fn time_text(sample: usize) -> String {
    format!("{}.{:02}", sample / 100, sample % 100)
}

/// Writes an ADC trace: metadata comments, `t_s,adc`, one row per sample at 100 Hz from t = 0.
pub fn write_adc_trace(w: &mut impl std::io::Write, meta: &[(&str, String)], adc: &[u16]) -> std::io::Result<()> {
    let mut out = String::with_capacity(adc.len() * 10 + 256);
    for (k, v) in meta {
        out.push_str("# ");
        out.push_str(k);
        out.push_str(": ");
        out.push_str(v);
        out.push('\n');
    }
    out.push_str("t_s,adc\n");
    for (i, &c) in adc.iter().enumerate() {
        use std::fmt::Write as _;
        // Writing into a String cannot fail.
        let _ = writeln!(out, "{}.{:02},{}", i / 100, i % 100, c);
    }
    w.write_all(out.as_bytes())
}
