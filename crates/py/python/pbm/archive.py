"""Fleet archives: one Parquet file, long format, one row group per release.

The format (shared with the Rust side, ``host-sim``): columns ``locomotive`` (str),
``release`` (str: the trace's path relative to its data set), ``label`` and ``split``
(str or null), ``sample`` (int32, 0-based), ``t_s`` (float64), ``adc`` (int32, 0..=4095) and
``meta`` (str: the trace's ``# key: value`` metadata as one JSON object, on a release's first
row only; null elsewhere). Rows of a release are in sample order, releases sorted by
(locomotive, release), and a release never spans two row groups. File metadata
``pbm.archive.version`` = ``1``.

Readers stream: :func:`read_releases` holds one row group (= one release) in memory at a
time, so an archive of any size is read in the memory of its largest release.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Dict, Iterable, Iterator, List, Optional, Sequence, Tuple

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

#: Value of the ``pbm.archive.version`` file metadata this module reads and writes.
VERSION = "1"
#: Key of the format version in the Parquet file's key-value metadata.
VERSION_KEY = b"pbm.archive.version"
#: Largest 12-bit ADC count.
ADC_MAX = 4095

#: The archive's columns, in order.
SCHEMA = pa.schema(
    [
        pa.field("locomotive", pa.string(), nullable=False),
        pa.field("release", pa.string(), nullable=False),
        pa.field("label", pa.string(), nullable=True),
        pa.field("split", pa.string(), nullable=True),
        pa.field("sample", pa.int32(), nullable=False),
        pa.field("t_s", pa.float64(), nullable=False),
        pa.field("adc", pa.int32(), nullable=False),
        pa.field("meta", pa.string(), nullable=True),
    ],
    metadata={VERSION_KEY: VERSION.encode()},
)


class ArchiveError(ValueError):
    """An archive that does not follow the format (the message names the row group)."""


@dataclass
class Release:
    """One release of a fleet archive: its identity and its samples."""

    #: Locomotive id.
    locomotive: str
    #: Release id (the trace's path relative to its data set, or its file name).
    release: str
    #: Sample times, s (float64).
    t_s: np.ndarray
    #: ADC counts (uint16, 0..=4095).
    adc: np.ndarray
    #: True class, when known.
    label: Optional[str] = None
    #: ``train`` / ``test``, when known.
    split: Optional[str] = None
    #: The trace's ``# key: value`` metadata, in file order.
    meta: Dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class RowGroup:
    """Where a release lies in an archive (what :func:`index` lists)."""

    #: Row group number.
    row_group: int
    #: Locomotive id.
    locomotive: str
    #: Release id.
    release: str
    #: Samples.
    rows: int


def _check_release(r: Release) -> Tuple[np.ndarray, np.ndarray]:
    """The release's columns as float64 / int32 arrays, or a ValueError saying what is wrong."""
    where = f"release {r.locomotive}/{r.release}"
    if not r.locomotive or not r.release:
        raise ValueError(f"{where}: locomotive and release ids must be non-empty strings")
    t = np.asarray(r.t_s)
    adc = np.asarray(r.adc)
    if t.ndim != 1 or adc.ndim != 1:
        raise ValueError(f"{where}: t_s and adc must be 1-D arrays")
    if len(adc) == 0:
        raise ValueError(f"{where}: a release needs at least one sample")
    if len(t) != len(adc):
        raise ValueError(f"{where}: t_s has {len(t)} samples, adc has {len(adc)}")
    if not np.issubdtype(t.dtype, np.floating):
        raise ValueError(f"{where}: t_s must be a float array, got {t.dtype}")
    if not np.all(np.isfinite(t)):
        raise ValueError(f"{where}: t_s holds a non-finite value (NaN or inf)")
    if not np.issubdtype(adc.dtype, np.integer):
        raise ValueError(f"{where}: adc must be an integer array of ADC counts, got {adc.dtype}")
    if adc.min() < 0 or adc.max() > ADC_MAX:
        raise ValueError(f"{where}: adc holds a count outside 0..={ADC_MAX}")
    return t.astype(np.float64, copy=False), adc.astype(np.int32)


