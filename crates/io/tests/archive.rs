//! Fleet archives (`pbm_io::archive`): data set → archive → data set round trip, the reader's
//! releases equal to the CSV reader's traces, the locomotive filter, and one test per kind of
//! bad input (each an error naming the file and, for a bad release, the release, never a
//! panic; the reader goes on with the next release).

use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int32Type, Int64Type};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::parser::parse_message_type;
use pbm_io::archive::{pack, unpack, ArchiveReader, ArchiveWriter, ArchivedRelease, SCHEMA};
use pbm_io::dataset::read_manifest;
use pbm_io::trace::{read_trace, Samples};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn small() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/small")
}

/// A release of `n` samples at 100 Hz.
fn release(loco: &str, name: &str, n: usize) -> ArchivedRelease {
    ArchivedRelease {
        locomotive: loco.into(),
        release: name.into(),
        label: Some("normal".into()),
        split: None,
        metadata: vec![("locomotive".into(), loco.into()), ("note".into(), "a, \"b\"".into())],
        t_s: (0..n).map(|i| i as f64 / 100.0).collect(),
        adc: (0..n).map(|i| 400 + (i % 7) as u16).collect(),
    }
}

fn all(reader: ArchiveReader) -> Vec<Result<ArchivedRelease, String>> {
    reader.map(|r| r.map_err(|e| e.to_string())).collect()
}

#[test]
fn a_data_set_round_trips_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("fleet.parquet");
    let (summary, skipped) = pack(&[small()], &archive).unwrap();
    assert!(skipped.is_empty(), "{skipped}");
    let original = read_manifest(&small()).unwrap();
    assert_eq!(summary.releases, original.len());
    assert!(summary.archive_bytes > 0 && summary.archive_bytes < summary.csv_bytes, "{summary}");

    // The archive: sorted by (locomotive, release), one row group per release, and each
    // release equal to what the CSV reader reads from its trace.
    let reader = ArchiveReader::open(&archive).unwrap();
    assert_eq!(reader.row_groups(), original.len());
    let releases: Vec<ArchivedRelease> = reader.map(Result::unwrap).collect();
    let keys: Vec<(String, String)> = releases.iter().map(|r| (r.locomotive.clone(), r.release.clone())).collect();
    let mut sorted = keys.clone();
    sorted.sort();
    assert_eq!(keys, sorted);
    for r in &releases {
        let row = original.iter().find(|m| m.file == r.release).unwrap();
        assert_eq!(
            (&r.locomotive, r.label.as_deref(), r.split.as_deref()),
            (&row.locomotive, Some(&*row.label), Some(&*row.split))
        );
        let csv = read_trace(&small().join(&r.release)).unwrap();
        let trace = r.clone().into_trace(format!("fleet.parquet: {}", r.release));
        assert_eq!(trace.metadata, csv.metadata);
        assert_eq!(trace.t_s, csv.t_s);
        assert_eq!(trace.samples, csv.samples);
        assert!(matches!(trace.samples, Samples::Adc(_)));
    }

    // Back to a data set: the same manifest rows (in the archive's order) and the same bytes.
    let back = tmp.path().join("back");
    let (unpacked, skipped) = unpack(&archive, &back).unwrap();
    assert!(skipped.is_empty(), "{skipped}");
    assert_eq!(unpacked.releases, original.len());
    let mut rows = read_manifest(&back).unwrap();
    let mut want = original.clone();
    rows.sort_by(|a, b| a.file.cmp(&b.file));
    want.sort_by(|a, b| a.file.cmp(&b.file));
    assert_eq!(rows, want);
    for row in &original {
        let a = std::fs::read(small().join(&row.file)).unwrap();
        let b = std::fs::read(back.join(&row.file)).unwrap();
        assert!(a == b, "{} differs after the round trip", row.file);
    }

    // And packing the unpacked set again gives the same archive contents.
    let again = tmp.path().join("again.parquet");
    pack(&[back], &again).unwrap();
    let a: Vec<_> = all(ArchiveReader::open(&archive).unwrap());
    let b: Vec<_> = all(ArchiveReader::open(&again).unwrap());
    assert_eq!(a, b);
}

