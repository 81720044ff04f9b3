//! Trace files of SPEC §7: a streaming reader ([`TraceReader`]: one sample at a time, memory
//! independent of the trace's length), a collecting one ([`read_trace`]) and the ADC writer.
//!
//! A trace is UTF-8 CSV: optional `# key: value` metadata lines, a header whose first two
//! columns are `t_s` and either `p_bar` (gauge pressure, bar) or `adc` (raw 12-bit counts),
//! optional extra numeric columns (such as `x_mm`), then one row per sample with strictly
//! increasing time. Rows are read by the `csv` crate.
//!
//! The reader never panics: every malformed input is a [`TraceError`] that names the file and
//! the 1-based line (0 when the problem concerns the whole file). Accepted leniencies, so that
//! hand-edited and Windows files load: a UTF-8 byte-order mark, `\r\n` line ends, blank lines,
//! spaces around fields, and `#` lines without the `key: value` form before the header (kept as
//! free comments, not metadata). Metadata keys are taken exactly as written (case and all).

use crate::error::FileError;
use crate::files::open_regular;
use crate::lines::{CsvLines, Line, LineError};
use pbm::sensor::ADC_FULL_SCALE;
use std::fmt;
use std::io::{BufRead, BufReader};
use std::path::Path;

/// Largest trace file [`read_trace`] collects into memory, bytes (64 MiB ≈ 7 h of `t_s,adc` at
/// 100 Hz); a 60 s release is about 60 kB. [`TraceReader`] streams files of any length.
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
    /// The samples as ADC counts (a `p_bar` trace through the sensor map of SPEC §5, no noise).
    pub fn adc_counts(&self) -> Vec<u16> {
        match &self.samples {
            Samples::Adc(v) => v.clone(),
            Samples::Bar(v) => v.iter().map(|&p| pbm::sensor::adc_from_bar(pbm::BarG(p)).0).collect(),
        }
    }

    /// The samples as gauge pressures, bar (an `adc` trace through the inverse sensor map).
    pub fn pressures_bar(&self) -> Vec<f64> {
        match &self.samples {
            Samples::Bar(v) => v.clone(),
            Samples::Adc(v) => v.iter().map(|&c| pbm::sensor::bar_from_adc(pbm::AdcCounts(c)).0).collect(),
        }
    }

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
    /// The path is not a regular file (a directory, pipe, device or socket).
    NotRegularFile,
    /// The file is larger than [`MAX_TRACE_BYTES`].
    TooLarge {
        /// The cap, bytes.
        limit: u64,
    },
    /// The file holds no bytes (or only blank and comment lines and no header).
    Empty,
    /// The bytes are not UTF-8.
    NotUtf8,
    /// A line is not a CSV line (too long, or a quote left open).
    BadLine(LineError),
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
            Self::NotRegularFile => f.write_str("not a regular file (a directory, pipe, device or socket): refused"),
            Self::TooLarge { limit } => write!(f, "file larger than the {limit}-byte limit for a trace"),
            Self::Empty => f.write_str("empty file: expected a `t_s,p_bar` or `t_s,adc` header and samples"),
            Self::NotUtf8 => f.write_str("not valid UTF-8"),
            Self::BadLine(e) => write!(f, "{e}"),
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
        crate::error::write_located(f, &self.file, self.line, &self.kind)
    }
}

impl std::error::Error for TraceError {}

impl From<TraceError> for FileError {
    fn from(e: TraceError) -> Self {
        FileError::new(e.file, e.line, e.kind)
    }
}

/// One sample of a trace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// The pressure or ADC value.
    pub value: Value,
    /// 1-based file line.
    pub line: usize,
}

/// The value of one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    /// Gauge pressure, bar (finite).
    Bar(f64),
    /// ADC counts, 0..=4095.
    Adc(u16),
}

/// Reads a trace one sample at a time: metadata and header when it is created, then one
/// [`Sample`] per call of [`Iterator::next`]; after an error it yields nothing more. Memory does
/// not grow with the trace.
pub struct TraceReader<R: BufRead> {
    source: String,
    metadata: Vec<(String, String)>,
    kind: TraceKind,
    columns: Vec<String>,
    lines: CsvLines<R>,
    extra: Vec<f64>,
    previous_t: Option<f64>,
    period: Option<(f64, f64)>,
    samples: usize,
    done: bool,
}

impl TraceReader<BufReader<std::fs::File>> {
    /// Opens a trace file (regular files only) and reads its metadata and header.
    pub fn open(path: &Path) -> Result<Self, TraceError> {
        let name = path.display().to_string();
        let file = open_regular(path).map_err(|_| {
            let kind = match std::fs::metadata(path) {
                Ok(_) => TraceErrorKind::NotRegularFile,
                Err(io) => TraceErrorKind::Io(io.kind()),
            };
            TraceError::new(&name, 0, kind)
        })?;
        Self::new(&name, BufReader::new(file))
    }
}

