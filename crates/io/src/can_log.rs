//! candump log files (`candump -L` / `canplayer` format) and the recorder that turns the
//! monitor's per-sample output into CAN frames through the core's [`CanReporter`].
//!
//! One line per frame: `(SECONDS.MICROS) IFACE ID#DATA`, e.g.
//! `(0000000001.000000) can0 18FF5080#0102030405060708`. Extended identifiers are written as
//! 8 hex digits, standard ones as 3; data as upper-case hex pairs; a remote frame as `ID#R`
//! (or `ID#R<len>`). The reader also accepts lower case, blank lines and `#` comments, and
//! rejects CAN FD (`ID##…`), error frames and anything malformed with a clear message (line
//! number and reason); it never panics.

use crate::can_bus::FrameSink;
use embedded_can::{ExtendedId, Frame, Id, StandardId};
use pbm::can::{CanFrame, CanReporter, PowerUp};
use pbm::monitor::Monitor;
use pbm::pipeline::fault_report;
use pbm::report::Verdict;
use std::io::{BufRead, Write};

/// The interface name written when none is given.
pub const DEFAULT_IFACE: &str = "can0";

/// One frame of a candump log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogRecord {
    /// Time stamp, µs.
    pub time_us: u64,
    /// Interface name as logged.
    pub iface: String,
    /// The frame.
    pub frame: CanFrame,
}

/// Why a log line is not a frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong.
    pub reason: String,
}

impl std::fmt::Display for LogError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "line {}: {}", self.line, self.reason)
    }
}

impl std::error::Error for LogError {}

/// Formats a frame as `ID#DATA` (or `ID#R`, `ID#R<len>` for a remote frame).
pub fn format_frame(frame: &CanFrame) -> String {
    pbm::can::candump::FrameText(frame).to_string()
}

/// One complete log line (without the newline).
pub fn format_line(time_us: u64, iface: &str, frame: &CanFrame) -> String {
    pbm::can::candump::Line { time_us, iface, frame }.to_string()
}

fn parse_time(tok: &str) -> Result<u64, String> {
    let inner = tok.strip_prefix('(').and_then(|t| t.strip_suffix(')')).ok_or("time stamp must be (SECONDS.MICROS)")?;
    let (secs, frac) = inner.split_once('.').ok_or("time stamp must be (SECONDS.MICROS)")?;
    if secs.is_empty() || !secs.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("bad seconds in time stamp {tok:?}"));
    }
    if frac.is_empty() || frac.len() > 6 || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("bad fraction in time stamp {tok:?} (1 to 6 digits)"));
    }
    let secs: u64 = secs.parse().map_err(|_| format!("time stamp {tok:?} out of range"))?;
    let mut micros: u64 = frac.parse().map_err(|_| format!("bad fraction in time stamp {tok:?}"))?;
    for _ in frac.len()..6 {
        micros *= 10;
    }
    secs.checked_mul(1_000_000)
        .and_then(|s| s.checked_add(micros))
        .ok_or_else(|| format!("time stamp {tok:?} out of range"))
}

fn hex_byte(pair: &[u8]) -> Option<u8> {
    let s = std::str::from_utf8(pair).ok()?;
    u8::from_str_radix(s, 16).ok()
}

/// Parses `ID#DATA`.
pub fn parse_frame(tok: &str) -> Result<CanFrame, String> {
    let (id_txt, rest) = tok.split_once('#').ok_or_else(|| format!("frame {tok:?} has no '#'"))?;
    if rest.starts_with('#') {
        return Err("CAN FD frame (ID##…): not supported, the monitor uses classical CAN".into());
    }
    if id_txt.is_empty() || !id_txt.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!("bad identifier {id_txt:?}"));
    }
    let id: Id = match id_txt.len() {
        3 => {
            let raw = u16::from_str_radix(id_txt, 16).map_err(|_| format!("bad identifier {id_txt:?}"))?;
            StandardId::new(raw).ok_or_else(|| format!("standard identifier {id_txt} above 0x7FF"))?.into()
        }
        8 => {
            let raw = u32::from_str_radix(id_txt, 16).map_err(|_| format!("bad identifier {id_txt:?}"))?;
            if raw & 0x2000_0000 != 0 {
                return Err(format!("error frame {id_txt}"));
            }
            ExtendedId::new(raw).ok_or_else(|| format!("extended identifier {id_txt} above 0x1FFFFFFF"))?.into()
        }
        n => return Err(format!("identifier {id_txt:?} has {n} digits (3 = standard, 8 = extended)")),
    };
    if let Some(r) = rest.strip_prefix('R').or_else(|| rest.strip_prefix('r')) {
        let dlc = if r.is_empty() {
            0
        } else {
            r.parse::<usize>().ok().filter(|&d| d <= 8).ok_or_else(|| format!("bad remote frame length {r:?}"))?
        };
        return CanFrame::new_remote(id, dlc).ok_or_else(|| "bad remote frame".to_string());
    }
    if rest.contains('_') {
        return Err("frames with a DLC above 8 (_x suffix) are not supported".into());
    }
    let bytes = rest.as_bytes();
    if bytes.len() % 2 != 0 {
        return Err(format!("data {rest:?} has an odd number of hex digits"));
    }
    if bytes.len() > 16 {
        return Err(format!("data {rest:?} longer than 8 bytes"));
    }
    let data: Vec<u8> =
        bytes.chunks(2).map(hex_byte).collect::<Option<_>>().ok_or_else(|| format!("bad hex data {rest:?}"))?;
    CanFrame::new(id, &data).ok_or_else(|| "bad frame".to_string())
}

