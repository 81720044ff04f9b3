"""Type stubs of the ``pbm`` package (the Rust extension ``pbm._pbm`` and its wrappers)."""

from os import PathLike
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import archive as archive

_Path = Union[str, "PathLike[str]"]

#: Names of the twin's optional mechanisms (keys of ``simulate(mechanisms=...)``).
MECHANISMS: List[str]
#: Largest count of the 12-bit ADC.
ADC_MAX: int
#: The monitor's sample period, s (100 Hz).
SAMPLE_PERIOD_S: float

def replay(
    adc: npt.NDArray[np.uint16],
    t_s: Optional[npt.NDArray[np.float64]] = None,
    locomotive: str = "-",
    earlier_releases: int = 0,
) -> Dict[str, Any]:
    """Replays one release of ADC counts through the monitor pipeline (as ``host-sim replay``).

    Keys: ``diagnosis`` (str, ``"-"`` if none closed), ``verdict`` (DBC label or None),
    ``confidence_pct`` (float or None), ``samples``, ``sensor_faults``, ``nmse_pct``,
    ``max_abs_residual_bar``, ``final_bar``, ``orifice_mm``, ``leak_mm``, ``supply_bar_g``,
    ``plateau_bar_g`` (float or None), float64 arrays ``t_s``, ``measured_bar``, ``twin_bar``,
    ``residual_bar``, ``twin_travel_mm``, ``est_orifice_mm``, ``est_leak_mm``,
    ``est_supply_bar_g``, ``est_plateau_bar_g``, bool array ``sensor_fault``, and ``can_log``
    (list of candump lines, as ``--can-log`` writes them).
    """

def replay_file(path: _Path) -> Dict[str, Any]:
    """Replays a trace file as ``host-sim replay PATH --can-log LOG``; adds ``meta``."""

def simulate(
    orifice_mm: float = ...,
    leak_mm: float = 0.0,
    supply_bar: float = ...,
    duration_s: float = 60.0,
    engine: str = "fixed",
    mechanisms: Optional[Mapping[str, float]] = None,
) -> Dict[str, npt.NDArray[np.float64]]:
    """Simulates one noise-free release at 100 Hz (``host-sim simulate``): ``t_s``, ``p_bar``, ``x_mm``."""

def decode_can(
    log: Union[str, Sequence[str]],
    status: bool = False,
    format: str = "text",
    codec_only: bool = False,
) -> Dict[str, Any]:
    """Decodes a candump log as ``host-sim can decode``: ``lines``, ``summary`` and counts."""

def read_trace(path: _Path) -> Dict[str, Any]:
    """Reads a trace file: ``t_s``, ``adc``, ``p_bar`` arrays, ``kind``, ``meta`` dict."""

def audit(path: _Path, pairs: bool = True) -> Dict[str, Any]:
    """Audits a data set directory (``host-sim audit --json``); adds ``verdict_text``, ``skipped``."""

def fleet_ingest(db: _Path, paths: Sequence[_Path], threads: int = 0) -> Dict[str, Any]:
    """Stores releases in a fleet history database (``host-sim fleet ingest``)."""

def fleet_status(db: _Path) -> List[str]:
    """The lines of ``host-sim fleet status DB``, one per locomotive."""
