//! The SPEC §7 trace reader: every malformed input is a clear error naming file and line, and
//! no input makes it panic.

use pbm_io::trace::{
    parse_trace, read_trace, write_adc_trace, Samples, Trace, TraceError, TraceErrorKind, MAX_TRACE_BYTES,
};
use proptest::prelude::*;

fn parse(text: &str) -> Result<Trace, TraceError> {
    parse_trace("t.csv", text.as_bytes())
}

/// Asserts that `text` fails with `kind` at `line`, and that the message names file and line.
fn assert_error(text: &str, line: usize, kind: TraceErrorKind) {
    let e = parse(text).expect_err("malformed trace must be rejected");
    assert_eq!((e.line, e.kind), (line, kind), "input {text:?}");
    let msg = e.to_string();
    let prefix = if line == 0 { "t.csv: ".to_owned() } else { format!("t.csv:{line}: ") };
    assert!(msg.starts_with(&prefix), "message {msg:?} should start with {prefix:?}");
}

#[test]
fn reads_adc_trace_with_metadata() {
    let t =
        parse("# label: normal\n# locomotive: loco-01\n# free comment, no key\nt_s,adc\n0.00,410\n0.01,415\n").unwrap();
    assert_eq!(t.meta("label"), Some("normal"));
    assert_eq!(t.meta("locomotive"), Some("loco-01"));
    assert_eq!(t.metadata.len(), 2);
    assert_eq!(t.t_s, vec![0.0, 0.01]);
    assert_eq!(t.samples, Samples::Adc(vec![410, 415]));
    assert_eq!(t.lines, vec![5, 6]);
}

#[test]
fn reads_bar_trace_with_extra_column_crlf_and_bom() {
    let t = parse("\u{feff}# source: rig\r\nt_s, p_bar ,x_mm\r\n0.00,0.0,0\r\n\r\n0.01, 0.25 ,1.5\r\n").unwrap();
    assert_eq!(t.samples, Samples::Bar(vec![0.0, 0.25]));
    assert_eq!(t.extra, vec![("x_mm".to_owned(), vec![0.0, 1.5])]);
    assert_eq!(t.meta("source"), Some("rig"));
}

#[test]
fn round_trips_the_writer() {
    let adc: Vec<u16> = (0..250).map(|i| (i * 16) as u16).collect();
    let mut buf = Vec::new();
    write_adc_trace(&mut buf, &[("label", "normal".to_owned())], &adc).unwrap();
    let t = parse_trace("w.csv", &buf).unwrap();
    assert_eq!(t.samples, Samples::Adc(adc));
    assert_eq!(t.t_s.len(), 250);
    assert!((t.t_s[249] - 2.49).abs() < 1e-12);
    t.check_sample_period(0.01, 1e-3).unwrap();
}

#[test]
fn empty_file() {
    assert_error("", 0, TraceErrorKind::Empty);
    assert_error("  \n\n", 0, TraceErrorKind::Empty);
    assert_error("# label: normal\n", 0, TraceErrorKind::Empty);
}

#[test]
fn missing_header() {
    assert_error("# label: x\n0.00,410\n0.01,411\n", 2, TraceErrorKind::MissingHeader);
}

#[test]
fn bad_header() {
    assert_error("time,adc\n0,410\n", 1, TraceErrorKind::BadHeader);
    assert_error("t_s,pressure\n0,1\n", 1, TraceErrorKind::BadHeader);
    assert_error("t_s\n0\n", 1, TraceErrorKind::BadHeader);
    assert_error("t_s,adc,x_mm,x_mm\n0,410,0,0\n", 1, TraceErrorKind::BadColumnName { column: 4 });
    assert_error("t_s,adc,\n0,410,0\n", 1, TraceErrorKind::BadColumnName { column: 3 });
}

#[test]
fn header_without_samples() {
    assert_error("# a: b\nt_s,adc\n\n", 0, TraceErrorKind::NoSamples);
}

