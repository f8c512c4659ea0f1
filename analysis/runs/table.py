"""Tables of samples that labs already have: Kistler DynoWare exports and plain CSV.

DynoWare's ASCII export (.txt or .csv) is a header block of ``key<sep>value`` lines (measurement
name, date, sampling rate, number of samples, comments...) followed by a column-name row
(``Time``/``Zeit`` and channel names such as ``Fx``), often a units row (``s N N N`` or
``[s] [N] ...``), then the samples. Exports made on German, French... Windows use a decimal comma
with tab or semicolon separators. A plain CSV is the same without the header block (a ``time_s``
column optional; the rate then comes from a ``rate_hz`` header line or the caller).

``read_force_table(path) -> ForceTable``: the columns as found, with their units, the sampling
rate (header or time column) and the header's ``key: value`` lines (also ``key:,value``,
``key:<tab>value``, ``key;value``). ``table_summary`` is `cutlab data info` on an export
(`cutlab data plot`: ``analysis.runs.plot.plot_table``). Turning the columns into the
dynamometer's X, Y, Z forces is :func:`analysis.identify.import_run`'s job.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict

import numpy as np
import pandas as pd

from analysis.errors import AnalysisError

__all__ = ["FORCE_UNIT_TO_N", "ExportSummary", "ForceTable", "read_force_table", "table_summary"]

_TIME_NAMES = ("time", "zeit", "t", "time_s", "temps", "tiempo", "tempo")
#: Force units (lower case) to N.
FORCE_UNIT_TO_N = {"n": 1.0, "kn": 1000.0, "lbf": 4.4482216152605, "mn": 1e-3}
_RATE_KEYS = ("sampling rate", "sample rate", "samplingrate", "abtastrate", "abtastfrequenz",
              "rate", "rate_hz", "sampling frequency", "frequency")  # fmt: skip


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


#: bytes of an export read as text to find its header block and column names; the samples
#: below are parsed by pandas straight from the file (a 100 MB export is never held as text)
HEAD_BYTES = 1 << 18


def _read_head(p: Path) -> tuple[list[str], str]:
    """The first lines of the file (whole lines, up to :data:`HEAD_BYTES`) and its encoding."""
    try:
        with p.open("rb") as fh:
            raw = fh.read(HEAD_BYTES + 1)
    except FileNotFoundError:
        raise AnalysisError(f"{p}: file not found") from None
    except OSError as exc:
        raise AnalysisError(f"{p}: cannot read: {exc}") from None
    if len(raw) > HEAD_BYTES:
        raw = raw[: raw.rfind(b"\n") + 1]  # whole lines only (and no split character)
    for enc in ("utf-8-sig", "cp1252", "latin-1"):
        try:
            return raw.decode(enc).splitlines(), enc
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
    other = ("s", "ms", "sec", "v", "mv", "hz", "pc", "nm", "n·m", "n*m", "n m")
    return bool(u) and all(x in FORCE_UNIT_TO_N or x in other for x in u)


def _unit_of(name: str) -> tuple[str, str]:
    m = re.match(r"^(.*?)\s*[\[(]\s*([^\])]+)\s*[\])]\s*$", name)
    if m:
        return m.group(1).strip(), m.group(2).strip()
    return name.strip(), ""


def read_force_table(path: str | Path) -> ForceTable:
    """Parse a DynoWare export or a plain CSV (see module docstring)."""
    p = Path(path)
    lines, encoding = _read_head(p)
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
    try:
        df = pd.read_csv(
            p, skiprows=data_start, sep=r"\s+" if sep == " " else sep, header=None,
            decimal=decimal, engine="python" if sep == " " else "c", encoding=encoding,
            skip_blank_lines=True,
        )  # fmt: skip
    except (ValueError, pd.errors.ParserError) as exc:
        raise AnalysisError(f"{p}: cannot read the samples: {exc}") from None
    if df.shape[1] != len(names):
        raise AnalysisError(
            f"{p}:{hdr_i + 1}: {len(names)} column names but {df.shape[1]} data columns"
        )
    numeric = all(pd.api.types.is_numeric_dtype(t) for t in df.dtypes)
    values = df if numeric else df.apply(pd.to_numeric, errors="coerce")
    data = values.to_numpy(float)
    bad = ~np.isfinite(data)  # a NaN or an empty cell, and inf (which pandas reads as a number)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        line, cell = _cell(p, encoding, data_start, int(r), int(c), sep)
        what = "not a finite number" if np.isinf(data[r, c]) else "not a number"
        raise AnalysisError(f"{p}:{line}: column {names[c]} = {cell}: {what}")
    header = _header(lines[:hdr_i])
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


def _cell(p: Path, encoding: str, data_start: int, row: int, col: int, sep: str) -> tuple[int, str]:
    """The line number (1-based) and the text of sample ``row``'s cell ``col`` as written (for a
    message: ``nan``, ``inf``, ``(empty)``; blank lines are skipped as pandas skips them)."""
    with open(p, encoding=encoding, errors="replace") as f:
        seen = -1
        for n, text in enumerate(f, start=1):
            if n <= data_start or not text.strip():
                continue
            seen += 1
            if seen == row:
                cells = _split(text.rstrip("\r\n"), sep)
                cell = cells[col] if col < len(cells) else ""
                return n, _shown(cell)
    return data_start + row + 1, "(empty)"


def _shown(cell: str) -> str:
    """A cell in a message: ``nan``, ``inf`` as written, text quoted, ``(empty)``."""
    if not cell:
        return "(empty)"
    try:
        float(cell.replace(",", "."))
    except ValueError:
        return repr(cell)
    return cell


# ``key: value``, ``key:,value`` (DynoWare CSV), ``key:\tvalue``, ``key;value``, ``key = value``;
# a unit in brackets after the key ("Sampling rate [Hz]") goes after the value.
_HEADER_LINE = re.compile(
    r"^\s*#?\s*(?P<key>[^:=\t;,\[(]+?)\s*(?:[\[(](?P<unit>[^\])]*)[\])])?\s*"
    r"(?::[\s,;]*|[=\t;,]\s*)(?P<value>.*?)\s*$"
)


def _header(lines: list[str]) -> dict[str, str]:
    """The header block's ``key<sep>value`` lines, keys in lower case."""
    header: dict[str, str] = {}
    for ln in lines:
        m = _HEADER_LINE.match(ln)
        if not m or not m.group("key").strip():
            continue
        value = m.group("value").strip().strip('"').rstrip(";,\t ").strip('"').strip()
        if m.group("unit") and value:
            value += f" {m.group('unit').strip()}"
        header[m.group("key").strip().lower()] = value
    return header


