//! Memory of the archive writer and reader does not grow with the number of releases: the
//! peak of live heap bytes while 500 releases are written and read back is compared with the
//! peak for 50 (a counting allocator; this file holds one test so that no other test's
//! allocations are counted). The samples grow tenfold; the peak grows only by the footer's
//! per-release metadata (a few kB per release, which Parquet keeps for the whole file).

use pbm_io::archive::{ArchiveReader, ArchiveWriter, ArchivedRelease};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded to the system allocator with the caller's layout.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(live, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `alloc` above with this layout.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Samples per release: a 60 s release at 100 Hz.
const SAMPLES: usize = 6000;

fn release(i: usize) -> ArchivedRelease {
    ArchivedRelease {
        locomotive: format!("loco-{:02}", i % 7),
        release: format!("traces/normal_{i:04}.csv"),
        label: Some("normal".into()),
        split: Some("train".into()),
        metadata: vec![("seed".into(), i.to_string())],
        t_s: (0..SAMPLES).map(|k| k as f64 / 100.0).collect(),
        adc: (0..SAMPLES).map(|k| (400 + (k * 7919 + i) % 3000) as u16).collect(),
    }
}

/// Peak live heap above the level at the start, bytes, while `f` runs.
fn peak_of(f: impl FnOnce()) -> usize {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    f();
    PEAK.load(Ordering::Relaxed) - base
}

/// (peak while writing, peak while reading) an archive of `n` releases.
fn peaks(dir: &std::path::Path, n: usize) -> (usize, usize) {
    let path = dir.join(format!("{n}.parquet"));
    // Releases sorted by (locomotive, release), made one at a time as a pack reads them.
    let mut keys: Vec<usize> = (0..n).collect();
    keys.sort_by_key(|&i| (format!("loco-{:02}", i % 7), i));
    let write = peak_of(|| {
        let mut w = ArchiveWriter::create(&path).unwrap();
        for &i in &keys {
            w.add(&release(i)).unwrap();
        }
        w.finish().unwrap();
    });
    let mut count = 0;
    let read = peak_of(|| {
        for r in ArchiveReader::open(&path).unwrap() {
            let r = r.unwrap();
            assert_eq!(r.adc.len(), SAMPLES);
            count += 1;
        }
    });
    assert_eq!(count, n);
    (write, read)
}

#[test]
fn memory_does_not_grow_with_the_number_of_releases() {
    let tmp = tempfile::tempdir().unwrap();
    let (write_50, read_50) = peaks(tmp.path(), 50);
    let (write_500, read_500) = peaks(tmp.path(), 500);
    // The samples of 500 releases as the reader holds them (f64 time, u16 count).
    let data_500 = 500 * SAMPLES * 10;
    println!(
        "peak live heap: write 50 → {write_50} B, 500 → {write_500} B; read 50 → {read_50} B, 500 → {read_500} B; \
         samples of 500 releases {data_500} B"
    );
    for (small, large, what) in [(write_50, write_500, "writing"), (read_50, read_500, "reading")] {
        // The Parquet footer describes every row group, so writer and reader keep a few kB per
        // release (measured 6.6 kB writing, 4.3 kB reading); a release's samples are 60 kB.
        let per_release = large.saturating_sub(small) / 450;
        assert!(per_release < 10_000, "{what}: {per_release} B more per release ({small} B for 50, {large} B for 500)");
        assert!(large < data_500 / 5, "{what}: peak {large} B is not small beside the {data_500} B of samples");
    }
}
