//! `archive pack` and `archive unpack`: data sets and trace files into one archive, and an
//! archive back into a data set.
//!
//! Manifest fields and the archive's optional columns meet through one convention: a label or
//! split of `-` in a manifest (the project's "none", as the replay table shows it) is a null
//! in the archive, and a null is written back as `-`.

use super::{ArchiveReader, ArchiveWriter, ArchivedRelease};
use crate::dataset::{write_manifest, Dataset, ManifestRow, MANIFEST, TRUTH};
use crate::error::{FileError, Skipped};
use crate::trace::{read_trace, TraceReader};
use anyhow::{bail, Context, Result};
use std::collections::{BTreeSet, HashSet};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// What [`pack`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct PackSummary {
    /// The archive.
    pub out: PathBuf,
    /// Releases written.
    pub releases: usize,
    /// Distinct locomotives among them.
    pub locomotives: usize,
    /// Samples written.
    pub samples: u64,
    /// Size of the trace files they came from, bytes.
    pub csv_bytes: u64,
    /// Size of the archive, bytes.
    pub archive_bytes: u64,
    /// Wall-clock time.
    pub elapsed: Duration,
}

impl std::fmt::Display for PackSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let secs = self.elapsed.as_secs_f64();
        write!(
            f,
            "packed {} releases of {} locomotives ({} samples) into {}: {} bytes, {:.1} % of the {} bytes of trace \
             CSV; {:.2} s ({:.0} releases/s)",
            self.releases,
            self.locomotives,
            self.samples,
            self.out.display(),
            self.archive_bytes,
            100.0 * self.archive_bytes as f64 / (self.csv_bytes.max(1)) as f64,
            self.csv_bytes,
            secs,
            if secs > 0.0 { self.releases as f64 / secs } else { 0.0 }
        )
    }
}

/// A release to pack: its key, what is known of it, and its trace file.
struct Entry {
    locomotive: String,
    release: String,
    label: Option<String>,
    split: Option<String>,
    path: PathBuf,
}

/// A manifest field, `-` read as unknown.
fn known(field: &str) -> Option<String> {
    (field != "-").then(|| field.to_owned())
}

/// The releases named by `inputs` (data set directories and trace files), and the inputs
/// refused while finding them.
fn entries(inputs: &[PathBuf], skipped: &mut Skipped, read_inputs: &mut Vec<PathBuf>) -> Vec<Entry> {
    let mut out = Vec::new();
    for input in inputs {
        if input.is_dir() {
            if !Dataset::is_dataset(input) {
                skipped.push(FileError::new(input.display(), 0, format!("a directory without {MANIFEST}")));
                continue;
            }
            let data = match Dataset::open(input) {
                Ok(d) => d,
                Err(e) => {
                    skipped.push(e);
                    continue;
                }
            };
            read_inputs.extend([input.join(MANIFEST), input.join(TRUTH)]);
            for e in data.refused() {
                skipped.push(e.clone());
            }
            for row in data.rows() {
                match data.trace_path(row) {
                    Ok(path) => out.push(Entry {
                        locomotive: row.locomotive.clone(),
                        release: row.file.clone(),
                        label: known(&row.label),
                        split: known(&row.split),
                        path,
                    }),
                    Err(e) => skipped.push(e),
                }
            }
            continue;
        }
        // A single trace: who and what come from its metadata.
        let reader = match TraceReader::open(input) {
            Ok(r) => r,
            Err(e) => {
                skipped.push(e);
                continue;
            }
        };
        let Some(locomotive) = reader.meta("locomotive").filter(|l| !l.is_empty()) else {
            skipped.push(FileError::new(
                input.display(),
                0,
                "no `# locomotive:` metadata, and no manifest names the locomotive: pack it from a data set",
            ));
            continue;
        };
        let release = input.file_name().map_or_else(|| input.display().to_string(), |n| n.to_string_lossy().into());
        out.push(Entry {
            locomotive: locomotive.to_owned(),
            release,
            label: reader.meta("label").and_then(known),
            split: reader.meta("split").and_then(known),
            path: input.clone(),
        });
    }
    out
}

