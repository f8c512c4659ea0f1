"""A run file or an exported table, whichever a path names: its summary and text (``cutlab data
info``) and its force plot (``cutlab data plot``). A run file is told by its suffix."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from analysis.runs.summary import RunSummary
    from analysis.runs.table import ExportSummary

__all__ = ["file_info_lines", "file_summary", "is_run_file", "plot_file"]


def is_run_file(path: str | Path) -> bool:
    """An HDF5 run file (.h5, .hdf5), not an export."""
    return str(path).lower().endswith((".h5", ".hdf5"))


def file_summary(
    path: str | Path, rate_hz: float | None = None
) -> RunSummary | ExportSummary:
    """A run file's channels, rate, samples, events and status, or an export's columns, units,
    rate (``rate_hz`` for one that does not say it) and header."""
    if not is_run_file(path):
        from analysis.runs.table import table_summary

        return table_summary(path, rate_hz)
    from analysis.runs.summary import run_summary

    return run_summary(path)


def file_info_lines(path: str | Path, summary: Mapping[str, object]) -> list[str]:
    """:func:`file_summary` as text."""
    from analysis.runs.text import export_info_lines, run_info_lines

    return (run_info_lines if is_run_file(path) else export_info_lines)(summary)


def plot_file(
    path: str | Path, out: str | Path, rate_hz: float | None = None,
    start_s: float | None = None, stop_s: float | None = None,
) -> tuple[Path, int]:  # fmt: skip
    """The force traces of a run file (from ``start_s`` to ``stop_s``, s after its first sample)
    or of an export, written to ``out``; the picture and the samples plotted."""
    if is_run_file(path):
        from analysis.runs.file import load_run
        from analysis.runs.plot import plot_run

        run = load_run(path, start_s, stop_s)
        return plot_run(run, out), len(run.time_s)
    from analysis.runs.plot import plot_table
    from analysis.runs.table import read_force_table

    table = read_force_table(path)
    return plot_table(table, out, rate_hz), len(table.data)
