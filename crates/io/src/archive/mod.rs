//! Fleet archives: the ADC traces of many releases in one Parquet file (`docs/archive.md`).
//!
//! The format is shared with the Python side and fixed: long format, one row per sample, **one
//! row group per release** (a release never spans two), rows of a release in sample order,
//! releases sorted by (locomotive, release), the columns [`COLUMNS`] in that order
//! ([`SCHEMA`]), and the file key-value metadata [`VERSION_KEY`] = [`VERSION`]. Only ADC
//! traces are archived.
//!
//! - [`ArchiveWriter`] adds one release at a time, each written out as its own row group
//!   before the next is taken: memory is one release.
//! - [`ArchiveReader`] yields one release (one row group) at a time as an
//!   [`ArchivedRelease`], which converts into the [`Trace`] the CSV reader gives; it can keep
//!   one locomotive only, deciding from the row groups' statistics (or, without them, from the
//!   two key columns) so that no page of another locomotive's samples is read.
//! - [`pack`] and [`unpack`] turn data sets and trace files into an archive and back (the
//!   traces the generator wrote come back byte for byte); [`results`] writes replay results
//!   as Parquet.
//!
//! Bad input follows the project's policy ([`crate::error`]): a file that is not an archive
//! (not Parquet, a column missing, of the wrong type or out of order, no version key) is one
//! error naming the file; a bad release (adc outside 0..=4095, time not increasing, samples not
//! numbered 0, 1, …, a release split over two row groups or two releases in one) is an error
//! naming the file and the release, and the reader goes on with the next one.

mod pack_cmd;
mod read;
pub mod results;
mod write;

pub use pack_cmd::{pack, unpack, PackSummary, UnpackSummary};
pub use read::{is_archive, ArchiveReader, MAX_RELEASE_SAMPLES};
pub use write::ArchiveWriter;

use crate::trace::{Samples, Trace, TraceKind};
use pbm::sensor::ADC_FULL_SCALE;
use std::fmt::Write as _;

/// The file key-value metadata key that marks a fleet archive.
pub const VERSION_KEY: &str = "pbm.archive.version";
/// The format version this crate reads and writes.
pub const VERSION: &str = "1";

/// The columns of an archive, in file order.
pub const COLUMNS: [&str; 8] = ["locomotive", "release", "label", "split", "sample", "t_s", "adc", "meta"];

/// The Parquet schema of an archive (the table of `docs/archive.md`).
pub const SCHEMA: &str = "
message pbm_fleet_archive {
    required binary locomotive (STRING);
    required binary release (STRING);
    optional binary label (STRING);
    optional binary split (STRING);
    required int32 sample;
    required double t_s;
    required int32 adc;
    optional binary meta (STRING);
}";

/// One archived release: who, which release, what is known of it, its metadata and samples.
#[derive(Debug, Clone, PartialEq)]
pub struct ArchivedRelease {
    /// Locomotive id.
    pub locomotive: String,
    /// Release id: the trace's path relative to its data set (or its file name).
    pub release: String,
    /// The true class, when known.
    pub label: Option<String>,
    /// `train` / `test`, when known.
    pub split: Option<String>,
    /// The trace's `# key: value` metadata, in file order (keys unique).
    pub metadata: Vec<(String, String)>,
    /// Sample times, s (finite, strictly increasing).
    pub t_s: Vec<f64>,
    /// 12-bit ADC counts (0..=4095), one per sample.
    pub adc: Vec<u16>,
}

impl ArchivedRelease {
    /// The release of an ADC trace; a pressure trace, or one with extra columns (which the
    /// archive has no place for), is refused with the reason.
    pub fn from_trace(
        locomotive: String,
        release: String,
        label: Option<String>,
        split: Option<String>,
        trace: Trace,
    ) -> Result<Self, String> {
        if trace.samples.kind() != TraceKind::Adc {
            return Err("a `t_s,p_bar` (pressure) trace: only ADC traces (`t_s,adc`) are archived".to_owned());
        }
        if !trace.extra.is_empty() {
            let names: Vec<&str> = trace.extra.iter().map(|(n, _)| n.as_str()).collect();
            return Err(format!("extra columns ({}) have no place in an archive: refused", names.join(", ")));
        }
        let Samples::Adc(adc) = trace.samples else {
            return Err("not an ADC trace".to_owned());
        };
        let r = Self { locomotive, release, label, split, metadata: trace.metadata, t_s: trace.t_s, adc };
        r.check()?;
        Ok(r)
    }

    /// The release as the CSV reader would give it: `source` names it in errors, and the
    /// "line" of sample `i` is `i + 1` (its row within the release).
    pub fn into_trace(self, source: String) -> Trace {
        let lines = (1..=self.t_s.len()).collect();
        Trace {
            source,
            metadata: self.metadata,
            t_s: self.t_s,
            samples: Samples::Adc(self.adc),
            extra: Vec::new(),
            lines,
        }
    }

    /// The value of metadata key `key`, if present.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// Checks what the format asks of a release: ids not empty, at least one sample, as many
    /// times as counts, times finite and strictly increasing, counts within 0..=4095,
    /// metadata keys unique. The error says what and at which (0-based) sample.
    pub fn check(&self) -> Result<(), String> {
        if self.locomotive.is_empty() || self.release.is_empty() {
            return Err("empty locomotive or release id".to_owned());
        }
        if self.t_s.is_empty() {
            return Err("no samples".to_owned());
        }
        if self.t_s.len() != self.adc.len() {
            return Err(format!("{} times but {} adc values", self.t_s.len(), self.adc.len()));
        }
        if i32::try_from(self.t_s.len()).is_err() {
            return Err("more samples than an INT32 sample index holds".to_owned());
        }
        check_samples(&self.t_s, &self.adc)?;
        for (i, (k, _)) in self.metadata.iter().enumerate() {
            if self.metadata[..i].iter().any(|(other, _)| other == k) {
                return Err(format!("metadata key `{k}` repeated"));
            }
        }
        Ok(())
    }

