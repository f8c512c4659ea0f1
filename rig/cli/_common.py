"""Small helpers shared by the command modules: JSON output, human tables, the progress bar."""

from __future__ import annotations

import json
import math
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


def parse_conditions(items: list[str]) -> dict[str, Any]:
    """``--conditions``: one JSON object, or KEY=VALUE pairs as `cutlab analyze forces` takes
    them (numbers become numbers: ``spindle_rpm=600 tool=phi10-flat``)."""
    from analysis.errors import ConfigError

    if not items:
        return {}
    if len(items) == 1 and items[0].lstrip().startswith("{"):
        try:
            obj = json.loads(items[0])
        except json.JSONDecodeError as exc:
            raise ConfigError(f"--conditions {items[0]!r}: not a JSON object ({exc})") from None
        if not isinstance(obj, dict):
            raise ConfigError(f"--conditions {items[0]!r}: expected a JSON object")
        return obj
    out: dict[str, Any] = {}
    for item in items:
        key, sep, val = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(
                f"--conditions {item!r}: expected KEY=VALUE (e.g. spindle_rpm=600) or one JSON "
                "object"
            )
        if key in out:
            raise ConfigError(f"--conditions: {key} given twice")
        out[key] = _number_or_text(val.strip())
    return out


def _number_or_text(text: str) -> int | float | str:
    """600 -> 600, 0.236 -> 0.236, phi10-flat -> 'phi10-flat' (nan/inf stay text)."""
    for kind in (int, float):
        try:
            v = kind(text)
        except ValueError:
            continue
        return v if math.isfinite(v) else text
    return text


class Progress:
    """One tqdm bar on stderr for every command, made at the first report (nothing shows when
    the input is refused before work starts) and silent when stderr is not a terminal (CI logs).

    Call it as ``bar(done, total)`` (a count or a position such as seconds recorded) or
    ``bar.step(note)`` (one more step of unknown count); use it as a context manager.
    """

    def __init__(self, desc: str, unit: str = "it", total: float | None = None,
                 quiet: bool = False, **tqdm_kw: Any) -> None:  # fmt: skip
        self._kw = dict(desc=desc, unit=unit, total=total, file=sys.stderr, leave=False,
                        disable=True if quiet else None, **tqdm_kw)  # fmt: skip
        self.bar: Any = None

    def _open(self) -> Any:
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(**self._kw)
        return self.bar

    def __call__(self, done: float, total: float | None = None) -> None:
        bar = self._open()
        if total is not None:
            bar.total = total
        bar.n = done
        bar.refresh()

    def step(self, note: str = "") -> None:
        bar = self._open()
        if note:
            bar.set_postfix_str(note, refresh=False)
        bar.update()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
