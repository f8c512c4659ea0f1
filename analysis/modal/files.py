"""An impulse-hammer test from a file: a run file (.h5) or a DynoWare / CSV export with a hammer
channel, analysed into the dynamometer's modes (`cutlab analyze modal`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from analysis.config import load_rig
from analysis.errors import AnalysisError
from analysis.modal.hammer import ImpactRecord, modal_analysis, plot_frf, tooth_passing_warnings
from analysis.runs import load_run, read_force_table

__all__ = ["hammer_file_record", "modal_file"]

_TIME_COLUMNS = ("time", "time_s", "zeit")


def hammer_file_record(
    path: str | Path, hammer: str = "hammer", rate_hz: float | None = None
) -> ImpactRecord:
    """The hammer channel (named ``hammer``, any case) and the other channels but time as
    responses (axis letters x, y, z where a name ends in one); ``rate_hz`` replaces an export's
    rate (a run file's own rate is kept)."""
    path = Path(path)
    if path.suffix.lower() in (".h5", ".hdf5"):
        run = load_run(path)
        data = run.force_n if run.force_n is not None else run.volts
        columns, rate = list(run.channel_names), run.rate_hz
    else:
        t = read_force_table(path)
        data, columns, rate = t.data, list(t.columns), t.rate_hz
        if rate_hz:
            rate = rate_hz
    lower = [c.lower() for c in columns]
    if hammer.lower() not in lower:
        raise AnalysisError(
            f"{path}: no hammer channel {hammer!r} among {columns}; name it with --hammer"
        )
    if not np.isfinite(rate):
        raise AnalysisError(f"{path}: no sampling rate in the file; give --rate HZ")
    h = lower.index(hammer.lower())
    resp = [k for k, c in enumerate(lower) if k != h and c not in _TIME_COLUMNS]
    names = tuple(lower[k][-1] if lower[k] and lower[k][-1] in "xyz" else columns[k] for k in resp)
    return ImpactRecord(data[:, h], data[:, resp], float(rate), names, path.stem)


def modal_file(
    path: str | Path,
    hammer: str = "hammer",
    rate_hz: float | None = None,
    record_s: float = 0.08,
    window_end: float = 0.05,
    spindle_rpm: Sequence[float] | None = None,
    teeth: int = 1,
    rig_path: str | Path | None = None,
    plot_png: str | Path | None = None,
) -> dict[str, Any]:
    """Modes of a hammer-test file as a JSON-able dict: hits used and double, modes per axis,
    skipped channels, the rig config's modes, warnings (the analysis's and, for planned
    ``spindle_rpm`` with ``teeth``, tooth-passing harmonics near a mode) and, with ``plot_png``,
    the FRF plot written."""
    rec = hammer_file_record(path, hammer, rate_hz)
    res = modal_analysis(rec, record_s=record_s, window_end=window_end)
    rig = load_rig(rig_path or None)
    warn = list(res.warnings)
    if spindle_rpm:
        warn += tooth_passing_warnings(res.modes, spindle_rpm, teeth)
    out: dict[str, Any] = {
        "file": str(Path(path)),
        "hits_used": list(res.hits_used),
        "double_hits": list(res.double_hits),
        "modes": [
            {
                "axis": m.channel,
                "frequency_hz": m.frequency_hz,
                "damping_ratio": m.damping_ratio,
                "damping_windowed": m.damping_windowed,
                "half_power_frequency_hz": m.half_power_frequency_hz,
                "half_power_damping": m.half_power_damping,
                "coherence": m.coherence,
            }
            for m in res.modes
        ],
        "skipped": [{"channel": c, "reason": r} for c, r in res.skipped],
        "config_modes": [m.model_dump() for m in rig.dynamometer.modes],
        "warnings": warn,
    }
    if plot_png:
        out["plot"] = str(plot_frf(res, plot_png))
    return out