/// Parses one log line. `Ok(None)` for blank lines and `#` comments.
pub fn parse_line(line: &str) -> Result<Option<LogRecord>, String> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(None);
    }
    let mut toks = line.split_whitespace();
    let (Some(time), Some(iface), Some(frame)) = (toks.next(), toks.next(), toks.next()) else {
        return Err("expected `(SECONDS.MICROS) IFACE ID#DATA`".into());
    };
    // Newer candump versions may append a direction flag (T = sent, R = received).
    match toks.next() {
        None | Some("T") | Some("R") => {}
        Some(extra) => return Err(format!("unexpected text {extra:?} after the frame")),
    }
    if toks.next().is_some() {
        return Err("unexpected text after the frame".into());
    }
    Ok(Some(LogRecord { time_us: parse_time(time)?, iface: iface.to_owned(), frame: parse_frame(frame)? }))
}

/// Longest candump line read, bytes (a frame line is under 60).
pub const MAX_LOG_LINE_BYTES: usize = 4096;

/// Reads and drops input up to and including the next `\n`.
fn skip_line<R: BufRead>(reader: &mut R) -> std::io::Result<()> {
    loop {
        let chunk = reader.fill_buf()?;
        if chunk.is_empty() {
            return Ok(());
        }
        match chunk.iter().position(|&b| b == b'\n') {
            Some(i) => {
                reader.consume(i + 1);
                return Ok(());
            }
            None => {
                let n = chunk.len();
                reader.consume(n);
            }
        }
    }
}

/// Reads a candump log line by line. Each item is a frame or the error of one line; reading
/// goes on after a bad line. An I/O error ends the iteration with that error.
pub fn read_log<R: BufRead>(reader: R) -> impl Iterator<Item = Result<LogRecord, LogError>> {
    let mut reader = reader;
    let mut line_no = 0usize;
    let mut buf = Vec::new();
    let mut done = false;
    std::iter::from_fn(move || loop {
        if done {
            return None;
        }
        buf.clear();
        match std::io::Read::take(&mut reader, MAX_LOG_LINE_BYTES as u64 + 1).read_until(b'\n', &mut buf) {
            Ok(0) => return None,
            Ok(_) if buf.len() > MAX_LOG_LINE_BYTES && !buf.ends_with(b"\n") => {
                line_no += 1;
                // Bounded memory whatever the input: the rest of the line is read and dropped.
                if let Err(e) = skip_line(&mut reader) {
                    done = true;
                    return Some(Err(LogError { line: line_no, reason: format!("read error: {e}") }));
                }
                return Some(Err(LogError {
                    line: line_no,
                    reason: format!("line longer than {MAX_LOG_LINE_BYTES} bytes: not a candump line"),
                }));
            }
            Ok(_) => {
                line_no += 1;
                let text = String::from_utf8_lossy(&buf);
                match parse_line(&text) {
                    Ok(None) => continue,
                    Ok(Some(r)) => return Some(Ok(r)),
                    Err(reason) => return Some(Err(LogError { line: line_no, reason })),
                }
            }
            Err(e) => {
                done = true;
                return Some(Err(LogError { line: line_no + 1, reason: format!("read error: {e}") }));
            }
        }
    })
}

/// Writes frames as candump log lines.
#[derive(Debug)]
pub struct CandumpWriter<W: Write> {
    out: W,
    iface: String,
    frames: u64,
}

impl<W: Write> CandumpWriter<W> {
    /// A writer that labels every frame with `iface`.
    pub fn new(out: W, iface: &str) -> Self {
        Self { out, iface: iface.to_owned(), frames: 0 }
    }

    /// Frames written so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Flushes and returns the inner writer.
    pub fn finish(mut self) -> std::io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write> FrameSink for CandumpWriter<W> {
    fn send(&mut self, time_us: u64, frame: &CanFrame) -> std::io::Result<()> {
        self.frames += 1;
        writeln!(self.out, "{}", format_line(time_us, &self.iface, frame))
    }
}

/// Drives the core's [`CanReporter`] from a [`Monitor`], one call per sample, and hands the
/// frames to a sink (a candump log, a socket, a mock bus). The same reporter code runs in the
/// firmware, so the frames are the ones the brake controller would send.
#[derive(Debug)]
pub struct CanRecorder<S: FrameSink> {
    reporter: CanReporter,
    sink: S,
    was_active: bool,
}

impl<S: FrameSink> CanRecorder<S> {
    /// A recorder whose counters start at 0 (locomotive 0, release number 0).
    pub fn new(sink: S) -> Self {
        Self { reporter: CanReporter::new(), sink, was_active: false }
    }

