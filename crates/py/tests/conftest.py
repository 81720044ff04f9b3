"""Shared fixtures: the repository, the `host-sim` binary the package is compared with, and a
small fleet archive."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import List

import pytest

#: The repository root (crates/py/tests → ../../..).
REPO = Path(__file__).resolve().parents[3]
DATA = REPO / "tests" / "data"


def _host_sim() -> Path:
    """`host-sim`: `PBM_HOST_SIM` when set (what `cargo xtask python` passes), else built here
    with cargo (test profile, as CI's other checks build it). Never skipped: a missing binary
    fails the tests."""
    given = os.environ.get("PBM_HOST_SIM")
    if given:
        path = Path(given)
        if not path.is_file():
            raise RuntimeError(f"PBM_HOST_SIM={given} is not a file")
        return path
    subprocess.run(
        ["cargo", "build", "--quiet", "--profile", "test", "-p", "host-sim"], cwd=REPO, check=True
    )
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return target / "debug" / "host-sim"


@pytest.fixture(scope="session")
def host_sim() -> Path:
    """Path of the `host-sim` binary."""
    return _host_sim()


def run(host_sim: Path, *args: object, check: bool = True) -> subprocess.CompletedProcess:
    """Runs host-sim with `args`; output as text."""
    p = subprocess.run([str(host_sim), *map(str, args)], capture_output=True, text=True, timeout=600)
    if check and p.returncode != 0:
        raise AssertionError(f"host-sim {' '.join(map(str, args))} exited {p.returncode}:\n{p.stderr}")
    return p


def equality_traces(tmp: Path) -> List[Path]:
    """The traces of the firmware's CAN equality check (xtask/src/firmware.rs,
    `equality_traces`): the 6 test and 6 `_0000` training traces of the small set, every
    sensor-fault trace, the independent plant's unfamiliar releases, and one release cut at 15 s.
    Python = CLI on these, and CLI = firmware there, so Python = firmware."""
    traces = []
    for cls in ["normal", "air_leak", "orifice_block", "leak_and_block", "low_supply", "orifice_missing"]:
        for split in ["test", "train"]:
            traces.append(DATA / "small" / "traces" / split / f"{cls}_0000.csv")
    traces += sorted((DATA / "sensor_fault").glob("*.csv"))
    traces += sorted((DATA / "independent").glob("unfamiliar_*.csv"))
    source = (DATA / "small" / "traces" / "test" / "orifice_block_0000.csv").read_text().splitlines()
    kept, rows = [], 0
    for line in source:
        if not (line.startswith("#") or line.startswith("t_s")):
            rows += 1
            if rows > 1500:
                break
        kept.append(line)
    cut = tmp / "orifice_block_cut_15s.csv"
    cut.write_text("\n".join(kept) + "\n")
    traces.append(cut)
    for t in traces:
        assert t.is_file(), t
    return traces