impl<R: BufRead> TraceReader<R> {
    /// Reads the metadata and header from `input`; `source` names the file in errors.
    pub fn new(source: &str, input: R) -> Result<Self, TraceError> {
        let err = |line: usize, kind: TraceErrorKind| TraceError::new(source, line, kind);
        let mut lines = CsvLines::new(input);
        let mut metadata: Vec<(String, String)> = Vec::new();
        let (kind, columns) = loop {
            let line = match lines.next_line() {
                None => return Err(err(0, TraceErrorKind::Empty)),
                Some(Err((line, e))) => return Err(err(line, line_error(e))),
                Some(Ok(Line::Comment(line))) => {
                    if let Some((key, value)) = lines.comment().split_once(':') {
                        let key = key.trim();
                        if !key.is_empty() && !key.contains(char::is_whitespace) {
                            if metadata.iter().any(|(k, _)| k == key) {
                                return Err(err(line, TraceErrorKind::DuplicateMetadata));
                            }
                            metadata.push((key.to_owned(), value.trim().to_owned()));
                        }
                    }
                    continue;
                }
                Some(Ok(Line::Record(line))) => line,
            };
            let names: Result<Vec<String>, _> =
                lines.record().iter().map(|f| std::str::from_utf8(f).map(str::to_owned)).collect();
            let names = names.map_err(|_| err(line, TraceErrorKind::NotUtf8))?;
            break parse_header(&names).map_err(|k| err(line, k))?;
        };
        Ok(Self {
            source: source.to_owned(),
            metadata,
            kind,
            extra: Vec::with_capacity(columns.len().saturating_sub(2)),
            columns,
            lines,
            previous_t: None,
            period: None,
            samples: 0,
            done: false,
        })
    }

    /// The file as named in errors.
    pub fn source(&self) -> &str {
        &self.source
    }
    /// `# key: value` metadata in file order (keys are unique).
    pub fn metadata(&self) -> &[(String, String)] {
        &self.metadata
    }
    /// The value of metadata key `key` (exact match), if present.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }
    /// Which quantity the value column holds.
    pub fn kind(&self) -> TraceKind {
        self.kind
    }
    /// Names of the extra columns after the second.
    pub fn extra_columns(&self) -> &[String] {
        self.columns.get(2..).unwrap_or(&[])
    }
    /// The extra columns' values of the sample read last.
    pub fn extra(&self) -> &[f64] {
        &self.extra
    }
    /// Samples read so far.
    pub fn samples_read(&self) -> usize {
        self.samples
    }
    /// From now on, consecutive samples must be `period_s` apart within `tolerance_s` (the
    /// monitor's clock is the sample count); a gap is a [`TraceErrorKind::SamplePeriod`] error.
    pub fn expect_period(&mut self, period_s: f64, tolerance_s: f64) {
        self.period = Some((period_s, tolerance_s));
    }

    fn fail(&mut self, line: usize, kind: TraceErrorKind) -> Option<Result<Sample, TraceError>> {
        self.done = true;
        Some(Err(TraceError::new(&self.source, line, kind)))
    }

    fn sample(&mut self, line: usize) -> Result<Sample, TraceErrorKind> {
        let record = self.lines.record();
        let expected = self.columns.len();
        if record.len() != expected {
            return Err(TraceErrorKind::ColumnCount { expected, found: record.len() });
        }
        let field = |i: usize| std::str::from_utf8(&record[i]).map_err(|_| TraceErrorKind::NotUtf8);
        let t = parse_finite(field(0)?, 1)?;
        if let Some(previous_s) = self.previous_t {
            if t <= previous_s {
                return Err(TraceErrorKind::TimeNotIncreasing { previous_s, found_s: t });
            }
            if let Some((expected_s, tolerance_s)) = self.period {
                let found_s = t - previous_s;
                if (found_s - expected_s).abs() > tolerance_s {
                    return Err(TraceErrorKind::SamplePeriod { expected_s, found_s });
                }
            }
        }
        let value = match self.kind {
            TraceKind::PressureBar => Value::Bar(parse_finite(field(1)?, 2)?),
            TraceKind::Adc => Value::Adc(parse_adc(field(1)?)?),
        };
        self.extra.clear();
        for i in 2..expected {
            self.extra.push(parse_finite(field(i)?, i + 1)?);
        }
        self.previous_t = Some(t);
        Ok(Sample { t_s: t, value, line })
    }
}

fn line_error(e: LineError) -> TraceErrorKind {
    match e {
        LineError::Io(k) => TraceErrorKind::Io(k),
        LineError::NotUtf8 => TraceErrorKind::NotUtf8,
        e => TraceErrorKind::BadLine(e),
    }
}

