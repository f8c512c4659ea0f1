"""Import force records that labs already have: Kistler DynoWare exports and plain CSV.

DynoWare's ASCII export (.txt or .csv) is a header block of ``key<sep>value`` lines (measurement
name, date, sampling rate, comments...; ``key: value``, ``key:,value``, ``key:<tab>value``,
``key;value``) followed by a column-name row (``Time``/``Zeit`` and channel names such as ``Fx``,
``Fx [N]``, ``Kraft X``, ``Channel 1``), often a units row, then the samples; decimal commas with
tab or semicolon separators are understood. A plain CSV is the same without the header block.

:func:`load_export` turns one into a force run in cutlab's frame:

- columns: ``axes`` (``x=-Fy,y=Fx,z=-Fz``, :mod:`analysis.identify.axes`), else the rig config's
  dynamometer (``axes`` or its channels' name, axis and sign), else columns named like Fx, Fy, Fz;
  force units converted to N (kN, lbf);
- offsets: a zero file (the same channels recorded at rest), ``offset <column>`` header lines, or
  ``zeroed``; otherwise from the air revolutions before/after the cut, and a record with no air
  (the operator kept only the steady cut) is taken as zeroed (the amplifier reset before the
  cut), which the result says;
- conditions: the header's condition lines, then the given layers (a conditions-table row, a
  file-name pattern, KEY=VALUE pairs; :mod:`analysis.identify.conditions`).

``import_run(path, ...) -> ForceRun`` is the same without the notes.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict, Unpack

import numpy as np

from analysis.config import Dynamometer
from analysis.errors import AnalysisError
from analysis.identify._common import ForceRun, RunConditions
from analysis.identify.axes import AxisMap, column_key, parse_axes
from analysis.identify.conditions import (
    Conditions,
    merge_conditions,
    normalize,
    resolve_conditions,
)
from analysis.runs import (
    FORCE_UNIT_TO_N,
    ForceTable,
    NoSteadyCutError,
    find_steady,
    read_force_table,
)
from analysis.runs.steady import NoAirError

__all__ = ["Export", "ForceTable", "import_run", "load_export", "merge_conditions",
           "read_force_table"]  # fmt: skip

Layers = Sequence[tuple[str, Mapping[str, object]]]

#: The zero of a record with no air and no other zero given.
NO_AIR_ZEROED = "no air in the record: taken as zeroed (charge amplifier reset before the cut)"


@dataclass(frozen=True)
class Export:
    """An imported export: the run (N, cutlab x, y, z), the mapping used (``axes``), where the
    offset comes from (``zero``), the file's header and path."""

    run: ForceRun
    axes: str
    zero: str
    header: dict[str, str]
    source: Path
    #: the conditions as the header, table, pattern and given pairs stated them (merged, cutlab's
    #: keys): what a catalogue keeps beside the fitted form (feed_mm_min, teeth, mode)
    stated: Conditions = field(default_factory=dict)


def _axes_for(t: ForceTable, axes: AxisMap | str | None, dyno: Dynamometer | None) -> AxisMap:
    if isinstance(axes, str):
        axes = parse_axes(axes)
    m = axes or AxisMap.default(t.columns, dyno)
    if m is None:
        want = ", ".join(c.name for c in dyno.channels) if dyno is not None else "Fx, Fy, Fz"
        raise AnalysisError(
            f"{t.path}: cannot find the X, Y and Z force channels among the columns "
            f"({', '.join(t.columns)}); expected {want}, or give --axes x=COLUMN,y=COLUMN,"
            "z=COLUMN (a '-' before a column flips its sign)"
        )
    return m


def _forces(t: ForceTable, m: AxisMap) -> np.ndarray:
    """(n, 3) N in cutlab's x, y, z."""
    force = np.zeros((len(t.data), 3))
    units_seen = set()
    for ax, (k, sign) in enumerate(m.columns(t.columns, str(t.path))):
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
    return force


_OFFSET_KEY = re.compile(r"^(?:offset|zero)[\s_]*(?:of[\s_]+)?(?P<col>.+)$")


