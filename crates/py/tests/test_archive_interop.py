"""The Python archive module and `host-sim archive` (the Rust side) read each other's files.

Needs the `host-sim archive pack|unpack` commands of the fleet-archive work (issue 21 item 2)."""

from __future__ import annotations

import numpy as np

import pbm
from pbm import archive
from conftest import DATA, run


def test_host_sim_pack_reads_as_the_python_archive(host_sim, tmp_path):
    rust = tmp_path / "rust.parquet"
    run(host_sim, "archive", "pack", "--out", rust, DATA / "small")
    python = str(tmp_path / "python.parquet")
    archive.write_archive(python, archive.releases_from_dataset(str(DATA / "small")))
    a, b = list(archive.read_releases(str(rust))), list(archive.read_releases(python))
    assert len(a) == len(b) == 18
    for x, y in zip(a, b):
        assert (x.locomotive, x.release, x.label, x.split) == (y.locomotive, y.release, y.label, y.split)
        assert list(x.meta.items()) == list(y.meta.items())
        np.testing.assert_array_equal(x.adc, y.adc)
        np.testing.assert_array_equal(x.t_s, y.t_s)


def test_host_sim_unpacks_a_python_archive_into_the_original_traces(host_sim, tmp_path):
    python = str(tmp_path / "python.parquet")
    archive.write_archive(python, archive.releases_from_dataset(str(DATA / "small")))
    out = tmp_path / "unpacked"
    run(host_sim, "archive", "unpack", "--out", out, python)
    assert (out / "manifest.csv").read_text().count("\n") == 19
    for r in archive.read_releases(python):
        back = pbm.read_trace(str(out / r.release))
        original = pbm.read_trace(str(DATA / "small" / r.release))
        np.testing.assert_array_equal(back["adc"], original["adc"])
        np.testing.assert_array_equal(back["t_s"], original["t_s"])
        assert back["meta"] == original["meta"]
