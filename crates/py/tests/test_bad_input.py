"""Bad input raises a clear ValueError / OSError with the Rust message: never a panic
(pyo3's PanicException is no ValueError, so it would fail these tests) and never a hang."""

from __future__ import annotations

import numpy as np
import pytest

import pbm
from conftest import DATA

TRACE = str(DATA / "small" / "traces" / "test" / "normal_0000.csv")


def _adc():
    return pbm.read_trace(TRACE)["adc"]


@pytest.mark.parametrize(
    "adc, message",
    [
        (np.array([410, 411, 412], dtype=np.int32), r"dtype uint16.*int32"),
        (np.array([410.0, 411.0]), r"dtype uint16.*float64"),
        (np.array([410, 411], dtype=">u2"), r"dtype uint16"),
        ([410, 411, 412], r"numpy array"),
        (np.zeros((2, 3), dtype=np.uint16), r"1-D"),
        (np.zeros(0, dtype=np.uint16), r"empty"),
        (np.array([410, 5000, 412], dtype=np.uint16), r"adc\[1\] = 5000 is outside the 12-bit range"),
    ],
)
def test_replay_refuses_bad_adc(adc, message):
    with pytest.raises(ValueError, match=message):
        pbm.replay(adc)


def test_replay_refuses_bad_times():
    adc = _adc()
    t = np.arange(len(adc)) * 0.01
    nan = t.copy()
    nan[5] = np.nan
    with pytest.raises(ValueError, match=r"t_s\[5\] is NaN.*finite"):
        pbm.replay(adc, nan)
    with pytest.raises(ValueError, match=r"t_s has 3 samples, adc has"):
        pbm.replay(adc, t[:3])
    slow = t.copy()
    slow[100:] += 0.05
    with pytest.raises(ValueError, match=r"t_s\[100\]: sample interval .* expected 0.01 s"):
        pbm.replay(adc, slow)
    with pytest.raises(ValueError, match=r"t_s must be .*float64"):
        pbm.replay(adc, t.astype(np.float32))


def test_a_strided_view_is_read_not_refused():
    adc = np.repeat(_adc(), 2)
    assert pbm.replay(adc[::2])["can_log"] == pbm.replay(_adc())["can_log"]


def test_simulate_refuses_bad_parameters():
    with pytest.raises(ValueError, match="invalid parameters"):
        pbm.simulate(orifice_mm=float("nan"))
    with pytest.raises(ValueError, match="invalid parameters"):
        pbm.simulate(supply_bar=-3.0)
    with pytest.raises(ValueError, match=r"duration must be in \(0, 3600\] s"):
        pbm.simulate(duration_s=float("nan"))
    with pytest.raises(ValueError, match=r"duration must be in \(0, 3600\] s"):
        pbm.simulate(duration_s=0.0)
    with pytest.raises(ValueError, match="engine must be"):
        pbm.simulate(engine="quantum")
    with pytest.raises(ValueError, match="not finite"):
        pbm.simulate(mechanisms={"valve_lag": float("nan")})


def test_missing_paths_raise_oserror(tmp_path):
    missing = str(tmp_path / "no_such_trace.csv")
    with pytest.raises(OSError, match="no_such_trace.csv"):
        pbm.read_trace(missing)
    with pytest.raises(OSError, match="no_such_trace.csv"):
        pbm.replay_file(missing)
    with pytest.raises(OSError, match="no such data set directory"):
        pbm.audit(str(tmp_path / "no_set"))
    with pytest.raises(OSError, match="no fleet database"):
        pbm.fleet_status(str(tmp_path / "none.sqlite"))
    with pytest.raises(OSError, match="no such file or directory"):
        pbm.fleet_ingest(str(tmp_path / "db.sqlite"), [missing])
    with pytest.raises(ValueError, match="at least one"):
        pbm.fleet_ingest(str(tmp_path / "db.sqlite"), [])


def test_malformed_trace_names_file_and_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("t_s,adc\n0.00,410\n0.01,banana\n")
    with pytest.raises(ValueError, match=r"bad.csv.*3"):
        pbm.read_trace(str(bad))
    gap = tmp_path / "gap.csv"
    gap.write_text("t_s,adc\n0.00,410\n0.01,410\n0.50,410\n")
    trace = pbm.read_trace(str(gap))
    with pytest.raises(ValueError, match="sample interval"):
        pbm.replay(trace["adc"], trace["t_s"])


def test_decoder_flags_garbage_and_refuses_non_text():
    out = pbm.decode_can(["garbage", "(1.0) can0 123#ZZ"])
    assert out["flagged"] == 2 and out["frames"] == 2
    with pytest.raises(ValueError, match="str or a list of str"):
        pbm.decode_can(42)
    with pytest.raises(ValueError, match="format must be"):
        pbm.decode_can("", format="xml")
