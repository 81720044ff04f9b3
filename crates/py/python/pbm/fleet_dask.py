"""Replay of a fleet archive on Dask: one task per locomotive, the package as the worker code.

Why Dask (and not Ray or Spark): it is a pure ``pip install`` (``dask[distributed]``), needs no
JVM (Spark) and no daemon or object store to run (Ray); a ``LocalCluster`` of worker processes
on one machine and a real cluster (``dask scheduler`` + ``dask worker`` on each node, or
dask-jobqueue / dask-kubernetes) run the same code, selected by a scheduler address.

The archive is partitioned by locomotive: a task reads its locomotive's row groups (one release
each) straight from the archive and replays them in order, so the k-th release of a locomotive
is replayed by a monitor that has seen k releases before it (the CAN frames' release counter,
as ``host-sim replay`` numbers a data set's releases), exactly as the single-process run
:func:`run_local` does. Every worker must be able to open the archive (a shared file system, or
a URI pyarrow opens, e.g. ``s3://…``).

Command line::

    python -m pbm.fleet_dask ARCHIVE --workers 2 [--out results.parquet] [--check]
    python -m pbm.fleet_dask ARCHIVE --scheduler tcp://HOST:8786 [--out results.parquet]
    python -m pbm.fleet_dask ARCHIVE --workers 2 --audit [--no-pairs]   # audit per locomotive
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import OrderedDict
from typing import Any, Dict, List, Optional, Sequence

#: Columns of a result row (one per release), in order.
RESULT_COLUMNS = [
    "locomotive",
    "release",
    "label",
    "split",
    "samples",
    "diagnosis",
    "verdict",
    "confidence_pct",
    "orifice_mm",
    "leak_mm",
    "supply_bar_g",
    "nmse_pct",
    "max_abs_residual_bar",
    "sensor_faults",
    "can_log",
]


def partitions(archive: str) -> "OrderedDict[str, List[int]]":
    """The archive's row groups per locomotive, in archive order (the unit of parallel work)."""
    from .archive import index

    parts: "OrderedDict[str, List[int]]" = OrderedDict()
    for g in index(archive):
        parts.setdefault(g.locomotive, []).append(g.row_group)
    return parts


def replay_locomotive(archive: str, row_groups: Sequence[int]) -> List[Dict[str, Any]]:
    """Replays the releases in ``row_groups`` (one locomotive's, in order) with ``pbm.replay``;
    one result row per release. The worker function of the Dask run."""
    from . import replay
    from .archive import read_releases

    rows = []
    for k, r in enumerate(read_releases(archive, row_groups)):
        out = replay(r.adc, r.t_s, locomotive=r.locomotive, earlier_releases=k % 256)
        rows.append(
            {
                "locomotive": r.locomotive,
                "release": r.release,
                "label": r.label,
                "split": r.split,
                "samples": out["samples"],
                "diagnosis": out["diagnosis"],
                "verdict": out["verdict"],
                "confidence_pct": out["confidence_pct"],
                "orifice_mm": out["orifice_mm"],
                "leak_mm": out["leak_mm"],
                "supply_bar_g": out["supply_bar_g"],
                "nmse_pct": out["nmse_pct"],
                "max_abs_residual_bar": out["max_abs_residual_bar"],
                "sensor_faults": out["sensor_faults"],
                "can_log": "\n".join(out["can_log"]),
            }
        )
    return rows


#: Columns of an audit result row (one per locomotive), in order.
AUDIT_COLUMNS = ["locomotive", "releases", "cause", "explains_all", "verdict_text", "skipped", "json"]