#[test]
fn one_locomotive_is_read_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("fleet.parquet");
    pack(&[small()], &archive).unwrap();
    let reader = ArchiveReader::open(&archive).unwrap().only_locomotive("loco-01");
    let picked: Vec<ArchivedRelease> = reader.map(Result::unwrap).collect();
    let want = read_manifest(&small()).unwrap().into_iter().filter(|r| r.locomotive == "loco-01").count();
    assert!(want > 0);
    assert_eq!(picked.len(), want);
    assert!(picked.iter().all(|r| r.locomotive == "loco-01"));
    assert_eq!(ArchiveReader::open(&archive).unwrap().only_locomotive("nobody").count(), 0);
}

#[test]
fn writer_refuses_what_breaks_the_format() {
    let tmp = tempfile::tempdir().unwrap();
    let mut w = ArchiveWriter::create(&tmp.path().join("a.parquet")).unwrap();
    w.add(&release("loco-02", "b.csv", 10)).unwrap();
    let e = w.add(&release("loco-01", "a.csv", 10)).unwrap_err().to_string();
    assert!(e.contains("release a.csv of loco-01") && e.contains("sorted"), "{e}");
    let e = w.add(&release("loco-02", "b.csv", 10)).unwrap_err().to_string();
    assert!(e.contains("sorted"), "{e}");
    let mut bad = release("loco-03", "c.csv", 10);
    bad.adc[4] = 4096;
    let e = w.add(&bad).unwrap_err().to_string();
    assert!(e.contains("release c.csv of loco-03: sample 4: adc value 4096 outside 0..=4095"), "{e}");
    let mut bad = release("loco-03", "c.csv", 10);
    bad.t_s[5] = bad.t_s[4];
    let e = w.add(&bad).unwrap_err().to_string();
    assert!(e.contains("sample 5: time not increasing"), "{e}");
    w.add(&release("loco-03", "c.csv", 10)).unwrap();
    w.finish().unwrap();
    let got = all(ArchiveReader::open(&tmp.path().join("a.parquet")).unwrap());
    assert_eq!(got, vec![Ok(release("loco-02", "b.csv", 10)), Ok(release("loco-03", "c.csv", 10))]);
}

#[test]
fn pack_skips_what_it_cannot_archive_and_packs_the_rest() {
    let tmp = tempfile::tempdir().unwrap();
    let good = small().join("traces/test/normal_0000.csv");
    let pressure = tmp.path().join("p.csv");
    std::fs::write(&pressure, "# locomotive: loco-09\nt_s,p_bar\n0.00,0.0\n0.01,0.1\n").unwrap();
    let anonymous = tmp.path().join("anon.csv");
    std::fs::write(&anonymous, "t_s,adc\n0.00,410\n0.01,411\n").unwrap();
    let broken = tmp.path().join("broken.csv");
    std::fs::write(&broken, "# locomotive: loco-09\nt_s,adc\n0.00,410\n0.01,5000\n").unwrap();
    let archive = tmp.path().join("a.parquet");
    let (summary, skipped) = pack(&[good.clone(), pressure, anonymous, broken, good], &archive).unwrap();
    assert_eq!(summary.releases, 1);
    let text = skipped.to_string();
    assert_eq!(skipped.len(), 4, "{text}");
    assert!(text.contains("p.csv: a `t_s,p_bar` (pressure) trace: only ADC traces"), "{text}");
    assert!(text.contains("anon.csv: no `# locomotive:` metadata"), "{text}");
    assert!(text.contains("broken.csv:4: adc value 5000 outside 0..=4095"), "{text}");
    assert!(text.contains("release normal_0000.csv of loco-05 is already packed"), "{text}");
    // Nothing at all to pack: an error, and no archive left behind.
    let none = tmp.path().join("none.parquet");
    let e = pack(&[tmp.path().join("p.csv")], &none).unwrap_err().to_string();
    assert!(e.contains("nothing to pack"), "{e}");
    assert!(!none.exists() && !tmp.path().join("none.parquet.partial").exists());
    // The output may not be one of the inputs.
    let e = pack(&[tmp.path().join("broken.csv")], &tmp.path().join("broken.csv")).unwrap_err().to_string();
    assert!(e.contains("would overwrite the input"), "{e}");
}