def _header_offsets(t: ForceTable, m: AxisMap) -> np.ndarray | None:
    """Offsets (3,) N from ``offset <column>: value`` header lines, if all three are there."""
    found: dict[str, float] = {}
    for k, v in t.header.items():
        mm = _OFFSET_KEY.match(k)
        if not mm:
            continue
        num = re.match(r"^\s*([+-]?\d+(?:[.,]\d+)?(?:[eE][+-]?\d+)?)", v)
        if not num:
            raise AnalysisError(f"{t.path}: header {k} = {v!r}: expected an offset in N")
        found[column_key(mm.group("col"))] = float(num.group(1).replace(",", "."))
    keys = [column_key(s) for s in m.sources]
    if not found or not all(k in found for k in keys):
        return None
    return np.array([s * found[k] for k, s in zip(keys, m.signs)])


def _zero_source(force: np.ndarray, rate_hz: float, rpm: float) -> str:
    """'air' when the record has air revolutions to take the offset from, else NO_AIR_ZEROED
    (only a cut); a record without cutting is left to the reduction to refuse."""
    try:
        part = find_steady(force, rate_hz, rpm, refine=False)
    except NoAirError:
        return NO_AIR_ZEROED
    except NoSteadyCutError:
        try:
            find_steady(force, rate_hz, rpm, refine=False, offset_n=np.zeros(3))
        except AnalysisError:
            return "air"
        return NO_AIR_ZEROED
    except AnalysisError:
        return "air"
    return "air" if part.air_revs > 0 else NO_AIR_ZEROED


def load_export(
    path: str | Path,
    conditions: RunConditions | Mapping[str, object] | None = None,
    dynamometer: Dynamometer | None = None,
    rate_hz: float | None = None,
    *,
    axes: AxisMap | str | None = None,
    layers: Layers = (),
    zero_file: str | Path | None = None,
    zeroed: bool = False,
    teeth_of: Callable[[str], int] | None = None,
    expected_tool: str | None = None,
) -> Export:
    """An export as a force run with its notes (see the module docstring).

    ``conditions``: a mapping overrides the header's conditions key by key after ``layers``
    [(where, conditions)] (a table row, a file-name pattern); a :class:`RunConditions` replaces
    them all. A condition in none is an error naming the file and the key. ``teeth_of(tool)``
    checks a ``teeth`` against the tool and fills it in for ``feed_mm_min``. ``rate_hz`` is
    needed when neither the header nor a time column gives the rate.
    """
    t = read_force_table(path)
    rate = rate_hz if rate_hz is not None else t.rate_hz
    if rate is None or not math.isfinite(rate) or rate <= 0:
        raise AnalysisError(
            f"{t.path}: no sampling rate (no rate in the header and no time column); give "
            "--rate HZ"
        )
    m = _axes_for(t, axes, dynamometer)
    force = _forces(t, m)
    stated: Conditions = {}
    if isinstance(conditions, RunConditions):
        cond = conditions
    else:
        given = dict(conditions or {})
        head = normalize(t.header, f"{t.path} (header)", "suffix")
        all_layers = [(f"{t.path} (header)", head), *layers,
                      (f"{t.path} (given conditions)", given)]  # fmt: skip
        cond = resolve_conditions(all_layers, teeth_of, expected_tool)
        for where, raw in all_layers:
            if raw:
                stated = merge_conditions(stated, normalize(raw, where))
    if zeroed:
        zero = "--zeroed: taken as zeroed"
    elif zero_file is not None:
        z = read_force_table(zero_file)
        offset = _forces(z, _axes_for(z, m, dynamometer)).mean(axis=0)
        force -= offset
        zero = f"zero file {Path(zero_file).name} ({', '.join(f'{v:.4g}' for v in offset)} N)"
    elif (offset := _header_offsets(t, m)) is not None:
        force -= offset
        zero = f"header offsets ({', '.join(f'{v:.4g}' for v in offset)} N)"
    else:
        zero = _zero_source(force, float(rate), cond.spindle_rpm)
    run = ForceRun(t.path.stem, force, float(rate), cond, "N")
    return Export(run, m.text, zero, dict(t.header), t.path, stated)


class ExportOptions(TypedDict, total=False):
    """The keyword options of :func:`load_export` that :func:`import_run` passes on."""

    axes: AxisMap | str | None
    layers: Layers
    zero_file: str | Path | None
    zeroed: bool
    teeth_of: Callable[[str], int] | None
    expected_tool: str | None


def import_run(
    path: str | Path,
    conditions: RunConditions | Mapping[str, object] | None = None,
    dynamometer: Dynamometer | None = None,
    rate_hz: float | None = None,
    **options: Unpack[ExportOptions],
) -> ForceRun:
    """The force run of :func:`load_export` (N, cutlab x, y, z)."""
    return load_export(path, conditions, dynamometer, rate_hz, **options).run
