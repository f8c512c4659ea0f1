"""Recorded runs: the HDF5 run file, a follower for a run still being written, the steady part of
a cut, a plot of the forces, a run file's summary, and tables exported by other software
(DynoWare, CSV).

The file layout is a namespace of its own (``from analysis.runs import file as rf``: ``rf.Run``,
``rf.load_run``, the dataset names); the names most callers need are here.
"""

from importlib import import_module
from typing import Any

from analysis.runs.steady import (
    IDENTIFY_TOLERANCE,
    NoSteadyCutError,
    find_steady,
    per_revolution,
    steady_window,
)

# Loaded on first use (PEP 562): the run file needs h5py and pandas (~0.3 s), which `cutlab --help`
# and every command that only needs the steady-cut constants should not pay for.
_LAZY = {
    "analysis.runs.file": ("LOSS_KINDS", "SAMPLE_FORMAT_RAW", "SAMPLE_FORMAT_VOLTS", "Run",
                           "RunFileError", "load_run"),
    "analysis.runs.follow": ("RunFollower", "follow"),
    "analysis.runs.plot": ("plot_run",),
    "analysis.runs.summary": ("RunSummary", "run_summary"),
    "analysis.runs.table": ("FORCE_UNIT_TO_N", "ExportSummary", "ForceTable", "read_force_table"),
}  # fmt: skip
_WHERE = {name: module for module, names in _LAZY.items() for name in names}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_WHERE[name]), name)
    globals()[name] = value
    return value


__all__ = [
    "ExportSummary",
    "FORCE_UNIT_TO_N",
    "ForceTable",
    "IDENTIFY_TOLERANCE",
    "LOSS_KINDS",
    "NoSteadyCutError",
    "Run",
    "RunFileError",
    "RunFollower",
    "RunSummary",
    "SAMPLE_FORMAT_RAW",
    "SAMPLE_FORMAT_VOLTS",
    "file",
    "find_steady",
    "follow",
    "load_run",
    "per_revolution",
    "plot_run",
    "read_force_table",
    "run_summary",
    "steady_window",
]