#[test]
fn unpack_refuses_a_non_empty_output_and_paths_leaving_it() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("a.parquet");
    let mut w = ArchiveWriter::create(&archive).unwrap();
    w.add(&release("loco-01", "../escape.csv", 5)).unwrap();
    w.add(&release("loco-01", "ok/x.csv", 5)).unwrap();
    w.add(&release("loco-02", "ok/x.csv", 5)).unwrap();
    w.finish().unwrap();
    let out = tmp.path().join("out");
    let (summary, skipped) = unpack(&archive, &out).unwrap();
    assert_eq!(summary.releases, 1);
    let text = skipped.to_string();
    assert!(text.contains("release ../escape.csv of loco-01: file `../escape.csv` must be a relative path"), "{text}");
    assert!(text.contains("release ok/x.csv of loco-02: its path is already taken"), "{text}");
    assert!(!tmp.path().join("escape.csv").exists());
    let e = unpack(&archive, &out).unwrap_err().to_string();
    assert!(e.contains("not an empty directory"), "{e}");
}

// ---- bad archives, written column by column with the parquet crate ---------------------------

/// One column's values for a raw row group.
enum Col {
    Text(Vec<Option<&'static str>>),
    I32(Vec<i32>),
    I64(Vec<i64>),
    F64(Vec<f64>),
}

/// The columns of a well-formed release (`loco`, `name`, `n` samples) in the format's order.
fn raw_release(loco: &'static str, name: &'static str, n: usize) -> Vec<Col> {
    let mut meta = vec![None; n];
    meta[0] = Some(r#"{"locomotive": "x"}"#);
    vec![
        Col::Text(vec![Some(loco); n]),
        Col::Text(vec![Some(name); n]),
        Col::Text(vec![Some("normal"); n]),
        Col::Text(vec![None; n]),
        Col::I32((0..n as i32).collect()),
        Col::F64((0..n).map(|i| i as f64 / 100.0).collect()),
        Col::I32(vec![410; n]),
        Col::Text(meta),
    ]
}

/// Writes row groups of raw columns under `schema`, with the version key unless `version` is
/// `None`.
fn write_raw(path: &Path, schema: &str, groups: &[Vec<Col>], version: Option<&str>) {
    let kv = version.map(|v| vec![KeyValue::new("pbm.archive.version".to_owned(), v.to_owned())]);
    let props = Arc::new(WriterProperties::builder().set_key_value_metadata(kv).build());
    let schema = Arc::new(parse_message_type(schema).unwrap());
    let descr = parquet::schema::types::SchemaDescriptor::new(schema.clone());
    let mut w = SerializedFileWriter::new(std::fs::File::create(path).unwrap(), schema, props).unwrap();
    for cols in groups {
        let mut g = w.next_row_group().unwrap();
        let mut i = 0;
        while let Some(mut c) = g.next_column().unwrap() {
            let optional = descr.column(i).max_def_level() > 0;
            match &cols[i] {
                Col::Text(v) => {
                    let values: Vec<ByteArray> = v.iter().flatten().map(|s| ByteArray::from(*s)).collect();
                    let def: Vec<i16> = v.iter().map(|x| i16::from(x.is_some())).collect();
                    c.typed::<ByteArrayType>().write_batch(&values, optional.then_some(&def[..]), None).unwrap();
                }
                Col::I32(v) => {
                    let def = vec![1i16; v.len()];
                    c.typed::<Int32Type>().write_batch(v, optional.then_some(&def[..]), None).unwrap();
                }
                Col::I64(v) => {
                    c.typed::<Int64Type>().write_batch(v, None, None).unwrap();
                }
                Col::F64(v) => {
                    let def = vec![1i16; v.len()];
                    c.typed::<DoubleType>().write_batch(v, optional.then_some(&def[..]), None).unwrap();
                }
            }
            c.close().unwrap();
            i += 1;
        }
        g.close().unwrap();
    }
    w.close().unwrap();
}

fn open_err(path: &Path) -> String {
    ArchiveReader::open(path).unwrap_err().to_string()
}

#[test]
fn a_file_that_is_not_parquet_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("x.parquet");
    std::fs::copy(small().join("traces/test/normal_0000.csv"), &p).unwrap();
    let e = open_err(&p);
    assert!(e.starts_with(&format!("{}: not a Parquet file", p.display())), "{e}");
    // A real archive cut short (its footer gone) and an empty file.
    let good = tmp.path().join("good.parquet");
    pack(&[small()], &good).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    for cut in [0, 3, bytes.len() / 2, bytes.len() - 5] {
        std::fs::write(&p, &bytes[..cut]).unwrap();
        let e = open_err(&p);
        assert!(e.contains("not a Parquet file"), "cut at {cut}: {e}");
    }
    // A directory and a missing file.
    assert!(open_err(tmp.path()).contains("a directory: refused"));
    assert!(open_err(&tmp.path().join("none.parquet")).contains("cannot read"));
}

#[test]
fn a_missing_misplaced_or_mistyped_column_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("x.parquet");
    let without_meta = SCHEMA.replace("optional binary meta (STRING);", "");
    let mut cols = raw_release("l", "r", 3);
    cols.pop();
    write_raw(&p, &without_meta, &[cols], Some("1"));
    assert!(
        open_err(&p).ends_with(
            "column `meta` missing (the columns are locomotive, release, label, split, sample, t_s, adc, meta)"
        ),
        "{}",
        open_err(&p)
    );

