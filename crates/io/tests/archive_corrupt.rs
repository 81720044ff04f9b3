//! A damaged archive (bytes flipped anywhere in the file) is an error, never a panic: every
//! 199th byte of a packed data set, one at a time, read through every row group. (The parquet
//! crate asserts on some damaged footers; the reader turns that into an error.)

use pbm_io::archive::{pack, ArchiveReader};
use std::path::Path;

#[test]
fn flipped_bytes_are_errors_not_panics() {
    let tmp = tempfile::tempdir().unwrap();
    let good = tmp.path().join("good.parquet");
    pack(&[Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/small")], &good).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let bad = tmp.path().join("bad.parquet");
    let (mut refused, mut bad_releases, mut panics) = (0, 0, Vec::new());
    // Plus the bytes whose flip made the parquet crate panic when this test was written.
    let known = [114_751, 122_996, 125_712, 125_809].into_iter().filter(|&at| at < bytes.len());
    for at in (0..bytes.len()).step_by(199).chain(known) {
        let mut b = bytes.clone();
        b[at] ^= 0xA5;
        std::fs::write(&bad, &b).unwrap();
        let run = std::panic::catch_unwind(|| match ArchiveReader::open(&bad) {
            Err(_) => (1, 0),
            Ok(r) => (0, r.filter(Result::is_err).count()),
        });
        match run {
            Ok((r, n)) => {
                refused += r;
                bad_releases += n;
            }
            Err(_) => panics.push(at),
        }
    }
    println!("{} positions: {refused} files refused, {bad_releases} releases refused", bytes.len().div_ceil(199));
    assert!(panics.is_empty(), "the reader panicked on bytes flipped at {panics:?}");
}
