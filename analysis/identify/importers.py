"""Import force records that labs already have: Kistler DynoWare exports and plain CSV.

DynoWare's ASCII export (.txt or .csv) is a header block of ``key<sep>value`` lines (measurement
name, date, sampling rate, number of samples, comments...) followed by a column-name row
(``Time``/``Zeit`` and channel names such as ``Fx``), often a units row (``s N N N`` or
``[s] [N] ...``), then the samples. Exports made on German, French... Windows use a decimal comma
with tab or semicolon separators. A plain CSV is the same without the header block (a ``time_s``
column optional; the rate then comes from ``--rate`` or a ``rate_hz`` header line).

The parser looks for the column-name row, detects the separator and the decimal mark, reads the
sampling rate from the header (or from the time column), the force unit from the units row or
``Fx [N]`` style names, and maps the channels to the dynamometer's X, Y, Z with the axis and sign
of each channel in the rig config (``Dynamometer.channels``: name, axis, sign). Header lines
naming cutting conditions (``spindle_rpm``, ``fz_mm``, ``depth_mm``, ``width_mm``, ...) become the
run's conditions. Force units are converted to N (kN, lbf) and recorded, so a set of runs
mixing units is reported rather than fitted.

``read_force_table(path) -> ForceTable`` (columns as found) and ``import_run(path, ...) ->
ForceRun`` (ready for ``analysis.identify_*``).
"""

from __future__ import annotations

import io
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.config import Dynamometer
from analysis.errors import AnalysisError
from analysis.identify._common import ForceRun, RunConditions

__all__ = ["ForceTable", "import_run", "merge_conditions", "read_force_table"]

_TIME_NAMES = ("time", "zeit", "t", "time_s", "temps", "tiempo", "tempo")
_UNIT_TO_N = {"n": 1.0, "kn": 1000.0, "lbf": 4.4482216152605, "mn": 1e-3}
_RATE_KEYS = ("sampling rate", "sample rate", "samplingrate", "abtastrate", "abtastfrequenz",
              "rate", "rate_hz", "sampling frequency", "frequency")  # fmt: skip
_CONDITION_KEYS = (
    "spindle_rpm", "fz_mm", "depth_mm", "width_mm", "tool", "material", "center_offset_mm",
    "mode", "feed_angle_deg", "feed_mm_min", "teeth", "flutes", "units",
)  # fmt: skip


@dataclass(frozen=True)
class ForceTable:
    """A parsed file: ``data`` (n, c) float, ``columns`` names, ``units`` per column (as found,
    '' if none), ``rate_hz`` (NaN if unknown), ``header`` key -> value text, ``decimal`` ('.'
    or ','), ``separator``."""

    path: Path
    data: np.ndarray
    columns: tuple[str, ...]
    units: tuple[str, ...]
    rate_hz: float
    header: dict[str, str] = field(default_factory=dict)
    decimal: str = "."
    separator: str = ","


def _read_text(p: Path) -> str:
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise AnalysisError(f"{p}: file not found") from None
    except OSError as exc:
        raise AnalysisError(f"{p}: cannot read: {exc}") from None
    for enc in ("utf-8-sig", "cp1252", "latin-1"):
        try:
            return raw.decode(enc)
        except UnicodeDecodeError:
            continue
    raise AnalysisError(f"{p}: not a text file")  # pragma: no cover - latin-1 decodes anything


_NUM = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?$")


def _split(line: str, sep: str) -> list[str]:
    if sep == " ":
        return line.split()
    return [c.strip().strip('"') for c in line.split(sep)]


def _is_numeric_row(cells: list[str]) -> bool:
    cells = [c for c in cells if c != ""]
    return bool(cells) and all(_NUM.match(c) for c in cells)


def _detect(lines: list[str]) -> tuple[int, str]:
    """Index of the column-name row and the separator: the last non-numeric row before the first
    run of >= 3 numeric rows with the same cell count (a units row may sit in between)."""
    for sep in ("\t", ";", ",", " "):
        for i in range(len(lines) - 3):
            cells = _split(lines[i], sep)
            if len(cells) < 2 or not _is_numeric_row(cells):
                continue
            nxt = [_split(x, sep) for x in lines[i : i + 3]]
            if not all(len(c) == len(cells) and _is_numeric_row(c) for c in nxt):
                continue
            # i is the first data row; the name row is above it (skip a units row).
            j = i - 1
            while j >= 0 and not lines[j].strip():
                j -= 1
            if j < 0:
                break
            if _looks_like_units(_split(lines[j], sep)) and j >= 1:
                return j - 1, sep
            return j, sep
    raise AnalysisError("no table of numbers with a column-name row found")


