//! CSV records with their exact file lines.
//!
//! The `csv` crate's reader reports record positions off by the number of blank lines and `\r`
//! bytes before them, and a project error must name the line a person opens. So every CSV
//! reader of the project reads physical lines itself and parses each with the `csv` crate's own
//! parser (`csv_core`), filling a `csv::ByteRecord`: quoting and escaping are the crate's, the
//! line number is exact. A quoted field cannot span lines (none of the project's formats has
//! one), and a `\r` inside a line is a character, not a line end.

use std::io::BufRead;

/// One line of CSV text, classified.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Line {
    /// A record, with its 1-based line: [`CsvLines::record`].
    Record(usize),
    /// A `#` line, with its 1-based line: [`CsvLines::comment`].
    Comment(usize),
}

/// Why a line could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineError {
    /// The input could not be read.
    Io(std::io::ErrorKind),
    /// A comment line is not UTF-8.
    NotUtf8,
    /// A line longer than [`MAX_LINE_BYTES`] (no line of the project's formats comes close; a
    /// file without line breaks would otherwise be read whole into memory).
    TooLong,
    /// A quote opened and not closed on its line (a field cannot span lines).
    UnclosedQuote,
}

/// Longest line read, bytes.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

impl std::fmt::Display for LineError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io(k) => write!(f, "cannot read: {k}"),
            Self::NotUtf8 => f.write_str("not valid UTF-8"),
            Self::TooLong => write!(f, "line longer than {MAX_LINE_BYTES} bytes: not a CSV line"),
            Self::UnclosedQuote => {
                f.write_str("a quoted field is not closed on its line (a field cannot hold a line break)")
            }
        }
    }
}

/// Reads CSV text line by line: blank lines are skipped, a UTF-8 byte-order mark and `\r\n`
/// line ends are accepted.
pub struct CsvLines<R: BufRead> {
    input: R,
    line: usize,
    buf: Vec<u8>,
    out: Vec<u8>,
    ends: Vec<usize>,
    record: csv::ByteRecord,
    comment: std::ops::Range<usize>,
    /// One parser, reset for each line: building one builds its DFA, which cost more than
    /// parsing the line (≈ 18 µs a line, 0.1 s per 6000-sample trace).
    parser: csv_core::Reader,
}

impl<R: BufRead> CsvLines<R> {
    /// Lines of `input`.
    pub fn new(input: R) -> Self {
        Self {
            input,
            line: 0,
            buf: Vec::with_capacity(128),
            out: vec![0; 128],
            ends: vec![0; 16],
            record: csv::ByteRecord::new(),
            comment: 0..0,
            parser: csv_core::ReaderBuilder::new().terminator(csv_core::Terminator::Any(b'\n')).build(),
        }
    }

    /// The 1-based number of the line read last.
    pub fn line(&self) -> usize {
        self.line
    }

    /// The record of the last [`Line::Record`] (fields trimmed of ASCII whitespace).
    pub fn record(&self) -> &csv::ByteRecord {
        &self.record
    }

    /// The text after the `#` of the last [`Line::Comment`] (checked UTF-8).
    pub fn comment(&self) -> &str {
        std::str::from_utf8(self.buf.get(self.comment.clone()).unwrap_or_default()).unwrap_or_default()
    }

    /// The next non-blank line, `None` at the end of the input.
    pub fn next_line(&mut self) -> Option<Result<Line, (usize, LineError)>> {
        loop {
            self.buf.clear();
            match std::io::Read::take(&mut self.input, MAX_LINE_BYTES as u64 + 1).read_until(b'\n', &mut self.buf) {
                Ok(0) => return None,
                Ok(_) => {}
                Err(e) => return Some(Err((self.line + 1, LineError::Io(e.kind())))),
            }
            self.line += 1;
            if self.buf.len() > MAX_LINE_BYTES && !self.buf.ends_with(b"\n") {
                return Some(Err((self.line, LineError::TooLong)));
            }
            let bom = if self.line == 1 && self.buf.starts_with("\u{feff}".as_bytes()) { 3 } else { 0 };
            let text = self.buf[bom..].trim_ascii();
            if text.is_empty() {
                continue;
            }
            if text.starts_with(b"#") {
                // Offsets of the text after the `#` inside `buf`.
                let start = self.buf.len() - self.buf[bom..].trim_ascii_start().len() + 1;
                self.comment = start..start + text.len() - 1;
                return Some(match std::str::from_utf8(&text[1..]) {
                    Ok(_) => Ok(Line::Comment(self.line)),
                    Err(_) => Err((self.line, LineError::NotUtf8)),
                });
            }
            if text.iter().filter(|&&b| b == b'"').count() % 2 == 1 {
                return Some(Err((self.line, LineError::UnclosedQuote)));
            }
            self.parser.reset();
            parse_fields(&mut self.parser, text, &mut self.out, &mut self.ends, &mut self.record);
            return Some(Ok(Line::Record(self.line)));
        }
    }
}

