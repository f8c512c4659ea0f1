"""The commands' output formats, shared by every package that renders a result as text: strict
JSON (:func:`finite_json`: NaN and infinity become null with a reason) and plain aligned text
tables (:func:`table_lines`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["TABLE_CELL_MAX", "finite_json", "json_default", "table_lines"]


def json_default(o: object) -> object:
    """``json.dump``'s ``default``: numpy values, pydantic models and paths."""
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if hasattr(o, "model_dump"):
        return o.model_dump()
    if hasattr(o, "__fspath__"):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def finite_json(obj: object) -> object:
    """``obj`` with every NaN or infinite float turned into None (strict JSON has neither).

    Where a mapping's value is replaced and it holds no ``<key>_reason`` yet, one is added
    saying what the value was (``"r2": null, "r2_reason": "not a number (nan)"``); a producer
    that knows why (``"one run"``) sets that reason itself. Numpy values become plain ones.
    """
    if isinstance(obj, Mapping):
        out: dict[Any, Any] = {}
        for k, v in obj.items():
            out[k] = finite_json(v)
            if out[k] is None and _nonfinite(v) and f"{k}_reason" not in obj:
                out[f"{k}_reason"] = _why(v)
        return out
    if isinstance(obj, list | tuple):
        return [finite_json(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return finite_json(obj.tolist())
    if isinstance(obj, float | np.floating):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.generic):
        return obj.item()
    if hasattr(obj, "model_dump"):
        return finite_json(obj.model_dump())
    return obj


def _nonfinite(v: Any) -> bool:
    return isinstance(v, float | np.floating) and not math.isfinite(v)


def _why(v: float) -> str:
    if math.isnan(v):
        return "not a number (undefined for this input)"
    return f"unbounded ({'+' if v > 0 else '-'}infinity)"


#: widest cell of a text table; a longer value is folded onto continuation lines (the whole
#: value is in --json), so one wide cell (a conditions dict) does not pad every row
TABLE_CELL_MAX = 60


def table_lines(rows: Sequence[Mapping[str, object]], floatfmt: str = ".4g",
                cell_max: int = TABLE_CELL_MAX) -> list[str]:  # fmt: skip
    """A plain aligned text table of dict rows, as lines; a cell longer than ``cell_max``
    characters is folded onto continuation lines (at ``, `` or spaces where it can)."""
    if not rows:
        return ["(no rows)"]
    cols = list(rows[0])

    def fmt(v: Any, nested: bool = False) -> str:
        if isinstance(v, float | np.floating):
            x = float(v)
            if x.is_integer() and abs(x) < 1e12:
                return str(int(x))  # 30000, not 3e+04
            return format(x, floatfmt)
        if isinstance(v, Mapping):  # {'a': 1} -> a=1, b=2 (folds at the commas)
            text = ", ".join(f"{k}={fmt(x, True)}" for k, x in v.items())
            return f"{{{text}}}" if nested else text
        return " ".join(str(v).split("\n"))

    cells = [[_fold(fmt(r.get(c, "")), cell_max) for c in cols] for r in rows]
    widths = [max(len(c), *(len(ln) for row in cells for ln in row[i])) for i, c in enumerate(cols)]
    out = ["  ".join(c.ljust(w) for c, w in zip(cols, widths))]
    for row in cells:
        for k in range(max(len(lines) for lines in row)):
            out.append("  ".join((lines[k] if k < len(lines) else "").ljust(w)
                                 for lines, w in zip(row, widths)))  # fmt: skip
    return out


def _fold(text: str, width: int) -> list[str]:
    """``text`` as lines of at most ``width`` characters (broken at spaces where it can)."""
    if len(text) <= width:
        return [text]
    import textwrap

    return textwrap.wrap(text, width, break_long_words=True, break_on_hyphens=False) or [""]