def _looks_like_units(cells: list[str]) -> bool:
    u = [c.strip("[]() ").lower() for c in cells if c.strip()]
    return bool(u) and all(x in _UNIT_TO_N or x in ("s", "ms", "sec", "v", "hz") for x in u)


def _unit_of(name: str) -> tuple[str, str]:
    m = re.match(r"^(.*?)\s*[\[(]\s*([^\])]+)\s*[\])]\s*$", name)
    if m:
        return m.group(1).strip(), m.group(2).strip()
    return name.strip(), ""


def read_force_table(path: str | Path) -> ForceTable:
    """Parse a DynoWare export or a plain CSV (see module docstring)."""
    p = Path(path)
    text = _read_text(p)
    lines = text.splitlines()
    try:
        hdr_i, sep = _detect(lines)
    except AnalysisError as exc:
        raise AnalysisError(f"{p}: {exc}") from None
    names_units = [_unit_of(c) for c in _split(lines[hdr_i], sep)]
    names = [n for n, _ in names_units]
    units = [u for _, u in names_units]
    data_start = hdr_i + 1
    unit_row = _split(lines[data_start], sep)
    if _looks_like_units(unit_row):
        units = [u.strip("[]() ") if u.strip() else units[k] for k, u in enumerate(unit_row)]
        data_start += 1
    # Decimal mark: a comma inside numbers when the separator is not a comma.
    sample = " ".join(lines[data_start : data_start + 50])
    decimal = "," if sep != "," and re.search(r"\d,\d", sample) else "."
    body = "\n".join(ln for ln in lines[data_start:] if ln.strip())
    try:
        df = pd.read_csv(
            io.StringIO(body), sep=r"\s+" if sep == " " else sep, header=None,
            decimal=decimal, engine="python" if sep == " " else "c",
        )  # fmt: skip
    except (ValueError, pd.errors.ParserError) as exc:
        raise AnalysisError(f"{p}: cannot read the samples: {exc}") from None
    if df.shape[1] != len(names):
        raise AnalysisError(
            f"{p}:{hdr_i + 1}: {len(names)} column names but {df.shape[1]} data columns"
        )
    bad = df.apply(pd.to_numeric, errors="coerce").isna().to_numpy()
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise AnalysisError(
            f"{p}:{data_start + r + 1}: column {names[c]} = {df.iat[r, c]!r}: not a number"
        )
    header: dict[str, str] = {}
    for ln in lines[:hdr_i]:
        m = re.match(r"^\s*#?\s*([^:=\t;]+?)\s*[:=\t;]\s*(.*?)\s*$", ln)
        if m and m.group(1):
            header[m.group(1).strip().lower()] = m.group(2).strip().strip('"').rstrip(";\t ")
    data = df.to_numpy(float)
    rate = math.nan
    for k in _RATE_KEYS:
        if k in header:
            num = re.match(r"^\s*([0-9]+(?:[.,][0-9]+)?)\s*(k?hz)?", header[k], re.I)
            if num:
                rate = float(num.group(1).replace(",", "."))
                if num.group(2) and num.group(2).lower() == "khz":
                    rate *= 1000
                break
    t_col = _time_column(names)
    if t_col is not None and len(data) > 2:
        dt = np.diff(data[:, t_col])
        scale = 1e-3 if units[t_col].lower() == "ms" else 1.0
        if np.any(dt <= 0):
            raise AnalysisError(f"{p}: the time column {names[t_col]} does not increase")
        from_time = 1.0 / (float(np.median(dt)) * scale)
        if math.isnan(rate):
            rate = from_time
        elif abs(from_time - rate) > 0.01 * rate:
            raise AnalysisError(
                f"{p}: header sampling rate {rate:g} Hz disagrees with the time column "
                f"({from_time:g} Hz)"
            )
    return ForceTable(p, data, tuple(names), tuple(units), rate, header, decimal, sep)


def _time_column(names) -> int | None:
    for k, n in enumerate(names):
        if n.strip().lower() in _TIME_NAMES:
            return k
    return None


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
        factor = _UNIT_TO_N.get(unit.lower())
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
