"""`pbm.replay` equals `host-sim replay --can-log --out` bit for bit, on the traces of the
firmware's CAN equality check (so Python = CLI = firmware) and the independent set."""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np
import pytest

import pbm
from conftest import DATA, equality_traces, run


def _fmt(x: float, decimals: int) -> str:
    """A float as the CLI's CSV writes it (empty for NaN / None)."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    return f"{x:.{decimals}f}"


def _traces(tmp: Path):
    extra = sorted((DATA / "independent").glob("clean_*.csv")) + sorted((DATA / "independent").glob("sensor_*.csv"))
    return equality_traces(tmp) + extra


def test_replay_equals_cli_on_the_firmware_equality_traces(host_sim, tmp_path):
    traces = _traces(tmp_path)
    assert len(traces) >= 27
    verdicts = set()
    for n, trace in enumerate(traces):
        out_dir = tmp_path / f"out{n}"
        log = tmp_path / f"{n}.log"
        run(host_sim, "replay", trace, "--can-log", log, "--out", out_dir)
        py = pbm.replay_file(str(trace))
        name = trace.name

        # CAN frames: the candump lines, byte for byte.
        cli_log = log.read_text().splitlines()
        assert py["can_log"] == cli_log, name
        assert any(" can0 " in line for line in cli_log), name

        # Verdict, confidence, final estimates, NMSE: the summary row.
        with open(out_dir / "summary.csv", newline="") as f:
            (summary,) = list(csv.DictReader(f))
        assert py["diagnosis"] == summary["diagnosis"], name
        verdicts.add(py["diagnosis"])
        m = re.fullmatch(r"(\w+) (\d+)%", summary["diagnosis"])
        if m:
            assert py["verdict"] == m.group(1), name
            assert py["confidence_pct"] == float(m.group(2)), name
        else:
            assert py["confidence_pct"] is None, name
        assert str(py["samples"]) == summary["samples"]
        assert str(py["sensor_faults"]) == summary["sensor_faults"]
        assert _fmt(py["nmse_pct"], 3) == summary["nmse_pct"], name
        assert f"{py['max_abs_residual_bar']:.4f}" == summary["max_abs_residual_bar"], name
        assert _fmt(py["final_bar"], 3) == summary["final_bar"], name
        for key in ["orifice_mm", "leak_mm", "supply_bar_g"]:
            assert _fmt(py[key], 3) == summary[f"est_{key}"], (name, key)

        # Every sample: measured, twin, residual, travel, sensor fault, estimates.
        with open(out_dir / name, newline="") as f:
            rows = list(csv.DictReader(f))
        assert len(rows) == py["samples"] == len(py["residual_bar"])
        cols = {
            "t_s": (py["t_s"], 2),
            "measured_bar": (py["measured_bar"], 5),
            "twin_bar": (py["twin_bar"], 5),
            "residual_bar": (py["residual_bar"], 5),
            "twin_travel_mm": (py["twin_travel_mm"], 3),
            "est_orifice_mm": (py["est_orifice_mm"], 4),
            "est_leak_mm": (py["est_leak_mm"], 4),
            "est_supply_bar_g": (py["est_supply_bar_g"], 4),
            "est_plateau_bar_g": (py["est_plateau_bar_g"], 4),
        }
        for col, (values, decimals) in cols.items():
            got = [_fmt(float(v), decimals) for v in values]
            want = [r[col] for r in rows]
            assert got == want, (name, col, next(i for i, (a, b) in enumerate(zip(got, want)) if a != b))
        assert [bool(r["sensor_fault"]) for r in rows] == list(py["sensor_fault"]), name
    # The traces cover classes, sensor faults and unfamiliar releases: many distinct verdicts.
    assert len(verdicts) >= 6, verdicts


def test_replay_of_arrays_needs_no_file():
    trace = pbm.read_trace(str(DATA / "small" / "traces" / "test" / "air_leak_0000.csv"))
    by_file = pbm.replay_file(str(DATA / "small" / "traces" / "test" / "air_leak_0000.csv"))
    # Default times (i × 10 ms) give the same replay as the file's times.
    by_array = pbm.replay(trace["adc"], locomotive=trace["meta"]["locomotive"])
    assert by_array["diagnosis"] == by_file["diagnosis"]
    assert by_array["can_log"] == by_file["can_log"]
    np.testing.assert_array_equal(by_array["residual_bar"], by_file["residual_bar"])
    assert by_array["residual_bar"].dtype == np.float64
    assert by_array["sensor_fault"].dtype == np.bool_
    # Another locomotive number changes the frames (identity in the CRC), not the verdict.
    other = pbm.replay(trace["adc"], locomotive="loco-07")
    assert other["diagnosis"] == by_file["diagnosis"]
    assert other["can_log"] != by_file["can_log"]


@pytest.mark.parametrize("release", [0, 3])
def test_release_counter_is_the_clis_in_a_data_set(host_sim, tmp_path, release):
    """`earlier_releases` numbers the frames as `host-sim replay DIR` numbers a locomotive's k-th
    release: the data set log is the concatenation the CLI writes."""
    trace = DATA / "small" / "traces" / "train" / "normal_0000.csv"
    a = pbm.replay_file(str(trace))
    t = pbm.read_trace(str(trace))
    b = pbm.replay(t["adc"], t["t_s"], locomotive=t["meta"]["locomotive"], earlier_releases=release)
    if release == 0:
        assert a["can_log"] == b["can_log"]
    else:
        assert a["can_log"] != b["can_log"]
        assert a["diagnosis"] == b["diagnosis"]