#[test]
fn bad_number() {
    assert_error("t_s,p_bar\n0.00,1.0\n0.01,1.x\n", 3, TraceErrorKind::BadNumber { column: 2 });
    assert_error("t_s,p_bar\nzero,1.0\n", 2, TraceErrorKind::BadNumber { column: 1 });
    assert_error("t_s,p_bar\n0.00,\n", 2, TraceErrorKind::BadNumber { column: 2 });
    assert_error("t_s,adc,x_mm\n0.00,410,abc\n", 2, TraceErrorKind::BadNumber { column: 3 });
    assert_error("t_s,adc\n0.00,four\n", 2, TraceErrorKind::BadNumber { column: 2 });
}

#[test]
fn nan_and_infinity() {
    assert_error("t_s,p_bar\n0.00,NaN\n", 2, TraceErrorKind::NotFinite { column: 2 });
    assert_error("t_s,p_bar\n0.00,1\ninf,1\n", 3, TraceErrorKind::NotFinite { column: 1 });
    assert_error("t_s,p_bar\n0.00,-infinity\n", 2, TraceErrorKind::NotFinite { column: 2 });
    assert_error("t_s,adc\n0.00,nan\n", 2, TraceErrorKind::NotFinite { column: 2 });
    assert_error("t_s,adc,x_mm\n0.00,410,1e999\n", 2, TraceErrorKind::NotFinite { column: 3 });
}

#[test]
fn time_must_increase() {
    assert_error(
        "t_s,adc\n0.00,410\n0.02,411\n0.01,412\n",
        4,
        TraceErrorKind::TimeNotIncreasing { previous_s: 0.02, found_s: 0.01 },
    );
    assert_error(
        "t_s,adc\n0.00,410\n0.00,411\n",
        3,
        TraceErrorKind::TimeNotIncreasing { previous_s: 0.0, found_s: 0.0 },
    );
}

#[test]
fn wrong_column_count() {
    assert_error("t_s,adc\n0.00,410,5\n", 2, TraceErrorKind::ColumnCount { expected: 2, found: 3 });
    assert_error("t_s,adc,x_mm\n0.00,410\n", 2, TraceErrorKind::ColumnCount { expected: 3, found: 2 });
    assert_error("t_s,adc\n0.00\n", 2, TraceErrorKind::ColumnCount { expected: 2, found: 1 });
}

#[test]
fn adc_out_of_range_or_not_integer() {
    assert_error("t_s,adc\n0.00,4096\n", 2, TraceErrorKind::AdcOutOfRange { value: 4096 });
    assert_error("t_s,adc\n0.00,-1\n", 2, TraceErrorKind::AdcOutOfRange { value: -1 });
    assert_error("t_s,adc\n0.00,99999999999999999999999\n", 2, TraceErrorKind::AdcOutOfRange { value: i64::MAX });
    assert_error("t_s,adc\n0.00,410.5\n", 2, TraceErrorKind::AdcNotInteger);
    assert_error("t_s,adc\n0.00,1e3\n", 2, TraceErrorKind::AdcNotInteger);
    // The limits themselves are readings (sensor faults are the monitor's business).
    let t = parse("t_s,adc\n0.00,0\n0.01,4095\n").unwrap();
    assert_eq!(t.samples, Samples::Adc(vec![0, 4095]));
}

#[test]
fn not_utf8() {
    let e = parse_trace("b.csv", b"t_s,adc\n0.00,410\n0.01,4\xff1\n").unwrap_err();
    assert_eq!((e.line, e.kind), (3, TraceErrorKind::NotUtf8));
}

#[test]
fn comments_and_metadata_errors() {
    assert_error("t_s,adc\n0.00,410\n# late: x\n", 3, TraceErrorKind::CommentAfterHeader);
    assert_error("# label: a\n# label: b\nt_s,adc\n0,410\n", 2, TraceErrorKind::DuplicateMetadata);
}