    let swapped = SCHEMA
        .replace("required double t_s;\n    required int32 adc;", "required int32 adc;\n    required double t_s;");
    let mut cols = raw_release("l", "r", 3);
    cols.swap(5, 6);
    write_raw(&p, &swapped, &[cols], Some("1"));
    assert!(open_err(&p).contains("column 6 is `adc`, expected `t_s`"), "{}", open_err(&p));

    let wide_adc = SCHEMA.replace("required int32 adc;", "required int64 adc;");
    let mut cols = raw_release("l", "r", 3);
    cols[6] = Col::I64(vec![410; 3]);
    write_raw(&p, &wide_adc, &[cols], Some("1"));
    assert!(open_err(&p).contains("column `adc` is INT64"), "{}", open_err(&p));

    let binary_loco = SCHEMA.replace("required binary locomotive (STRING);", "required binary locomotive;");
    write_raw(&p, &binary_loco, &[raw_release("l", "r", 3)], Some("1"));
    assert!(open_err(&p).contains("column `locomotive` is BYTE_ARRAY"), "{}", open_err(&p));

    let extra =
        SCHEMA.replace("optional binary meta (STRING);", "optional binary meta (STRING);\n    required int32 more;");
    let mut cols = raw_release("l", "r", 3);
    cols.push(Col::I32(vec![0; 3]));
    write_raw(&p, &extra, &[cols], Some("1"));
    assert!(open_err(&p).contains("unexpected column `more`"), "{}", open_err(&p));
}

#[test]
fn the_version_key_is_required() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("x.parquet");
    write_raw(&p, SCHEMA, &[raw_release("l", "r", 3)], None);
    assert!(open_err(&p).contains("not a fleet archive: no `pbm.archive.version` key"), "{}", open_err(&p));
    write_raw(&p, SCHEMA, &[raw_release("l", "r", 3)], Some("2"));
    assert!(open_err(&p).contains("archive version 2; this build reads version 1"), "{}", open_err(&p));
}