def write_dataset(releases: Sequence[Any], directory: str) -> None:
    """Writes releases as a data set directory (``manifest.csv`` + ADC trace files with their
    metadata), so that the audit reads them exactly as ``host-sim audit`` reads the originals:
    times are written in their shortest round-trip form, so they parse to the same float64."""
    import csv
    import os

    os.makedirs(directory, exist_ok=True)
    with open(os.path.join(directory, "manifest.csv"), "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["file", "label", "locomotive", "split"])
        for k, r in enumerate(releases):
            name = f"release_{k:05d}.csv"
            w.writerow([name, r.label or "-", r.locomotive, r.split or "train"])
            with open(os.path.join(directory, name), "w") as t:
                for key, value in r.meta.items():
                    t.write(f"# {key}: {value}\n")
                t.write("t_s,adc\n")
                t.writelines(f"{float(x)!r},{int(c)}\n" for x, c in zip(r.t_s, r.adc))


def audit_locomotive(archive: str, row_groups: Sequence[int], pairs: bool = True) -> Dict[str, Any]:
    """Audits one locomotive's releases (``row_groups``) as ``host-sim audit`` audits a data set
    of them: which unmodelled mechanism, if any, explains the residual. One result row."""
    import json
    import tempfile

    from . import audit
    from .archive import read_releases

    releases = list(read_releases(archive, row_groups))
    with tempfile.TemporaryDirectory(prefix="pbm-audit-") as d:
        write_dataset(releases, d)
        try:
            out = audit(d, pairs=pairs)
        except ValueError as e:
            # Nothing auditable (e.g. every release a sensor fault): a row that says why.
            return {
                "locomotive": releases[0].locomotive,
                "releases": len(releases),
                "cause": None,
                "explains_all": None,
                "verdict_text": f"not audited: {e}",
                "skipped": "",
                "json": "",
            }
    return {
        "locomotive": releases[0].locomotive,
        "releases": len(releases),
        "cause": out["cause"],
        "explains_all": out["explains_all"],
        "verdict_text": out["verdict_text"],
        "skipped": "\n".join(out["skipped"]),
        "json": json.dumps({k: v for k, v in out.items() if k not in ("verdict_text", "skipped")}, sort_keys=True),
    }


def audit_local(archive: str, pairs: bool = True) -> List[Dict[str, Any]]:
    """The single-process audit: one row per locomotive, in archive order."""
    return [audit_locomotive(archive, groups, pairs) for groups in partitions(archive).values()]


def run_local(archive: str) -> List[Dict[str, Any]]:
    """The single-process run: every locomotive in this process, in archive order."""
    rows: List[Dict[str, Any]] = []
    for groups in partitions(archive).values():
        rows.extend(replay_locomotive(archive, groups))
    return rows


def run(archive: str, workers: int = 2, scheduler: Optional[str] = None) -> List[Dict[str, Any]]:
    """Replays the archive on Dask: on ``scheduler`` (``tcp://host:port``) when given, else on a
    ``LocalCluster`` of ``workers`` processes with one thread each. Rows in archive order."""
    return _run_timed(archive, workers, scheduler)[0]


def audit_run(
    archive: str, workers: int = 2, scheduler: Optional[str] = None, pairs: bool = True
) -> List[Dict[str, Any]]:
    """Audits every locomotive of the archive on Dask (one task each); rows in archive order."""
    return _run_timed(archive, workers, scheduler, audit=True, pairs=pairs)[0]


def _run_timed(
    archive: str, workers: int, scheduler: Optional[str], audit: bool = False, pairs: bool = True
) -> "tuple[List[Dict[str, Any]], float]":
    """:func:`run` (or :func:`audit_run`) and the seconds its tasks took (cluster start-up
    excluded)."""
    from dask.distributed import Client, LocalCluster

    if scheduler is None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    parts = partitions(archive)
    cluster = None
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        # Workers import the package once before the clock starts.
        client.run(lambda: __import__("pbm"))
        start = time.perf_counter()
        if audit:
            futures = [
                client.submit(audit_locomotive, archive, groups, pairs, key=f"audit-{loco}", pure=False)
                for loco, groups in parts.items()
            ]
        else:
            futures = [
                client.submit(replay_locomotive, archive, groups, key=f"replay-{loco}", pure=False)
                for loco, groups in parts.items()
            ]
        results = client.gather(futures)
        elapsed = time.perf_counter() - start
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    if audit:
        return list(results), elapsed
    return [row for rows in results for row in rows], elapsed


def write_results(path: str, rows: List[Dict[str, Any]], columns: Sequence[str] = RESULT_COLUMNS) -> None:
    """Writes result rows as a Parquet file (columns :data:`RESULT_COLUMNS`, or
    :data:`AUDIT_COLUMNS` for audit rows)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist(rows, schema=None)
    pq.write_table(table.select(list(columns)), path)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m pbm.fleet_dask``: replays an archive on Dask and prints the throughput."""
    p = argparse.ArgumentParser(prog="python -m pbm.fleet_dask", description=__doc__.split("\n\n")[0])
    p.add_argument("archive", help="fleet archive (Parquet, one row group per release)")
    p.add_argument("--workers", type=int, default=2, help="local cluster: worker processes (1 thread each)")
    p.add_argument("--scheduler", help="address of a running Dask scheduler, e.g. tcp://10.0.0.1:8786")
    p.add_argument("--out", help="write one result row per release to this Parquet file")
    p.add_argument("--check", action="store_true", help="also run in this process and require equal results")
    p.add_argument("--audit", action="store_true", help="audit each locomotive's releases instead of replaying them")
    p.add_argument("--no-pairs", action="store_true", help="with --audit: do not try pairs of mechanisms")
    a = p.parse_args(argv)
    pairs = not a.no_pairs
    rows, elapsed = _run_timed(a.archive, a.workers, a.scheduler, audit=a.audit, pairs=pairs)
    where = a.scheduler or f"local cluster of {a.workers} workers"
    unit = "locomotives audited" if a.audit else "releases"
    print(f"{len(rows)} {unit} on {where} in {elapsed:.2f} s: {len(rows) / elapsed:.2f} {unit}/s")
    if a.out:
        write_results(a.out, rows, AUDIT_COLUMNS if a.audit else RESULT_COLUMNS)
        print(f"wrote {a.out}")
    if a.check:
        start = time.perf_counter()
        local = audit_local(a.archive, pairs) if a.audit else run_local(a.archive)
        t = time.perf_counter() - start
        if local != rows:
            diff = next(i for i, (x, y) in enumerate(zip(local, rows)) if x != y) if len(local) == len(rows) else -1
            print(f"check FAILED: the Dask results differ from the single-process run (first at row {diff})")
            return 1
        print(f"check: equal to the single-process run ({len(local) / t:.2f} {unit}/s in this process)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