#[test]
fn sample_period() {
    let t = parse("t_s,adc\n0.00,410\n0.01,410\n0.03,410\n").unwrap();
    let e = t.check_sample_period(0.01, 1e-3).unwrap_err();
    assert_eq!(e.line, 4);
    assert!(matches!(e.kind, TraceErrorKind::SamplePeriod { found_s, .. } if (found_s - 0.02).abs() < 1e-9));
    assert!(e.to_string().starts_with("t.csv:4: sample interval"), "{e}");
}

#[test]
fn missing_file() {
    let e = read_trace(std::path::Path::new("/nonexistent/dir/trace.csv")).unwrap_err();
    assert_eq!((e.line, e.kind), (0, TraceErrorKind::Io(std::io::ErrorKind::NotFound)));
    assert!(e.to_string().contains("/nonexistent/dir/trace.csv"));
}

#[test]
fn huge_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.csv");
    let f = std::fs::File::create(&path).unwrap();
    // Sparse: no disk space used, but one byte over the cap.
    f.set_len(MAX_TRACE_BYTES + 1).unwrap();
    let e = read_trace(&path).unwrap_err();
    assert_eq!((e.line, e.kind), (0, TraceErrorKind::TooLarge { limit: MAX_TRACE_BYTES }));
    assert!(e.to_string().contains("huge.csv"));
}

#[test]
fn reads_a_file_from_disk() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ok.csv");
    std::fs::write(&path, "t_s,p_bar\n0.00,0.1\n0.01,0.2\n").unwrap();
    let t = read_trace(&path).unwrap();
    assert_eq!(t.samples, Samples::Bar(vec![0.1, 0.2]));
    assert_eq!(t.source, path.display().to_string());
}

/// Invariants of every trace the reader accepts.
fn check_invariants(t: &Trace) {
    assert!(!t.t_s.is_empty());
    assert_eq!(t.t_s.len(), t.samples.len());
    assert_eq!(t.t_s.len(), t.lines.len());
    assert!(t.t_s.iter().all(|v| v.is_finite()));
    assert!(t.t_s.windows(2).all(|w| w[1] > w[0]));
    match &t.samples {
        Samples::Adc(v) => assert!(v.iter().all(|&c| c <= 4095)),
        Samples::Bar(v) => assert!(v.iter().all(|p| p.is_finite())),
    }
    for (_, col) in &t.extra {
        assert_eq!(col.len(), t.t_s.len());
        assert!(col.iter().all(|v| v.is_finite()));
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        if let Ok(t) = parse_trace("fuzz.csv", &bytes) {
            check_invariants(&t);
        }
    }

    #[test]
    fn mutated_traces_never_panic(
        edits in proptest::collection::vec((0usize..200, proptest::sample::select(vec![
            "", ",", "\n", "#", "-", ".", "e", "9", "NaN", "inf", "4096", "p_bar", "adc", ":", "\r", " ", "\u{feff}",
        ])), 1..6),
        drop in proptest::collection::vec(0usize..200, 0..3),
    ) {
        let mut text = String::from("# label: normal\n# seed: 1\nt_s,adc,x_mm\n0.00,410,0\n0.01,415,0.5\n0.02,420,1.0\n0.03,430,1.5\n");
        for d in drop {
            let i = d % text.len();
            if text.is_char_boundary(i) && text.is_char_boundary(i + 1) {
                text.remove(i);
            }
        }
        for (pos, s) in edits {
            let mut i = pos % (text.len() + 1);
            while !text.is_char_boundary(i) {
                i -= 1;
            }
            text.insert_str(i, s);
        }
        match parse_trace("mut.csv", text.as_bytes()) {
            Ok(t) => check_invariants(&t),
            Err(e) => prop_assert!(e.to_string().starts_with("mut.csv")),
        }
    }
}
