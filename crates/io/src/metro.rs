//! The MetroPT-3 record (SPEC §8): the columns the reservoir audit reads, by name.
//!
//! A row must have every column of the header (a short row is an error naming its line, never
//! a shifted column); time stamps are calendar date-times (`YYYY-MM-DD hh:mm:ss`, optional
//! fractional seconds), so a record may cross midnight, a month or a year.

use crate::error::FileError;
use crate::table::read_rows_checked;
use chrono::NaiveDateTime;
use serde::Deserialize;
use std::path::Path;

/// Longest interval between two rows of one record, s (the recorder samples about every 10 s;
/// a longer gap is an outage, across which the reservoir model cannot be integrated).
pub const MAX_GAP_S: f64 = 600.0;

/// The extract of the repository (CC BY 4.0, see `tests/data/metropt3/README.md`), relative to
/// the repository root.
pub const EXTRACT: &str = "tests/data/metropt3/metropt3_head.csv";

/// One row of the record, as the audit uses it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MetroRow {
    /// Seconds since the first row.
    pub t_s: f64,
    /// Reservoir pressure TP3, bar.
    pub tp3_bar: f64,
    /// Compressor loaded (COMP < 0.5).
    pub loaded: bool,
    /// Oil (compressor outlet) temperature, °C.
    pub oil_c: f64,
}

#[derive(Deserialize)]
struct RawRow {
    timestamp: String,
    #[serde(rename = "TP3")]
    tp3: f64,
    #[serde(rename = "COMP")]
    comp: f64,
    #[serde(rename = "Oil_temperature")]
    oil_temperature: f64,
}

/// The columns the audit reads.
pub const COLUMNS: [&str; 4] = ["timestamp", "TP3", "COMP", "Oil_temperature"];

/// Fewest rows an audit can use.
pub const MIN_ROWS: usize = 20;

/// Reads a MetroPT-3 CSV (columns `timestamp`, `TP3`, `COMP`, `Oil_temperature` by name; the
/// others are ignored). Time must increase; every number must be finite.
pub fn read_metro(path: &Path) -> Result<Vec<MetroRow>, FileError> {
    let name = path.display().to_string();
    let file = crate::files::open_regular(path)?;
    let raw: Vec<(usize, RawRow)> = read_rows_checked(&name, std::io::BufReader::new(file), |header| {
        match COLUMNS.iter().find(|c| !header.iter().any(|h| h == **c)) {
            Some(missing) => Err(format!("no column `{missing}` (needed: {})", COLUMNS.join(", "))),
            None => Ok(()),
        }
    })?;
    let mut rows: Vec<MetroRow> = Vec::with_capacity(raw.len());
    let mut t0 = None;
    for (line, r) in raw {
        let err = |m: String| FileError::new(&name, line, m);
        let t = parse_time(&r.timestamp)
            .ok_or_else(|| err(format!("timestamp `{}` is not `YYYY-MM-DD hh:mm:ss`", r.timestamp)))?;
        for (column, v) in [("TP3", r.tp3), ("COMP", r.comp), ("Oil_temperature", r.oil_temperature)] {
            if !v.is_finite() {
                return Err(err(format!("{column} is not a finite number")));
            }
        }
        let t0 = *t0.get_or_insert(t);
        let t_s = (t - t0).num_microseconds().map_or(f64::NAN, |us| us as f64 * 1e-6);
        if let Some(prev) = rows.last() {
            if t_s.partial_cmp(&prev.t_s) != Some(std::cmp::Ordering::Greater) {
                return Err(err(format!("time is not increasing ({} is not after the previous row)", r.timestamp)));
            }
            if t_s - prev.t_s > MAX_GAP_S {
                return Err(err(format!(
                    "a gap of {:.0} s before {}: the audit needs one continuous record (the extract is sampled \
                     about every 10 s); cut the file at the gap",
                    t_s - prev.t_s,
                    r.timestamp
                )));
            }
        }
        rows.push(MetroRow { t_s, tp3_bar: r.tp3, loaded: r.comp < 0.5, oil_c: r.oil_temperature });
    }
    if rows.len() < MIN_ROWS {
        return Err(FileError::new(&name, 0, format!("only {} rows (at least {MIN_ROWS} needed)", rows.len())));
    }
    Ok(rows)
}

fn parse_time(s: &str) -> Option<NaiveDateTime> {
    NaiveDateTime::parse_from_str(s.trim(), "%Y-%m-%d %H:%M:%S%.f").ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.csv");
        std::fs::write(&p, text).unwrap();
        (dir, p)
    }

    fn rows(first: &str, n: usize) -> String {
        let start = parse_time(first).unwrap();
        let mut s = String::from(",timestamp,TP3,COMP,Oil_temperature\n");
        for i in 0..n {
            let t = start + chrono::Duration::seconds(10 * i as i64);
            s.push_str(&format!("{i},{},9.0,1.0,50.0\n", t.format("%Y-%m-%d %H:%M:%S")));
        }
        s
    }

    #[test]
    fn a_record_may_cross_a_month_and_a_year() {
        let (_d, p) = write(&rows("2020-02-29 23:59:00", 25));
        let r = read_metro(&p).unwrap();
        assert_eq!(r.len(), 25);
        assert!((r[24].t_s - 240.0).abs() < 1e-9);
        let (_d, p) = write(&rows("2021-12-31 23:59:50", 25));
        assert!((read_metro(&p).unwrap()[1].t_s - 10.0).abs() < 1e-9);
    }

    #[test]
    fn an_outage_in_the_record_is_an_error_naming_its_line() {
        let text = rows("2020-02-01 00:00:00", 25).replace("12,2020-02-01 00:02:00", "12,2020-02-03 00:02:00");
        let (_d, p) = write(&text);
        let e = read_metro(&p).unwrap_err();
        assert_eq!(e.line, 14, "{e}");
        assert!(e.message.contains("gap of 172810 s"), "{e}");
    }

    #[test]
    fn a_short_row_is_an_error_not_a_shifted_column() {
        let mut text = rows("2020-02-01 00:00:00", 25);
        text = text.replacen("3,2020-02-01 00:00:30,9.0,1.0,50.0", "3,2020-02-01 00:00:30,9.0,50.0", 1);
        let (_d, p) = write(&text);
        let e = read_metro(&p).unwrap_err();
        assert_eq!(e.line, 5, "{e}");
        assert!(e.to_string().contains("expected 5 columns"), "{e}");
    }

    #[test]
    fn missing_columns_and_bad_times_are_named() {
        let (_d, p) = write("timestamp,TP3\n2020-02-01 00:00:00,9\n");
        let e = read_metro(&p).unwrap_err();
        assert!(e.to_string().contains("COMP"), "{e}");
        let text = rows("2020-02-01 00:00:00", 25).replacen("2020-02-01 00:00:20", "2020-02-01 00:00:05", 1);
        let (_d, p) = write(&text);
        let e = read_metro(&p).unwrap_err();
        assert_eq!(e.line, 4, "{e}");
    }
}
