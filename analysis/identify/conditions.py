"""Cutting conditions of each run: from its own header (or run file), a conditions table, a
file-name pattern, and KEY=VALUE pairs, merged key by key in that order.

A conditions table (CSV or TOML) has one row per export, matched by file name with or without
its extension::

    file,spindle_rpm,feed_mm_min,ap_mm,ae_mm,teeth,tool
    cut_0300.txt,6000,300,3,25,2,phi25-flat

``fz_mm`` may replace ``feed_mm_min``; ``ap_mm`` is the axial depth (cutlab's ``depth_mm``),
``ae_mm`` the radial width (``width_mm``); ``teeth``, ``tool``, ``mode``, ``material``... are
optional. TOML: ``[[runs]]`` tables with the same keys. An unknown key, a feed given twice that
disagrees, or ``teeth`` against the tool's flutes is an error naming the file and the field.
"""

from __future__ import annotations

import csv
import io
import math
import re
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from analysis.errors import AnalysisError
from analysis.identify._common import RunConditions

__all__ = [
    "CONDITION_KEYS",
    "ConditionValue",
    "Conditions",
    "ConditionsTable",
    "load_conditions_table",
    "merge_conditions",
    "pattern_conditions",
    "resolve_conditions",
]

#: Condition keys cutlab understands (aliases ap_mm -> depth_mm, ae_mm -> width_mm).
CONDITION_KEYS = (
    "spindle_rpm", "fz_mm", "feed_mm_min", "depth_mm", "width_mm", "teeth", "flutes", "tool",
    "material", "mode", "feed_angle_deg", "center_offset_mm", "units",
)  # fmt: skip
_ALIASES = {"ap_mm": "depth_mm", "ae_mm": "width_mm"}
_NUMERIC = {"spindle_rpm", "fz_mm", "feed_mm_min", "depth_mm", "width_mm", "teeth", "flutes",
            "feed_angle_deg", "center_offset_mm"}  # fmt: skip
# Header keys that look like a condition (a unit suffix) but are not one: refused, not ignored.
_LOOKS_LIKE = re.compile(r"_(mm|rpm|deg|mm_min|mm_rev)$")
# Keys in units cutlab does not use: refused as mixed units rather than converted.
_FOREIGN = re.compile(r"_(in|inch|ipm|ipt|ipr|m|cm|um|sfm|in_min|m_min|ft_min|in_rev|rad)$")


#: A condition's value once normalized: a number (mm, rpm, deg, count) or a name.
ConditionValue = float | str
#: Conditions by cutlab's keys (:data:`CONDITION_KEYS`).
Conditions = dict[str, ConditionValue]


def _value(v: object) -> object:
    """Numbers in text (decimal comma too) become numbers; numpy's (a run file's attributes, a
    table read by pandas) become Python's, so that every message shows ``nan``, not
    ``np.float64(nan)``."""
    if isinstance(v, np.generic):
        return v.item()
    if not isinstance(v, str):
        return v
    s = v.strip()
    if re.fullmatch(r"[+-]?\d+,\d+", s):
        s = s.replace(",", ".")
    try:
        f = float(s)
    except ValueError:
        return s
    return int(f) if re.fullmatch(r"[+-]?\d+", s) else f


