"""The motion table as CSV, written chunk by chunk (``cutlab nc motions --csv``).

One row per canonical segment, the columns of :meth:`planning.nc.Motion.to_dataframe` (line,
block, kind, x0 y0 z0 x1 y1 z1, cx cy cz, plane, feed_mm_min, spindle_rpm, tool, coolant,
dwell_s, and a0 b0 c0 a1 b1 c1 when asked for). Every float is written by ``repr`` (the shortest
text that reads back as the same float: ``float(text) == value``, so ``3554.8655`` stays
``3554.8655``); NaN (no arc centre, no feed) is an empty field, as pandas writes it.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TextIO

import numpy as np

from planning.nc.motion import KIND_NAMES, Motion

COLUMNS = [
    "line", "block", "kind", "x0", "y0", "z0", "x1", "y1", "z1", "cx", "cy", "cz", "plane",
    "feed_mm_min", "spindle_rpm", "tool", "coolant", "dwell_s",
]  # fmt: skip
ROTARY_COLUMNS = ["a0", "b0", "c0", "a1", "b1", "c1"]
#: rows formatted at a time (the text of 8192 rows is about 1.5 MB)
ROWS_PER_WRITE = 8192
_KIND = np.asarray(KIND_NAMES, dtype=object)
_BOOL = np.asarray(["False", "True"], dtype=object)


def _floats(a: np.ndarray) -> list[str]:
    """Shortest round-trip text of each float; NaN as ''."""
    nan = np.isnan(a)
    if nan.all():
        return [""] * a.size
    out = list(map(float.__repr__, a.tolist()))
    if nan.any():
        for i in np.flatnonzero(nan).tolist():
            out[i] = ""
    return out


def _ints(a: np.ndarray) -> list[str]:
    return list(map(int.__repr__, a.tolist()))


def motion_rows(m: Motion, rotary: bool) -> str:
    """The CSV rows (no header) of one Motion chunk."""
    if not len(m):
        return ""
    s, e, c = m.start, m.end, m.center
    cols = [
        _ints(m.line), _ints(m.block), _KIND[m.kind].tolist(),
        _floats(s[:, 0]), _floats(s[:, 1]), _floats(s[:, 2]),
        _floats(e[:, 0]), _floats(e[:, 1]), _floats(e[:, 2]),
        _floats(c[:, 0]), _floats(c[:, 1]), _floats(c[:, 2]),
        _ints(m.plane), _floats(m.feed_mm_min), _floats(m.spindle_rpm), _ints(m.tool),
        _BOOL[m.coolant.astype(np.int8)].tolist(), _floats(m.dwell_s),
    ]  # fmt: skip
    if rotary:
        for arr in (m.rotary_start_deg, m.rotary_end_deg):
            cols.extend(_floats(arr[:, i]) for i in range(3))
    fmt = ",".join(["%s"] * len(cols)) + "\n"
    return "".join(map(fmt.__mod__, zip(*cols)))


def write_motion_csv(chunks: Iterable[Motion], fh: TextIO, *, rotary: bool = False) -> int:
    """Write the header and the rows of every chunk to ``fh``; return the number of rows.

    ``rotary``: include the a0..c1 columns (the caller decides before the first row, e.g. from
    :func:`planning.nc.run.file_mentions_rotary`).
    """
    fh.write(",".join(COLUMNS + (ROTARY_COLUMNS if rotary else [])) + "\n")
    n = 0
    for m in chunks:
        for k in range(0, len(m), ROWS_PER_WRITE):  # bounds the text held at once
            fh.write(motion_rows(m[k : k + ROWS_PER_WRITE], rotary))
        n += len(m)
    return n


__all__ = ["COLUMNS", "ROTARY_COLUMNS", "motion_rows", "write_motion_csv"]