/// Packs the traces of `inputs` (data set directories with `manifest.csv`, trace files with
/// `# locomotive:` metadata) into the archive `out`, sorted by (locomotive, release), one
/// release in memory at a time. A trace that cannot be read or archived (a pressure trace,
/// extra columns, a bad line), or whose (locomotive, release) was already taken, is skipped
/// with its file and line; the archive is written under a temporary name and renamed when
/// complete. Fails when nothing could be packed or the archive cannot be written.
pub fn pack(inputs: &[PathBuf], out: &Path) -> Result<(PackSummary, Skipped)> {
    let start = Instant::now();
    let mut skipped = Skipped::none();
    let mut read_inputs: Vec<PathBuf> = Vec::new();
    let mut entries = entries(inputs, &mut skipped, &mut read_inputs);
    read_inputs.extend(entries.iter().map(|e| e.path.clone()));
    crate::files::refuse_overwriting_inputs([out], read_inputs.iter().map(PathBuf::as_path))
        .map_err(anyhow::Error::msg)?;
    // Stable: of two entries with one key, the first given is packed.
    entries.sort_by(|a, b| (&a.locomotive, &a.release).cmp(&(&b.locomotive, &b.release)));
    let partial = {
        let mut name = out.as_os_str().to_owned();
        name.push(".partial");
        PathBuf::from(name)
    };
    let mut writer = ArchiveWriter::create(&partial)?;
    let (mut csv_bytes, mut locomotives) = (0u64, BTreeSet::new());
    let mut previous: Option<(String, String, PathBuf)> = None;
    for e in entries {
        let shown = e.path.display().to_string();
        if let Some((loco, release, first)) = &previous {
            if *loco == e.locomotive && *release == e.release {
                skipped.push(FileError::new(
                    &shown,
                    0,
                    format!(
                        "release {release} of {loco} is already packed from {}: a (locomotive, release) is archived \
                         once",
                        first.display()
                    ),
                ));
                continue;
            }
        }
        let trace = match read_trace(&e.path) {
            Ok(t) => t,
            Err(err) => {
                skipped.push(err);
                continue;
            }
        };
        let release = match ArchivedRelease::from_trace(e.locomotive, e.release, e.label, e.split, trace) {
            Ok(r) => r,
            Err(m) => {
                skipped.push(FileError::new(&shown, 0, m));
                continue;
            }
        };
        if let Err(err) = writer.add(&release) {
            let _ = std::fs::remove_file(&partial);
            return Err(err);
        }
        csv_bytes += std::fs::metadata(&e.path).map_or(0, |m| m.len());
        locomotives.insert(release.locomotive.clone());
        previous = Some((release.locomotive, release.release, e.path));
    }
    let (releases, samples) = (writer.releases(), writer.samples());
    let finished = writer.finish();
    if releases == 0 || finished.is_err() {
        let _ = std::fs::remove_file(&partial);
        finished?;
        bail!("nothing to pack{}", if skipped.is_empty() { String::new() } else { format!("\n{skipped}") });
    }
    std::fs::rename(&partial, out)
        .with_context(|| format!("cannot rename {} to {}", partial.display(), out.display()))?;
    let archive_bytes = std::fs::metadata(out).map_or(0, |m| m.len());
    let summary = PackSummary {
        out: out.to_owned(),
        releases,
        locomotives: locomotives.len(),
        samples,
        csv_bytes,
        archive_bytes,
        elapsed: start.elapsed(),
    };
    Ok((summary, skipped))
}

/// What [`unpack`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct UnpackSummary {
    /// The data set directory.
    pub out: PathBuf,
    /// Traces written.
    pub releases: usize,
    /// Wall-clock time.
    pub elapsed: Duration,
}

impl std::fmt::Display for UnpackSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let secs = self.elapsed.as_secs_f64();
        write!(
            f,
            "unpacked {} releases into the data set {} in {:.2} s ({:.0} releases/s)",
            self.releases,
            self.out.display(),
            secs,
            if secs > 0.0 { self.releases as f64 / secs } else { 0.0 }
        )
    }
}

/// Writes the archive `archive` back as a data set in `out` (absent or empty): one trace CSV
/// per release at its release id, and `manifest.csv` in the archive's order. A release that
/// cannot be read, or whose id is not a relative path inside the data set or repeats a path
/// already written, is skipped with the reason. Fails when the archive cannot be opened or
/// nothing could be unpacked.
pub fn unpack(archive: &Path, out: &Path) -> Result<(UnpackSummary, Skipped)> {
    let start = Instant::now();
    if out.exists() && std::fs::read_dir(out).map_or(true, |mut d| d.next().is_some()) {
        bail!("{} exists and is not an empty directory: choose a new output directory", out.display());
    }
    let reader = ArchiveReader::open(archive)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let name = reader.name().to_owned();
    let mut skipped = Skipped::none();
    let mut rows: Vec<ManifestRow> = Vec::new();
    let mut written: HashSet<String> = HashSet::new();
    for r in reader {
        let r = match r {
            Ok(r) => r,
            Err(e) => {
                skipped.push(e);
                continue;
            }
        };
        let refuse = |m: String| FileError::new(&name, 0, format!("release {} of {}: {m}", r.release, r.locomotive));
        if let Err(m) = crate::files::check_relative(&r.release) {
            skipped.push(refuse(m));
            continue;
        }
        if [MANIFEST, TRUTH].contains(&r.release.as_str()) || !written.insert(r.release.clone()) {
            skipped.push(refuse("its path is already taken in the data set being written".to_owned()));
            continue;
        }
        let path = out.join(&r.release);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        let mut file = std::io::BufWriter::new(
            std::fs::File::create(&path).with_context(|| format!("cannot create {}", path.display()))?,
        );
        r.write_csv(&mut file).with_context(|| format!("cannot write {}", path.display()))?;
        std::io::Write::flush(&mut file).with_context(|| format!("cannot write {}", path.display()))?;
        rows.push(ManifestRow {
            file: r.release,
            label: r.label.unwrap_or_else(|| "-".to_owned()),
            locomotive: r.locomotive,
            split: r.split.unwrap_or_else(|| "-".to_owned()),
        });
    }
    if rows.is_empty() {
        bail!(
            "nothing could be unpacked from {name}{}",
            if skipped.is_empty() { String::new() } else { format!("\n{skipped}") }
        );
    }
    write_manifest(&out.join(MANIFEST), &rows)?;
    Ok((UnpackSummary { out: out.to_owned(), releases: rows.len(), elapsed: start.elapsed() }, skipped))
}