/// Parses one line of CSV into `record` (fields trimmed) with a fresh (or reset) `csv_core`
/// parser whose terminator is `\n`. Only `\n` ends a record, and the line holds none, so the
/// whole line is one record (an unclosed quote runs to the end of the line, as the `csv` crate
/// reads it).
fn parse_fields(
    parser: &mut csv_core::Reader,
    mut input: &[u8],
    out: &mut Vec<u8>,
    ends: &mut Vec<usize>,
    record: &mut csv::ByteRecord,
) {
    use csv_core::ReadRecordResult::{End, InputEmpty, OutputEndsFull, OutputFull, Record};
    let (mut nout, mut nends) = (0, 0);
    loop {
        // Once `input` is empty the parser takes the call as the end of the input and closes
        // the record.
        let (result, nin, o, e) = parser.read_record(input, &mut out[nout..], &mut ends[nends..]);
        input = &input[nin..];
        nout += o;
        nends += e;
        match result {
            InputEmpty => {}
            OutputFull => out.resize(out.len() * 2, 0),
            OutputEndsFull => ends.resize(ends.len() * 2, 0),
            Record | End => break,
        }
    }
    record.clear();
    let mut start = 0;
    for &end in &ends[..nends] {
        record.push_field(out[start..end].trim_ascii());
        start = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    fn lines(text: &str) -> Vec<(usize, Vec<String>)> {
        let mut r = CsvLines::new(text.as_bytes());
        let mut v = Vec::new();
        while let Some(l) = r.next_line() {
            match l.expect("line") {
                Line::Record(n) => {
                    let line = n;
                    v.push((line, r.record().iter().map(|f| String::from_utf8_lossy(f).into_owned()).collect()));
                }
                Line::Comment(n) => v.push((n, vec![format!("#{}", r.comment())])),
            }
        }
        v
    }

    #[test]
    fn lines_are_exact_with_blank_lines_crlf_bom_and_quotes() {
        let v = lines("\u{feff}a, b \r\n\r\n\r\n# note\r\n\"x,y\",\"q\"\"q\"\n  \nlast");
        assert_eq!(
            v,
            vec![
                (1, vec!["a".into(), "b".into()]),
                (4, vec!["# note".into()]),
                (5, vec!["x,y".into(), "q\"q".into()]),
                (7, vec!["last".into()]),
            ]
        );
        assert_eq!(lines("b\rc"), vec![(1, vec!["b\rc".into()])]);
    }

    #[test]
    fn an_open_quote_and_an_endless_line_are_errors() {
        let mut r = CsvLines::new("a,b\n\"open,1\nnext".as_bytes());
        assert!(matches!(r.next_line(), Some(Ok(Line::Record(1)))));
        assert_eq!(r.next_line(), Some(Err((2, LineError::UnclosedQuote))));
        // A file without line breaks is not read whole: the line is refused at the cap.
        let endless = std::io::repeat(b'7').take(10 * MAX_LINE_BYTES as u64);
        let mut r = CsvLines::new(std::io::BufReader::new(endless));
        assert_eq!(r.next_line(), Some(Err((1, LineError::TooLong))));
        assert!(r.buf.capacity() <= 2 * MAX_LINE_BYTES + 1024);
    }

    #[test]
    fn long_lines_grow_the_buffers() {
        let long: Vec<String> = (0..100).map(|i| format!("{i:>20}")).collect();
        let v = lines(&long.join(","));
        assert_eq!(v[0].1.len(), 100);
        assert_eq!(v[0].1[99], "99");
    }
}