def release_table(r: Release) -> pa.Table:
    """One release as an Arrow table of the archive's schema."""
    t, adc = _check_release(r)
    n = len(adc)
    meta = [json.dumps(dict(r.meta), ensure_ascii=False)] + [None] * (n - 1)
    return pa.Table.from_arrays(
        [
            pa.array([r.locomotive] * n, pa.string()),
            pa.array([r.release] * n, pa.string()),
            pa.array([r.label] * n, pa.string()),
            pa.array([r.split] * n, pa.string()),
            pa.array(np.arange(n, dtype=np.int32)),
            pa.array(t),
            pa.array(adc),
            pa.array(meta, pa.string()),
        ],
        schema=SCHEMA,
    )


def write_archive(path: str, releases: Iterable[Release], compression: str = "zstd") -> int:
    """Writes ``releases`` as a fleet archive at ``path``, one row group each; returns their count.

    Releases are sorted by (locomotive, release) as the format requires (so they are held in
    memory until written; a caller streaming a huge fleet passes them sorted and can use
    :class:`ArchiveWriter` directly). A (locomotive, release) pair given twice is refused.
    """
    ordered = sorted(releases, key=lambda r: (r.locomotive, r.release))
    with ArchiveWriter(path, compression=compression) as w:
        for r in ordered:
            w.write(r)
        return w.count


class ArchiveWriter:
    """Streams releases, already sorted by (locomotive, release), into a fleet archive."""

    def __init__(self, path: str, compression: str = "zstd") -> None:
        """Creates (or truncates) the archive at ``path``."""
        # The encodings host-sim writes: ids with a dictionary, sample index and counts delta
        # coded, times byte-stream split, zstd level 1 over all (≈ 11 % of the trace CSV;
        # pyarrow's defaults give ≈ 85 %: the times and noisy counts defeat plain encodings).
        self._writer = pq.ParquetWriter(
            path,
            SCHEMA,
            compression=compression,
            compression_level=1 if compression == "zstd" else None,
            use_dictionary=["locomotive", "release", "label", "split"],
            column_encoding={
                "sample": "DELTA_BINARY_PACKED",
                "adc": "DELTA_BINARY_PACKED",
                "t_s": "BYTE_STREAM_SPLIT",
                "meta": "PLAIN",
            },
            write_statistics=True,
        )
        self._last: Optional[Tuple[str, str]] = None
        #: Releases written.
        self.count = 0

    def write(self, r: Release) -> None:
        """Appends one release as one row group; refuses one out of (locomotive, release) order."""
        key = (r.locomotive, r.release)
        if self._last is not None and key <= self._last:
            raise ValueError(
                f"release {r.locomotive}/{r.release} out of order or repeated "
                f"(after {self._last[0]}/{self._last[1]}): releases must be sorted by (locomotive, release)"
            )
        table = release_table(r)
        self._writer.write_table(table, row_group_size=table.num_rows)
        self._last = key
        self.count += 1

    def close(self) -> None:
        """Writes the footer."""
        self._writer.close()

    def __enter__(self) -> "ArchiveWriter":
        """Context manager: closes on exit."""
        return self

    def __exit__(self, *exc: object) -> None:
        """Closes the file."""
        self.close()


def open_archive(path: str) -> pq.ParquetFile:
    """Opens an archive and checks its version and columns (a local path or a URI pyarrow knows,
    e.g. ``s3://bucket/fleet.parquet``)."""
    if "://" in str(path):
        fs, inner = pa.fs.FileSystem.from_uri(str(path))
        source = fs.open_input_file(inner)
    else:
        source = str(path)
    try:
        pf = pq.ParquetFile(source)
    except (pa.ArrowInvalid, OSError) as e:
        if isinstance(e, FileNotFoundError):
            raise
        raise ArchiveError(f"{path}: not a Parquet file ({e})") from e
    meta = pf.metadata.metadata or {}
    version = meta.get(VERSION_KEY)
    if version != VERSION.encode():
        raise ArchiveError(
            f"{path}: not a fleet archive of version {VERSION} "
            f"(pbm.archive.version is {version.decode() if version else 'missing'})"
        )
    names = pf.schema_arrow.names
    if names != SCHEMA.names:
        raise ArchiveError(f"{path}: columns {names}, expected {SCHEMA.names}")
    return pf


