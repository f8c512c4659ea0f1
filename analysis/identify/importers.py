"""Import force records that labs already have: Kistler DynoWare exports and plain CSV.

DynoWare's ASCII export (.txt or .csv) is a header block of ``key<sep>value`` lines (measurement
name, date, sampling rate, number of samples, comments...) followed by a column-name row
(``Time``/``Zeit`` and channel names such as ``Fx``), often a units row (``s N N N`` or
``[s] [N] ...``), then the samples. Exports made on German, French... Windows use a decimal comma
with tab or semicolon separators. A plain CSV is the same without the header block (a ``time_s``
column optional; the rate then comes from ``--rate`` or a ``rate_hz`` header line).

The parser (:func:`analysis.runs.read_force_table`) looks for the column-name row, detects the
separator and the decimal mark, reads the sampling rate from the header (or from the time
column), the force unit from the units row or ``Fx [N]`` style names; ``import_run`` maps the
channels to the dynamometer's X, Y, Z with the axis and sign of each channel in the rig config
(``Dynamometer.channels``: name, axis, sign). Header lines
naming cutting conditions (``spindle_rpm``, ``fz_mm``, ``depth_mm``, ``width_mm``, ...) become the
run's conditions. Force units are converted to N (kN, lbf) and recorded, so a set of runs
mixing units is reported rather than fitted.

``read_force_table(path) -> ForceTable`` (columns as found) and ``import_run(path, ...) ->
ForceRun`` (ready for ``analysis.identify_*``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from analysis.config import Dynamometer
from analysis.errors import AnalysisError
from analysis.identify._common import ForceRun, RunConditions
from analysis.runs import FORCE_UNIT_TO_N, ForceTable, read_force_table

__all__ = ["ForceTable", "import_run", "merge_conditions", "read_force_table"]

_CONDITION_KEYS = (
    "spindle_rpm", "fz_mm", "depth_mm", "width_mm", "tool", "material", "center_offset_mm",
    "mode", "feed_angle_deg", "feed_mm_min", "teeth", "flutes", "units",
)  # fmt: skip


def _channel_map(table: ForceTable, dyno: Dynamometer | None) -> list[tuple[int, int, float]]:
    """(column, axis index, sign) for X, Y, Z from the config's channels or default names."""
    cols = {n.strip().lower(): k for k, n in enumerate(table.columns)}
    out = []
    if dyno is not None:
        for ch in dyno.channels:
            k = cols.get(ch.name.lower())
            if k is not None:
                out.append((k, "xyz".index(ch.axis), float(ch.sign)))
    if not out:
        for ax, cands in enumerate((("fx", "fx_n", "x"), ("fy", "fy_n", "y"), ("fz", "fz_n", "z"))):
            for c in cands:
                if c in cols:
                    out.append((cols[c], ax, 1.0))
                    break
    axes = sorted(a for _, a, _ in out)
    if axes != [0, 1, 2]:
        names = ", ".join(table.columns)
        want = ", ".join(c.name for c in dyno.channels) if dyno is not None else "Fx, Fy, Fz"
        raise AnalysisError(
            f"{table.path}: cannot find the X, Y and Z force channels among the columns "
            f"({names}); expected {want} (set the names in the rig config's dynamometer channels)"
        )
    return out


def merge_conditions(recorded: Mapping[str, Any], given: Mapping[str, Any]) -> dict[str, Any]:
    """A run's recorded conditions overridden key by key by ``given``; a given feed replaces the
    recorded one in whichever form each gives it (``fz_mm`` or ``feed_mm_min``)."""
    out = dict(recorded)
    if "fz_mm" in given:
        out.pop("feed_mm_min", None)
    if "feed_mm_min" in given:
        out.pop("fz_mm", None)
    out.update(given)
    return out


def import_run(
    path: str | Path,
    conditions: RunConditions | Mapping[str, Any] | None = None,
    dynamometer: Dynamometer | None = None,
    rate_hz: float | None = None,
) -> ForceRun:
    """A force run (N, dynamometer X, Y, Z) from a DynoWare export or plain CSV.

    ``conditions``: a mapping overrides the conditions in the file's header key by key (the
    header's ``fz_mm`` stays unless the mapping gives one); a :class:`RunConditions` replaces
    them. A condition in neither is an error naming the file and the key. ``rate_hz`` is needed
    when neither the header nor a time column gives the rate.
    """
    t = read_force_table(path)
    rate = rate_hz if rate_hz is not None else t.rate_hz
    if rate is None or not math.isfinite(rate) or rate <= 0:
        raise AnalysisError(
            f"{t.path}: no sampling rate (no rate in the header and no time column); give rate_hz"
        )
    force = np.zeros((len(t.data), 3))
    units_seen = set()
    for k, ax, sign in _channel_map(t, dynamometer):
        unit = (t.units[k] or "N").strip()
        factor = FORCE_UNIT_TO_N.get(unit.lower())
        if factor is None:
            raise AnalysisError(
                f"{t.path}: column {t.columns[k]} in {unit!r}: expected N, kN or lbf"
            )
        units_seen.add(unit)
        force[:, ax] = sign * factor * t.data[:, k]
    if len(units_seen) > 1:
        raise AnalysisError(
            f"{t.path}: force channels in mixed units ({', '.join(sorted(units_seen))}); "
            "export all channels in N"
        )
    if not isinstance(conditions, RunConditions):
        # Header numbers follow the file's locale too ("0,236").
        cond_map: dict[str, Any] = {
            k: (v.replace(",", ".") if re.fullmatch(r"[+-]?\d+,\d+", v) else v)
            for k, v in t.header.items()
            if k in _CONDITION_KEYS
        }
        given = dict(conditions or {})
        cond_map = merge_conditions(cond_map, given)
        where = f"{t.path} (header" + (" and the given conditions)" if given else ")")
        conditions = RunConditions.from_mapping(cond_map, where)
    return ForceRun(t.path.stem, force, float(rate), conditions, "N")
