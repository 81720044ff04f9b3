"""The locomotive spring parking brake monitor in Python.

The functions are the Rust code of the monitor and of ``host-sim`` (PyO3 extension
``pbm._pbm``): ``replay`` gives bit for bit the verdict, confidence, estimates and CAN frames
of ``host-sim replay --can-log``. Bad input raises ``ValueError`` (``OSError`` for a file that
cannot be read) with the Rust message.

Modules: :mod:`pbm.archive` (fleet archives in Parquet, streamed one release at a time) and
:mod:`pbm.fleet_dask` (replay of a fleet archive on a Dask cluster).
"""

from __future__ import annotations

import json
from typing import Any, Dict

from . import _pbm
from ._pbm import (
    ADC_MAX,
    MECHANISMS,
    SAMPLE_PERIOD_S,
    decode_can,
    fleet_ingest,
    fleet_status,
    read_trace,
    replay,
    simulate,
)

__all__ = [
    "ADC_MAX",
    "MECHANISMS",
    "SAMPLE_PERIOD_S",
    "audit",
    "decode_can",
    "fleet_ingest",
    "fleet_status",
    "read_trace",
    "replay",
    "replay_file",
    "simulate",
]


def replay_file(path: str) -> Dict[str, Any]:
    """Replays a trace file as ``host-sim replay PATH --can-log LOG`` does.

    The trace is read with the CLI's reader (a ``p_bar`` trace goes through the sensor map, no
    noise), and its ``locomotive`` metadata numbers the CAN frames. Returns the dict of
    :func:`replay` plus ``meta`` (the trace's metadata).
    """
    trace = read_trace(path)
    result = replay(trace["adc"], trace["t_s"], locomotive=trace["meta"].get("locomotive", "-"))
    result["meta"] = trace["meta"]
    return result


def audit(path: str, pairs: bool = True) -> Dict[str, Any]:
    """Audits a data set directory as ``host-sim audit PATH --json FILE`` does.

    Returns the ``--json`` document as a dict (``cause``, ``magnitude``, ``causes``, NMSEs,
    ``warnings``, …) plus ``verdict_text`` (the verdict in one sentence) and ``skipped`` (traces
    refused while loading, with file and line). ``pairs=False`` does not try pairs of
    mechanisms. Takes tens of seconds on 2 cores.
    """
    document, verdict_text, skipped = _pbm.audit_json(str(path), pairs)
    result: Dict[str, Any] = json.loads(document)
    result["verdict_text"] = verdict_text
    result["skipped"] = skipped
    return result