#[test]
fn bad_releases_are_named_and_the_others_still_read() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("x.parquet");
    let name = p.display().to_string();
    let mut groups = Vec::new();
    groups.push(raw_release("loco-01", "a.csv", 5));
    let mut high = raw_release("loco-01", "b.csv", 5);
    high[6] = Col::I32(vec![410, 411, 5000, 412, 413]);
    groups.push(high);
    let mut negative = raw_release("loco-01", "c.csv", 5);
    negative[6] = Col::I32(vec![410, -1, 411, 412, 413]);
    groups.push(negative);
    let mut backwards = raw_release("loco-01", "d.csv", 5);
    backwards[5] = Col::F64(vec![0.0, 0.01, 0.03, 0.02, 0.04]);
    groups.push(backwards);
    let mut nan = raw_release("loco-01", "e.csv", 5);
    nan[5] = Col::F64(vec![0.0, f64::NAN, 0.02, 0.03, 0.04]);
    groups.push(nan);
    let mut numbering = raw_release("loco-01", "f.csv", 5);
    numbering[4] = Col::I32(vec![0, 1, 3, 2, 4]);
    groups.push(numbering);
    let mut meta_twice = raw_release("loco-01", "g.csv", 3);
    meta_twice[7] = Col::Text(vec![Some("{}"), None, Some("{}")]);
    groups.push(meta_twice);
    let mut meta_not_json = raw_release("loco-01", "h.csv", 3);
    meta_not_json[7] = Col::Text(vec![Some("locomotive: x"), None, None]);
    groups.push(meta_not_json);
    let mut label_changes = raw_release("loco-01", "i.csv", 3);
    label_changes[2] = Col::Text(vec![Some("normal"), Some("air_leak"), Some("normal")]);
    groups.push(label_changes);
    // A release split over two row groups, and two releases in one.
    groups.push(raw_release("loco-02", "split.csv", 3));
    groups.push(raw_release("loco-02", "split.csv", 3));
    let mut two = raw_release("loco-02", "two.csv", 3);
    two[1] = Col::Text(vec![Some("two.csv"), Some("two.csv"), Some("three.csv")]);
    groups.push(two);
    groups.push(raw_release("loco-03", "z.csv", 5));
    write_raw(&p, SCHEMA, &groups, Some("1"));

    let got = all(ArchiveReader::open(&p).unwrap());
    assert_eq!(got.len(), groups.len());
    let ok: Vec<&str> = got.iter().filter_map(|r| r.as_ref().ok()).map(|r| r.release.as_str()).collect();
    assert_eq!(ok, ["a.csv", "z.csv"]);
    let err = |i: usize| got[i].as_ref().unwrap_err().clone();
    let expect = [
        (1, "release b.csv of loco-01 (row group 1): sample 2: adc value 5000 outside 0..=4095"),
        (2, "release c.csv of loco-01 (row group 2): sample 1: adc value -1 outside 0..=4095"),
        (3, "release d.csv of loco-01 (row group 3): sample 3: time not increasing: 0.02 s after 0.03 s"),
        (4, "release e.csv of loco-01 (row group 4): sample 1: t_s is NaN or infinite"),
        (5, "release f.csv of loco-01 (row group 5): row 2 has sample index 3"),
        (6, "release g.csv of loco-01 (row group 6): `meta` on row 2: only a release's first row carries"),
        (7, "release h.csv of loco-01 (row group 7): `meta` is not a JSON object of strings"),
        (8, "release i.csv of loco-01 (row group 8): `label` changes within the release"),
        (9, "release split.csv of loco-02: split over row groups 9 and 10 (a release must be one row group)"),
        (10, "release split.csv of loco-02: split over row groups 9 and 10"),
        (11, "row group 11: two releases in one row group (`release` is two.csv on row 0 and three.csv on row 2)"),
    ];
    for (i, want) in expect {
        let e = err(i);
        assert!(e.starts_with(&format!("{name}: ")), "{e}");
        assert!(e.contains(want), "row group {i}: {e}\nwanted: {want}");
    }
}

#[test]
fn nulls_where_the_format_requires_values_are_refused() {
    // pyarrow declares every column optional unless told: such a file reads while it has no
    // null where the format requires a value.
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("x.parquet");
    let nullable = SCHEMA.replace("required", "optional");
    let mut with_null = raw_release("loco-01", "b.csv", 3);
    with_null[0] = Col::Text(vec![Some("loco-01"), None, Some("loco-01")]);
    write_raw(&p, &nullable, &[raw_release("loco-01", "a.csv", 3), with_null], Some("1"));
    let got = all(ArchiveReader::open(&p).unwrap());
    assert_eq!(got[0].as_ref().map(|r| r.release.as_str()), Ok("a.csv"));
    let e = got[1].as_ref().unwrap_err();
    assert!(e.contains("row group 1: `locomotive` is null on some rows"), "{e}");
}

#[test]
fn row_groups_read_from_several_threads_at_once_are_right() {
    // The parquet crate's reader of a `File` shares one cursor between clones; the archive
    // reader reads at explicit offsets instead (a parallel replay read wrong pages before).
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("fleet.parquet");
    pack(&[small()], &archive).unwrap();
    let reader = ArchiveReader::open(&archive).unwrap();
    let sequential: Vec<ArchivedRelease> = (0..reader.row_groups()).map(|i| reader.read(i).unwrap()).collect();
    std::thread::scope(|s| {
        for t in 0..4 {
            let (reader, sequential) = (&reader, &sequential);
            s.spawn(move || {
                for round in 0..20 {
                    for k in 0..sequential.len() {
                        let i = (k + t + round) % sequential.len();
                        assert_eq!(reader.read(i).as_ref(), Ok(&sequential[i]), "thread {t}, row group {i}");
                    }
                }
            });
        }
    });
}