def normalize(
    d: Mapping[str, object], where: str, unknown: Literal["error", "suffix", "skip"] = "error"
) -> Conditions:
    """Condition keys of ``d`` with aliases resolved and numbers parsed. Unknown keys are an
    error; with ``unknown="suffix"`` (an export's header block, which holds much else) only keys
    that look like a condition (``*_mm``, ``*_rpm``...) are; ``"skip"`` (a run file's own record,
    which also names the campaign, block, paths...) leaves them out."""
    out: Conditions = {}
    for raw_key, v in d.items():
        key = str(raw_key).strip().lower()
        canon = _ALIASES.get(key, key)
        if canon not in CONDITION_KEYS:
            if _FOREIGN.search(key):
                raise AnalysisError(
                    f"{where}: {raw_key} = {v!r}: cutlab works in mm, mm/min, rpm and deg "
                    "(mixed units); give the _mm, _mm_min, _rpm or _deg key"
                )
            if unknown == "skip" or (unknown == "suffix" and not _LOOKS_LIKE.search(key)):
                continue
            raise AnalysisError(
                f"{where}: unknown condition {raw_key!r} = {v!r}; expected "
                f"{', '.join(CONDITION_KEYS + tuple(_ALIASES))}"
            )
        if v is None or (isinstance(v, str) and not v.strip()):
            continue
        v = v.item() if isinstance(v, np.generic) else v  # messages say nan, not np.float64(nan)
        val = _value(v)
        if canon in _NUMERIC and not isinstance(val, int | float):
            raise AnalysisError(f"{where}: {raw_key} = {v!r}: not a number")
        if not isinstance(val, int | float | str):
            raise AnalysisError(f"{where}: {raw_key} = {v!r}: expected a number or a name")
        if canon in out and out[canon] != val:
            raise AnalysisError(
                f"{where}: {raw_key} = {v!r} contradicts {canon} = {out[canon]!r}"
            )
        out[canon] = val
    return out


def merge_conditions(
    recorded: Mapping[str, ConditionValue], given: Mapping[str, ConditionValue]
) -> Conditions:
    """A run's recorded conditions overridden key by key by ``given``; a given feed replaces the
    recorded one in whichever form each gives it (``fz_mm`` or ``feed_mm_min``)."""
    out = dict(recorded)
    if "fz_mm" in given:
        out.pop("feed_mm_min", None)
    if "feed_mm_min" in given:
        out.pop("fz_mm", None)
    out.update(given)
    return out


@dataclass(frozen=True)
class ConditionsTable:
    """Rows of a conditions table: file key (lower case) -> (where, conditions)."""

    path: Path
    rows: dict[str, tuple[str, Conditions]]

    def row(self, file: str | Path) -> tuple[str, Conditions]:
        """(where, conditions) of the row for ``file`` (by name, or name without extension)."""
        p = Path(str(file))
        for key in (p.name.lower(), p.stem.lower()):
            if key in self.rows:
                return self.rows[key]
        raise AnalysisError(
            f"{self.path}: no row for {p.name} (field file: expected {p.name} or {p.stem}; "
            f"rows: {', '.join(sorted(self.rows)) or 'none'})"
        )