impl<R: BufRead> Iterator for TraceReader<R> {
    type Item = Result<Sample, TraceError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let line = match self.lines.next_line() {
            None => {
                self.done = true;
                if self.samples == 0 {
                    return Some(Err(TraceError::new(&self.source, 0, TraceErrorKind::NoSamples)));
                }
                return None;
            }
            Some(Err((line, e))) => return self.fail(line, line_error(e)),
            Some(Ok(Line::Comment(line))) => return self.fail(line, TraceErrorKind::CommentAfterHeader),
            Some(Ok(Line::Record(line))) => line,
        };
        match self.sample(line) {
            Ok(s) => {
                self.samples += 1;
                Some(Ok(s))
            }
            Err(kind) => self.fail(line, kind),
        }
    }
}

/// Reads a whole trace file into memory (at most [`MAX_TRACE_BYTES`]; stream longer ones with
/// [`TraceReader`]).
pub fn read_trace(path: &Path) -> Result<Trace, TraceError> {
    let name = path.display().to_string();
    if let Ok(meta) = std::fs::metadata(path) {
        if meta.is_file() && meta.len() > MAX_TRACE_BYTES {
            return Err(TraceError::new(&name, 0, TraceErrorKind::TooLarge { limit: MAX_TRACE_BYTES }));
        }
    }
    collect(TraceReader::open(path)?)
}

/// Tolerance on the 10 ms sample interval of a release trace, s.
pub const PERIOD_TOLERANCE_S: f64 = 1e-3;

/// Reads a release trace for the monitor's tools: [`read_trace`] plus the fixed 100 Hz clock of
/// the ADC (SPEC §5), checked sample by sample (the error names the first offending line).
pub fn read_release_trace(path: &Path) -> Result<Trace, TraceError> {
    let trace = read_trace(path)?;
    trace.check_sample_period(pbm::twin::SAMPLE_PERIOD_S, PERIOD_TOLERANCE_S)?;
    Ok(trace)
}

/// Parses trace bytes; `source` names the file in errors.
pub fn parse_trace(source: &str, bytes: &[u8]) -> Result<Trace, TraceError> {
    if bytes.len() as u64 > MAX_TRACE_BYTES {
        return Err(TraceError::new(source, 0, TraceErrorKind::TooLarge { limit: MAX_TRACE_BYTES }));
    }
    collect(TraceReader::new(source, bytes)?)
}

/// Reads every remaining sample of `reader` into a [`Trace`].
pub fn collect<R: BufRead>(mut reader: TraceReader<R>) -> Result<Trace, TraceError> {
    let mut t_s = Vec::new();
    let mut bar = Vec::new();
    let mut adc = Vec::new();
    let mut extra: Vec<Vec<f64>> = vec![Vec::new(); reader.extra_columns().len()];
    let mut lines = Vec::new();
    while let Some(sample) = reader.next() {
        let s = sample?;
        t_s.push(s.t_s);
        lines.push(s.line);
        match s.value {
            Value::Bar(p) => bar.push(p),
            Value::Adc(c) => adc.push(c),
        }
        for (column, &v) in extra.iter_mut().zip(reader.extra()) {
            column.push(v);
        }
    }
    let samples = match reader.kind {
        TraceKind::PressureBar => Samples::Bar(bar),
        TraceKind::Adc => Samples::Adc(adc),
    };
    let extra = reader.extra_columns().iter().cloned().zip(extra).collect();
    Ok(Trace { source: reader.source, metadata: reader.metadata, t_s, samples, extra, lines })
}

fn parse_header(names: &[String]) -> Result<(TraceKind, Vec<String>), TraceErrorKind> {
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
    Ok((kind, names.to_vec()))
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

/// Writes `# key: value` metadata lines (a value's line breaks become spaces, so a value can
/// never end the metadata early).
pub fn write_metadata(w: &mut impl std::io::Write, meta: &[(&str, String)]) -> std::io::Result<()> {
    for (k, v) in meta {
        writeln!(w, "# {k}: {}", v.replace(['\n', '\r'], " "))?;
    }
    Ok(())
}

/// Writes an ADC trace: metadata comments, `t_s,adc`, one row per sample at 100 Hz from t = 0.
pub fn write_adc_trace(w: &mut impl std::io::Write, meta: &[(&str, String)], adc: &[u16]) -> std::io::Result<()> {
    let mut out = Vec::with_capacity(adc.len() * 10 + 256);
    write_metadata(&mut out, meta)?;
    {
        let mut rows = csv::Writer::from_writer(&mut out);
        rows.write_record(["t_s", "adc"])?;
        // Reused buffers: a paper-size data set writes 35 M rows.
        let (mut t, mut v) = (String::new(), String::new());
        for (i, &c) in adc.iter().enumerate() {
            use std::fmt::Write as _;
            t.clear();
            v.clear();
            let _ = write!(t, "{}.{:02}", i / 100, i % 100);
            let _ = write!(v, "{c}");
            rows.write_record([&t, &v])?;
        }
        rows.flush()?;
    }
    w.write_all(&out)
}
