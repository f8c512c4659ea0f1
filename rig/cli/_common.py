"""Small helpers shared by the command modules: JSON output and human tables."""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


def _default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if hasattr(o, "model_dump"):
        return o.model_dump()
    if hasattr(o, "__fspath__"):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def print_json(obj: Any) -> None:
    """Write ``obj`` as JSON to stdout (numpy scalars and arrays allowed)."""
    json.dump(obj, sys.stdout, indent=2, default=_default, allow_nan=True)
    sys.stdout.write("\n")


def print_table(rows: Sequence[Mapping[str, Any]], floatfmt: str = ".4g") -> None:
    """A plain aligned text table of dict rows to stdout."""
    if not rows:
        print("(no rows)")
        return
    cols = list(rows[0])

    def fmt(v: Any) -> str:
        if isinstance(v, float | np.floating):
            x = float(v)
            if x.is_integer() and abs(x) < 1e12:
                return str(int(x))  # 30000, not 3e+04
            return format(x, floatfmt)
        return str(v)

    cells = [[fmt(r.get(c, "")) for c in cols] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(cols)]
    print("  ".join(c.ljust(w) for c, w in zip(cols, widths)))
    for row in cells:
        print("  ".join(v.ljust(w) for v, w in zip(row, widths)))


def status(msg: str) -> None:
    """Status and progress go to stderr so stdout stays machine-readable."""
    print(msg, file=sys.stderr, flush=True)
