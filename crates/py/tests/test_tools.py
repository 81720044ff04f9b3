"""The twin, the CAN decoder, the audit and the fleet history equal their `host-sim` commands."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import pbm
from conftest import DATA, run


@pytest.mark.parametrize(
    "engine, orifice, leak, supply, duration",
    [("fixed", 1.2, 0.0, 6.0, 60.0), ("fixed", 0.7, 0.9, 5.2, 30.0), ("f64", 1.0, 0.4, 6.5, 20.0)],
)
def test_simulate_equals_cli(host_sim, tmp_path, engine, orifice, leak, supply, duration):
    out = tmp_path / "sim.csv"
    run(
        host_sim, "simulate", "--engine", engine, "--orifice-mm", orifice, "--leak-mm", leak,
        "--supply-bar", supply, "--duration", duration, "--out", out,
    )
    rows = [line.split(",") for line in out.read_text().splitlines() if not line.startswith("#")][1:]
    py = pbm.simulate(orifice_mm=orifice, leak_mm=leak, supply_bar=supply, duration_s=duration, engine=engine)
    assert len(rows) == len(py["t_s"]) == round(duration * 100)
    got = [[f"{t:.2f}", f"{p:.6f}", f"{x:.4f}"] for t, p, x in zip(py["t_s"], py["p_bar"], py["x_mm"])]
    assert got == rows


def test_simulate_mechanisms_change_the_release():
    assert "valve_lag" in pbm.MECHANISMS and len(pbm.MECHANISMS) == 10
    base = pbm.simulate(duration_s=10.0)
    lagged = pbm.simulate(duration_s=10.0, mechanisms={"valve_lag": 0.2})
    assert base["p_bar"].shape == lagged["p_bar"].shape == (1000,)
    assert not np.array_equal(base["p_bar"], lagged["p_bar"])
    with pytest.raises(ValueError, match="unknown mechanism"):
        pbm.simulate(mechanisms={"warp_drive": 1.0})


def _logs(host_sim, tmp_path):
    """candump logs to decode: two replays, the demo log, and a log with damaged lines."""
    logs = []
    for n, trace in enumerate(
        [DATA / "small" / "traces" / "test" / "air_leak_0000.csv", DATA / "sensor_fault" / "normal_frozen.csv"]
    ):
        log = tmp_path / f"replay{n}.log"
        run(host_sim, "replay", trace, "--can-log", log)
        logs.append(log)
    demo = tmp_path / "demo.log"
    run(host_sim, "can", "demo-log", "--out", demo)
    logs.append(demo)
    lines = demo.read_text().splitlines()
    damaged = tmp_path / "damaged.log"
    # A flipped data nibble (CRC), a garbage line and a dropped frame.
    first = lines[3]
    flipped = first[:-1] + ("0" if first[-1] != "0" else "1")
    damaged.write_text("\n".join(lines[:3] + [flipped, "not a candump line"] + lines[5:]) + "\n")
    logs.append(damaged)
    return logs


def test_decode_equals_cli(host_sim, tmp_path):
    flagged_somewhere = False
    for log in _logs(host_sim, tmp_path):
        text = log.read_text()
        for args, kwargs in [([], {}), (["--status"], {"status": True}), (["--format", "csv"], {"format": "csv"})]:
            cli = run(host_sim, "can", "decode", log, *args)
            from_lines = pbm.decode_can(text.splitlines(), **kwargs)
            from_text = pbm.decode_can(text, **kwargs)
            assert from_lines == from_text
            assert from_lines["lines"] == cli.stdout.splitlines(), (log.name, args)
            assert from_lines["summary"] in cli.stderr, (log.name, args)
            flagged_somewhere |= from_lines["flagged"] > 0
        assert from_lines["frames"] == len(text.splitlines())
    assert flagged_somewhere


def _normal_set(tmp_path):
    """Two normal releases of one locomotive (the smallest audit input)."""
    d = tmp_path / "normal"
    d.mkdir()
    manifest = "file,label,locomotive,split\n"
    for k, src in enumerate(["traces/train/normal_0000.csv", "traces/train/normal_0001.csv"]):
        (d / f"n{k}.csv").write_text((DATA / "small" / src).read_text())
        manifest += f"n{k}.csv,normal,loco-01,train\n"
    (d / "manifest.csv").write_text(manifest)
    return d


def test_audit_equals_cli(host_sim, tmp_path):
    d = _normal_set(tmp_path)
    js = tmp_path / "audit.json"
    cli = run(host_sim, "audit", d, "--json", js, "--no-pairs")
    py = pbm.audit(str(d), pairs=False)
    assert py.pop("skipped") == []
    verdict_text = py.pop("verdict_text")
    assert f"verdict: {verdict_text}" in cli.stdout
    assert py == json.loads(js.read_text())


def test_fleet_history_equals_cli(host_sim, tmp_path):
    small = DATA / "small"
    cli_db, py_db = tmp_path / "cli.sqlite", tmp_path / "py.sqlite"
    run(host_sim, "fleet", "ingest", "--db", cli_db, small)
    stored = pbm.fleet_ingest(str(py_db), [str(small)])
    with open(small / "manifest.csv", newline="") as f:
        assert stored["releases"] == stored["new"] == len(list(csv.DictReader(f)))
    assert pbm.fleet_status(str(py_db)) == run(host_sim, "fleet", "status", "--db", cli_db).stdout.splitlines()
    # Ingesting again adds nothing.
    assert pbm.fleet_ingest(str(py_db), [str(small)])["new"] == 0