    /// A recorder for a monitor powering up as `power_up` says (locomotive, release count kept).
    pub fn with_identity(sink: S, power_up: PowerUp) -> Self {
        let mut r = Self::new(sink);
        r.reporter.set_identity(power_up);
        r
    }

    /// Call right after `monitor.update(..)` for each sample, at the sample's time. `verdict`
    /// is the current diagnosis (None until one is made); `release_active` is the valve
    /// command. Returns the number of frames sent.
    pub fn on_sample(
        &mut self,
        time_us: u64,
        monitor: &Monitor,
        verdict: Option<Verdict>,
        release_active: bool,
    ) -> std::io::Result<usize> {
        if release_active && !self.was_active {
            // A release command: the next release number, as the pipeline does.
            self.reporter.new_release();
        }
        self.was_active = release_active;
        let status = monitor.status();
        let fault = verdict.map(|v| fault_report(monitor, v));
        let out = self.reporter.step(&status, fault.as_ref(), release_active);
        for f in out.as_slice() {
            self.sink.send(time_us, f)?;
        }
        Ok(out.as_slice().len())
    }

    /// The sink.
    pub fn sink(&self) -> &S {
        &self.sink
    }

    /// Returns the sink.
    pub fn into_sink(self) -> S {
        self.sink
    }
}

/// Seconds to microseconds for log time stamps (negative and NaN times clamp to 0).
pub fn time_us(t_s: f64) -> u64 {
    if t_s.is_finite() && t_s > 0.0 {
        (t_s * 1e6).round() as u64
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_round_trip() {
        let f = CanFrame::new_extended(0x18FF_5080, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        let line = format_line(1_000_000, "can0", &f);
        assert_eq!(line, "(0000000001.000000) can0 18FF5080#0102030405060708");
        let r = parse_line(&line).unwrap().unwrap();
        assert_eq!((r.time_us, r.iface.as_str(), r.frame), (1_000_000, "can0", f));
        let s = CanFrame::new_standard(0x12, &[0xAB]).unwrap();
        assert_eq!(format_frame(&s), "012#AB");
        assert_eq!(parse_frame("012#ab").unwrap(), s);
        assert_eq!(parse_frame("012#").unwrap(), CanFrame::new_standard(0x12, &[]).unwrap());
        let r = parse_frame("123#R4").unwrap();
        assert!(r.is_remote_frame() && r.dlc() == 4);
        assert_eq!(format_frame(&r), "123#R4");
        assert_eq!(parse_line("(1.5) vcan0 123#00 R").unwrap().unwrap().time_us, 1_500_000);
        assert_eq!(parse_line("  # comment").unwrap(), None);
        assert_eq!(parse_line("").unwrap(), None);
    }

    #[test]
    fn bad_lines_are_clear_errors() {
        for (line, needle) in [
            ("(1.0) can0", "expected"),
            ("1.0 can0 123#00", "time stamp"),
            ("(1.0000000) can0 123#00", "fraction"),
            ("(99999999999999999999.0) can0 123#00", "range"),
            ("(1.0) can0 1234#00", "4 digits"),
            ("(1.0) can0 800#00", "above 0x7FF"),
            ("(1.0) can0 3FFFFFFF#00", "error frame"),
            ("(1.0) can0 1FFFFFFG#00", "bad identifier"),
            ("(1.0) can0 123#0", "odd"),
            ("(1.0) can0 123#001122334455667788", "longer than 8"),
            ("(1.0) can0 123#zz", "bad hex"),
            ("(1.0) can0 123##1AB", "CAN FD"),
            ("(1.0) can0 123#R9", "remote"),
            ("(1.0) can0 123#00 X", "unexpected"),
            ("(1.0) can0 12300", "no '#'"),
            ("(1.0) can0 123#1122_5", "DLC"),
        ] {
            let e = parse_line(line).unwrap_err();
            assert!(e.contains(needle), "{line}: {e}");
        }
    }

    #[test]
    fn reader_reports_line_numbers_and_goes_on() {
        let text = b"(1.000000) can0 123#00\n\ngarbage\n\xff\xfe\n(2.000000) can0 18FF5080#\n";
        let items: Vec<_> = read_log(&text[..]).collect();
        assert_eq!(items.len(), 4);
        assert!(items[0].is_ok());
        assert_eq!(items[1].as_ref().unwrap_err().line, 3);
        assert_eq!(items[2].as_ref().unwrap_err().line, 4);
        assert_eq!(items[3].as_ref().unwrap().time_us, 2_000_000);
    }
}