def index(path: str) -> List[RowGroup]:
    """Lists the releases of an archive (row group, locomotive, release, samples), reading only
    the two identity columns of each row group."""
    pf = open_archive(path)
    out = []
    for g in range(pf.num_row_groups):
        ids = pf.read_row_group(g, columns=["locomotive", "release"])
        locos = ids.column("locomotive").unique()
        rels = ids.column("release").unique()
        if len(locos) != 1 or len(rels) != 1:
            raise ArchiveError(f"{path}: row group {g} holds {len(rels)} releases (one per row group)")
        out.append(RowGroup(g, locos[0].as_py(), rels[0].as_py(), ids.num_rows))
    return out


def _release_of(path: str, pf: pq.ParquetFile, g: int) -> Release:
    """Row group ``g`` as a :class:`Release`, checked."""
    tb = pf.read_row_group(g)
    where = f"{path}: row group {g}"
    if tb.num_rows == 0:
        raise ArchiveError(f"{where}: empty")
    loco = tb.column("locomotive").unique()
    rel = tb.column("release").unique()
    if len(loco) != 1 or len(rel) != 1:
        raise ArchiveError(f"{where}: holds {len(rel)} releases (one per row group)")
    sample = tb.column("sample").to_numpy()
    if not np.array_equal(sample, np.arange(tb.num_rows)):
        raise ArchiveError(f"{where}: samples are not 0..{tb.num_rows - 1} in order")
    if tb.column("t_s").null_count or tb.column("adc").null_count:
        raise ArchiveError(f"{where}: null t_s or adc")
    adc = tb.column("adc").to_numpy()
    if adc.min() < 0 or adc.max() > ADC_MAX:
        raise ArchiveError(f"{where}: adc count outside 0..={ADC_MAX}")
    meta_text = tb.column("meta")[0].as_py()
    try:
        meta = json.loads(meta_text) if meta_text else {}
    except json.JSONDecodeError as e:
        raise ArchiveError(f"{where}: meta is not a JSON object ({e})") from e
    if not isinstance(meta, dict):
        raise ArchiveError(f"{where}: meta is not a JSON object")
    return Release(
        locomotive=loco[0].as_py(),
        release=rel[0].as_py(),
        label=tb.column("label")[0].as_py(),
        split=tb.column("split")[0].as_py(),
        t_s=tb.column("t_s").to_numpy(),
        adc=adc.astype(np.uint16),
        meta={str(k): str(v) for k, v in meta.items()},
    )


def read_releases(path: str, row_groups: Optional[Sequence[int]] = None) -> Iterator[Release]:
    """Streams the releases of an archive (all, or the given row groups), one row group at a time."""
    pf = open_archive(path)
    groups = range(pf.num_row_groups) if row_groups is None else row_groups
    for g in groups:
        if not 0 <= g < pf.num_row_groups:
            raise ArchiveError(f"{path}: no row group {g} (the archive has {pf.num_row_groups})")
        yield _release_of(path, pf, g)


def releases_from_dataset(directory: str) -> Iterator[Release]:
    """The releases of a data set directory (``manifest.csv`` + ADC traces), read with the CLI's
    trace reader (``pbm.read_trace``): what goes into an archive of that data set. A pressure
    (``p_bar``) trace is refused, as the format holds ADC traces only."""
    import csv
    import os

    from . import read_trace

    with open(os.path.join(directory, "manifest.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        trace = read_trace(os.path.join(directory, row["file"]))
        if trace["kind"] != "adc":
            raise ValueError(f"{row['file']}: a pressure trace; a fleet archive holds ADC traces only")
        yield Release(
            locomotive=row["locomotive"],
            release=row["file"],
            label=row["label"] or None,
            split=row["split"] or None,
            t_s=trace["t_s"],
            adc=trace["adc"],
            meta=trace["meta"],
        )


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m pbm.archive DATASET OUT.parquet``: writes a data set directory as an archive."""
    import argparse

    p = argparse.ArgumentParser(prog="python -m pbm.archive", description=main.__doc__)
    p.add_argument("dataset", help="data set directory (manifest.csv + ADC traces)")
    p.add_argument("out", help="the archive to write (Parquet)")
    a = p.parse_args(argv)
    n = write_archive(a.out, releases_from_dataset(a.dataset))
    print(f"wrote {n} releases to {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