def _time_column(names: Sequence[str]) -> int | None:
    for k, n in enumerate(names):
        if n.strip().lower() in _TIME_NAMES:
            return k
    return None


class ExportSummary(TypedDict):
    """`cutlab data info --json` on an export (:func:`table_summary`); None: rate unknown."""

    file: str
    format: str
    columns: list[str]
    units: list[str]
    rate_hz: float | None
    rate_reason: str | None
    samples: int
    duration_s: float | None
    decimal: str
    separator: str
    header: dict[str, str]


def table_summary(path: str | Path, rate_hz: float | None = None) -> ExportSummary:
    """What an export holds (`cutlab data info` on a DynoWare / CSV file): columns and units,
    rate, samples, duration, the header lines, decimal mark and separator."""
    t = read_force_table(path)
    rate = rate_hz if rate_hz is not None else t.rate_hz
    known = math.isfinite(rate) and rate > 0
    return {
        "file": str(t.path),
        "format": "export",
        "columns": list(t.columns),
        "units": list(t.units),
        "rate_hz": rate if known else None,
        "rate_reason": None if known else "no rate in the header and no time column; give --rate",
        "samples": len(t.data),
        "duration_s": len(t.data) / rate if known else None,
        "decimal": t.decimal,
        "separator": {"\t": "tab", " ": "space"}.get(t.separator, t.separator),
        "header": dict(t.header),
    }
