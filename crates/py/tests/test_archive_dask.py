"""Fleet archives (write/read round trip, the format's rules) and the Dask run (equal to the
single-process run)."""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

import pbm
from pbm import archive, fleet_dask
from conftest import DATA


def _release(loco, rel, n, seed, label=None, split=None, meta=None):
    rng = np.random.default_rng(seed)
    return archive.Release(
        locomotive=loco,
        release=rel,
        t_s=np.round(np.arange(n) * 0.01, 2),
        adc=rng.integers(0, 4096, n, dtype=np.uint16),
        label=label,
        split=split,
        meta=meta or {},
    )


def test_round_trip_keeps_every_column_and_one_row_group_per_release(tmp_path):
    path = str(tmp_path / "fleet.parquet")
    releases = [
        _release("loco-02", "traces/b.csv", 50, 1, "air_leak", "test", {"label": "air_leak", "seed": "7"}),
        _release("loco-01", "traces/z.csv", 30, 2),
        _release("loco-01", "traces/a.csv", 1, 3, "normal", "train", {"locomotive": "loco-01"}),
    ]
    assert archive.write_archive(path, releases) == 3
    pf = pq.ParquetFile(path)
    assert pf.num_row_groups == 3
    assert pf.metadata.metadata[b"pbm.archive.version"] == b"1"
    assert pf.schema_arrow.names == [
        "locomotive", "release", "label", "split", "sample", "t_s", "adc", "meta",
    ]
    assert [str(pf.schema_arrow.field(c).type) for c in ["sample", "t_s", "adc"]] == ["int32", "double", "int32"]
    # Sorted by (locomotive, release); meta on the first row only.
    idx = archive.index(path)
    assert [(g.locomotive, g.release, g.rows) for g in idx] == [
        ("loco-01", "traces/a.csv", 1), ("loco-01", "traces/z.csv", 30), ("loco-02", "traces/b.csv", 50),
    ]
    meta = pf.read_row_group(2).column("meta").to_pylist()
    assert json.loads(meta[0]) == {"label": "air_leak", "seed": "7"} and meta[1:] == [None] * 49
    back = list(archive.read_releases(path))
    want = sorted(releases, key=lambda r: (r.locomotive, r.release))
    for got, r in zip(back, want):
        assert (got.locomotive, got.release, got.label, got.split, got.meta) == (
            r.locomotive, r.release, r.label, r.split, r.meta,
        )
        np.testing.assert_array_equal(got.t_s, r.t_s)
        np.testing.assert_array_equal(got.adc, r.adc)
        assert got.adc.dtype == np.uint16
    # Streaming a subset reads just those row groups.
    assert [r.release for r in archive.read_releases(path, [2])] == ["traces/b.csv"]


def test_writer_refuses_what_the_format_forbids(tmp_path):
    path = str(tmp_path / "bad.parquet")
    with pytest.raises(ValueError, match="out of order or repeated"):
        archive.write_archive(path, [_release("l", "r", 5, 1), _release("l", "r", 5, 2)])
    with pytest.raises(ValueError, match="at least one sample"):
        archive.write_archive(path, [_release("l", "r", 0, 1)])
    bad = _release("l", "r", 5, 1)
    bad.adc = np.array([0, 1, 4096, 3, 4])
    with pytest.raises(ValueError, match="outside 0..=4095"):
        archive.write_archive(path, [bad])
    nan = _release("l", "r", 5, 1)
    nan.t_s = np.array([0.0, 0.01, np.nan, 0.03, 0.04])
    with pytest.raises(ValueError, match="non-finite"):
        archive.write_archive(path, [nan])


def test_reader_refuses_a_parquet_file_that_is_no_archive(tmp_path):
    import pyarrow as pa

    other = str(tmp_path / "other.parquet")
    pq.write_table(pa.table({"x": [1, 2]}), other)
    with pytest.raises(archive.ArchiveError, match="pbm.archive.version"):
        list(archive.read_releases(other))
    text = tmp_path / "text.parquet"
    text.write_text("not parquet")
    with pytest.raises(archive.ArchiveError, match="not a Parquet file"):
        archive.index(str(text))
    with pytest.raises(FileNotFoundError):
        archive.index(str(tmp_path / "missing.parquet"))


@pytest.fixture(scope="module")
def small_archive(tmp_path_factory):
    """The small data set (19 releases, several locomotives) as an archive."""
    path = str(tmp_path_factory.mktemp("fleet") / "small.parquet")
    n = archive.write_archive(path, archive.releases_from_dataset(str(DATA / "small")))
    assert n == 18
    return path


def test_archive_of_a_data_set_replays_as_its_traces(small_archive):
    r = next(archive.read_releases(small_archive))
    trace = pbm.read_trace(str(DATA / "small" / r.release))
    np.testing.assert_array_equal(r.adc, trace["adc"])
    np.testing.assert_array_equal(r.t_s, trace["t_s"])
    assert r.meta == trace["meta"]
    assert pbm.replay(r.adc, r.t_s, locomotive=r.locomotive)["can_log"] == pbm.replay_file(
        str(DATA / "small" / r.release)
    )["can_log"]


def test_dask_local_cluster_of_2_workers_equals_the_single_process_run(small_archive, tmp_path):
    local = fleet_dask.run_local(small_archive)
    distributed = fleet_dask.run(small_archive, workers=2)
    assert len(local) == 18
    assert distributed == local
    # The k-th release of a locomotive carries release counter k (frames differ by identity).
    assert len({row["can_log"] for row in local}) == 18
    assert {row["label"] for row in local} >= {"normal", "air_leak"}
    # The command line writes the rows and checks them against the single-process run.
    out = str(tmp_path / "results.parquet")
    assert fleet_dask.main([small_archive, "--workers", "2", "--out", out, "--check"]) == 0
    table = pq.read_table(out)
    assert table.column_names == fleet_dask.RESULT_COLUMNS
    assert table.to_pylist() == local


def test_dask_audit_per_locomotive_equals_the_audit_of_its_data_set(tmp_path):
    """Each locomotive's releases, audited on a 2-worker cluster, give the audit `pbm.audit`
    (= `host-sim audit`, tested in test_tools) gives on a data set directory of those traces."""
    srcs = ["traces/train/normal_0000.csv", "traces/train/normal_0001.csv"]
    releases, d = [], tmp_path / "set"
    d.mkdir()
    manifest = "file,label,locomotive,split\n"
    for loco in ["loco-01", "loco-09"]:
        for src in srcs:
            t = pbm.read_trace(str(DATA / "small" / src))
            releases.append(archive.Release(loco, src, t["t_s"], t["adc"], "normal", "train", t["meta"]))
    for k, src in enumerate(srcs):
        (d / f"n{k}.csv").write_text((DATA / "small" / src).read_text())
        manifest += f"n{k}.csv,normal,loco-01,train\n"
    (d / "manifest.csv").write_text(manifest)
    path = str(tmp_path / "audit.parquet")
    archive.write_archive(path, releases)
    rows = fleet_dask.audit_run(path, workers=2, pairs=False)
    assert [r["locomotive"] for r in rows] == ["loco-01", "loco-09"]
    # The single-process audit of the same releases (one locomotive's data set directory).
    direct = pbm.audit(str(d), pairs=False)
    assert rows[0]["verdict_text"] == direct["verdict_text"]
    assert json.loads(rows[0]["json"]) == {k: v for k, v in direct.items() if k not in ("verdict_text", "skipped")}
    assert rows[0]["json"] == rows[1]["json"]
