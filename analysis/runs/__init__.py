"""Recorded runs: the HDF5 run file, a follower for a run still being written, the steady part of
a cut, a plot of the forces, a run file's summary, and tables exported by other software
(DynoWare, CSV).

The file layout is a namespace of its own (``from analysis.runs import file as rf``: ``rf.Run``,
``rf.load_run``, the dataset names); the names most callers need are here.
"""

from analysis.runs import file
from analysis.runs.file import (
    LOSS_KINDS,
    SAMPLE_FORMAT_RAW,
    SAMPLE_FORMAT_VOLTS,
    Run,
    RunFileError,
    load_run,
)
from analysis.runs.follow import RunFollower, follow
from analysis.runs.plot import plot_run
from analysis.runs.steady import (
    IDENTIFY_TOLERANCE,
    NoSteadyCutError,
    find_steady,
    per_revolution,
    steady_window,
)
from analysis.runs.summary import run_summary
from analysis.runs.table import FORCE_UNIT_TO_N, ForceTable, read_force_table

__all__ = [
    "FORCE_UNIT_TO_N",
    "ForceTable",
    "IDENTIFY_TOLERANCE",
    "LOSS_KINDS",
    "NoSteadyCutError",
    "Run",
    "RunFileError",
    "RunFollower",
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