    /// The metadata as the `meta` column holds it: one JSON object, keys and values strings,
    /// in file order.
    pub fn meta_json(&self) -> String {
        meta_json(&self.metadata)
    }

    /// Writes the release as a trace CSV: the metadata lines, `t_s,adc`, one row per sample.
    /// A time is written with two decimals when that gives back the exact value (the
    /// generator's 10 ms clock), else with as many as it needs; so a trace `host-sim generate`
    /// wrote comes back byte for byte.
    pub fn write_csv(&self, w: &mut impl std::io::Write) -> std::io::Result<()> {
        let meta: Vec<(&str, String)> = self.metadata.iter().map(|(k, v)| (k.as_str(), v.clone())).collect();
        let mut out = Vec::with_capacity(self.adc.len() * 10 + 256);
        crate::trace::write_metadata(&mut out, &meta)?;
        out.extend_from_slice(b"t_s,adc\n");
        let mut line = String::new();
        for (&t, &c) in self.t_s.iter().zip(&self.adc) {
            line.clear();
            write_time(&mut line, t);
            let _ = writeln!(line, ",{c}");
            out.extend_from_slice(line.as_bytes());
        }
        w.write_all(&out)
    }
}

/// Checks a release's samples: times finite and strictly increasing, counts within 0..=4095.
fn check_samples(t_s: &[f64], adc: &[u16]) -> Result<(), String> {
    for (i, &t) in t_s.iter().enumerate() {
        if !t.is_finite() {
            return Err(format!("sample {i}: t_s is NaN or infinite"));
        }
        if let Some(&previous) = i.checked_sub(1).and_then(|p| t_s.get(p)) {
            if t <= previous {
                return Err(format!("sample {i}: time not increasing: {t} s after {previous} s"));
            }
        }
    }
    if let Some((i, &c)) = adc.iter().enumerate().find(|(_, &c)| c > ADC_FULL_SCALE) {
        return Err(format!("sample {i}: adc value {c} outside 0..={ADC_FULL_SCALE}"));
    }
    Ok(())
}

/// `t` with two decimals when they give back exactly `t`, else its shortest exact form.
fn write_time(out: &mut String, t: f64) {
    let start = out.len();
    let _ = write!(out, "{t:.2}");
    if out[start..].parse::<f64>().ok() != Some(t) {
        out.truncate(start);
        let _ = write!(out, "{t}");
    }
}

/// Metadata as one JSON object string, in order.
fn meta_json(metadata: &[(String, String)]) -> String {
    let mut s = String::from("{");
    for (i, (k, v)) in metadata.iter().enumerate() {
        if i > 0 {
            s.push_str(", ");
        }
        // Serialising a string cannot fail.
        s.push_str(&serde_json::to_string(k).unwrap_or_default());
        s.push_str(": ");
        s.push_str(&serde_json::to_string(v).unwrap_or_default());
    }
    s.push('}');
    s
}

/// Parses the `meta` column's JSON object into ordered key-value pairs (keys unique, values
/// strings).
fn parse_meta_json(text: &str) -> Result<Vec<(String, String)>, String> {
    use serde::de::{Deserializer, MapAccess, Visitor};
    struct Ordered;
    impl<'de> Visitor<'de> for Ordered {
        type Value = Vec<(String, String)>;
        fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("a JSON object whose values are strings")
        }
        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
            let mut out: Vec<(String, String)> = Vec::new();
            while let Some((k, v)) = map.next_entry::<String, String>()? {
                if out.iter().any(|(other, _)| *other == k) {
                    return Err(serde::de::Error::custom(format!("key `{k}` repeated")));
                }
                out.push((k, v));
            }
            Ok(out)
        }
    }
    let mut de = serde_json::Deserializer::from_str(text);
    let pairs =
        (&mut de).deserialize_map(Ordered).map_err(|e| format!("`meta` is not a JSON object of strings: {e}"))?;
    de.end().map_err(|e| format!("`meta` has text after its JSON object: {e}"))?;
    Ok(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_keep_two_decimals_when_exact() {
        let mut s = String::new();
        for t in [0.0, 0.01, 1.1, 59.99, 123.45] {
            s.clear();
            write_time(&mut s, t);
            assert_eq!(s.parse::<f64>().unwrap(), t);
        }
        s.clear();
        write_time(&mut s, 1.1);
        assert_eq!(s, "1.10");
        s.clear();
        write_time(&mut s, 0.0125);
        assert_eq!(s, "0.0125");
    }

    #[test]
    fn metadata_json_keeps_order_and_refuses_other_shapes() {
        let meta = vec![("z".to_owned(), "1".to_owned()), ("a \"q\"".to_owned(), "x, y".to_owned())];
        let json = meta_json(&meta);
        assert_eq!(json, r#"{"z": "1", "a \"q\"": "x, y"}"#);
        assert_eq!(parse_meta_json(&json).unwrap(), meta);
        assert!(parse_meta_json(r#"{"a": 1}"#).is_err());
        assert!(parse_meta_json(r#"{"a": "1", "a": "2"}"#).unwrap_err().contains("repeated"));
        assert!(parse_meta_json("[1]").is_err());
        assert!(parse_meta_json("{} x").is_err());
    }
}