def _table_rows(p: Path) -> list[tuple[str, dict[str, object]]]:
    try:
        text = p.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise AnalysisError(f"{p}: conditions table not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise AnalysisError(f"{p}: cannot read the conditions table: {exc}") from None
    if p.suffix.lower() == ".toml":
        try:
            doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise AnalysisError(f"{p}: not valid TOML: {exc}") from None
        runs = doc.get("runs")
        extra = sorted(set(doc) - {"runs"})
        if not isinstance(runs, list) or extra:
            raise AnalysisError(
                f"{p}: expected [[runs]] tables (file = ..., spindle_rpm = ...)"
                + (f"; unknown key(s) {', '.join(extra)}" if extra else "")
            )
        return [(f"{p}: runs[{k}]", dict(r)) for k, r in enumerate(runs)]
    lines = [ln for ln in text.splitlines()]
    first = next((ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#")), "")
    sep = max((";", "\t", ","), key=first.count)
    reader = csv.reader(io.StringIO(text), delimiter=sep)
    rows, names = list(reader), None
    out: list[tuple[str, dict[str, object]]] = []
    for n, cells in enumerate(rows, start=1):
        cells = [c.strip() for c in cells]
        if not any(cells) or cells[0].startswith("#"):
            continue
        if names is None:
            names = cells
            continue
        if len(cells) != len(names):
            raise AnalysisError(
                f"{p}:{n}: {len(cells)} fields but the header row has {len(names)} "
                f"({', '.join(names)})"
            )
        out.append((f"{p}:{n}", dict(zip(names, cells))))
    if names is None:
        raise AnalysisError(f"{p}: empty conditions table: expected a header row "
                            "file,spindle_rpm,feed_mm_min,ap_mm,ae_mm")  # fmt: skip
    return out


def load_conditions_table(path: str | Path) -> ConditionsTable:
    """Read a conditions table (CSV with ``,`` ``;`` or tab, or TOML ``[[runs]]``)."""
    p = Path(path)
    rows: dict[str, tuple[str, Conditions]] = {}
    for where, raw in _table_rows(p):
        f = str(raw.pop("file", "") or "").strip()
        if not f:
            raise AnalysisError(f"{where}: field file missing or empty (the export's file name)")
        cond = normalize(raw, where)
        key = Path(f).name.lower()
        if key in rows:
            raise AnalysisError(f"{where}: file = {f!r}: a second row for it ({rows[key][0]})")
        rows[key] = (where, cond)
    return ConditionsTable(p, rows)


def pattern_conditions(pattern: str, file: str | Path) -> Conditions:
    """Conditions from a file name: ``cut_{spindle_rpm}rpm_f{feed_mm_min}.txt`` style (fields in
    braces are condition keys; the rest must match literally)."""
    name = Path(str(file)).name
    parts = re.split(r"\{([A-Za-z_]+)\}", pattern)
    rx = ""
    for k, part in enumerate(parts):
        rx += f"(?P<{part}>[-+0-9.,]+|[^_/\\\\]+?)" if k % 2 else re.escape(part)
    try:
        m = re.fullmatch(rx, name) or re.fullmatch(rx, Path(name).stem)
    except re.error:
        raise AnalysisError(f"--conditions-pattern {pattern!r}: a field appears twice") from None
    if not m:
        raise AnalysisError(
            f"{file}: file name does not match --conditions-pattern {pattern!r}"
        )
    return normalize(m.groupdict(), f"{name} (--conditions-pattern)")


def resolve_conditions(
    layers: Sequence[tuple[str, Mapping[str, object]]],
    teeth_of: Callable[[str], int] | None = None,
    expected_tool: str | None = None,
) -> RunConditions:
    """Merge ``layers`` [(where, conditions)] key by key (later ones win, a feed replaces the
    other form of the feed) into RunConditions. ``teeth_of(tool name)`` gives the tool's teeth:
    a ``teeth`` (or ``flutes``) that differs is an error naming where it came from; a
    ``feed_mm_min`` without teeth takes the tool's."""
    merged: Conditions = {}
    origin: dict[str, str] = {}
    for where, raw in layers:
        if not raw:
            continue
        d = normalize(raw, where)
        merged = merge_conditions(merged, d)
        origin.update(dict.fromkeys(d, where))
        if "fz_mm" in d and "feed_mm_min" in d:
            origin["feed_mm_min"] = where
    wheres = list(dict.fromkeys(w for w, d in layers if d))
    # (no layer holds anything: the first still names the file, e.g. "RUN.h5 (conditions)")
    where = " + ".join(wheres) or (layers[0][0] if layers else "<conditions>")
    # The run's own tool first: a run of another tool than expected_tool is refused elsewhere.
    tool = str(merged.get("tool", "") or "") or expected_tool or ""
    tool_teeth = teeth_of(tool) if (teeth_of and tool) else None
    for key in ("teeth", "flutes"):
        if key in merged and tool_teeth is not None and float(merged[key]) != tool_teeth:
            raise AnalysisError(
                f"{origin[key]}: {key} = {merged[key]!r} but tool {tool!r} has {tool_teeth} "
                "teeth (flutes or inserts)"
            )
    if "feed_mm_min" in merged and not ({"teeth", "flutes"} & set(merged)) and tool_teeth:
        merged["teeth"] = tool_teeth
    if {"fz_mm", "feed_mm_min", "spindle_rpm"} <= set(merged) and (
        {"teeth", "flutes"} & set(merged)
    ):
        teeth = float(merged["teeth"] if "teeth" in merged else merged["flutes"])
        fz = float(merged["feed_mm_min"]) / (abs(float(merged["spindle_rpm"])) * teeth)
        if not math.isclose(fz, float(merged["fz_mm"]), rel_tol=0.01):
            raise AnalysisError(
                f"{origin['fz_mm']}: fz_mm = {merged['fz_mm']!r} contradicts feed_mm_min = "
                f"{merged['feed_mm_min']!r} ({fz:.4g} mm/tooth at {merged['spindle_rpm']} rpm "
                f"and {teeth:g} teeth)"
            )
    return RunConditions.from_mapping(merged, where)
