"""The motion table as CSV, written chunk by chunk (``cutlab nc motions --csv``).

One row per canonical segment, the columns of :meth:`planning.nc.Motion.to_dataframe` (line,
block, kind, x0 y0 z0 x1 y1 z1, cx cy cz, plane, feed_mm_min, spindle_rpm, tool, coolant,
dwell_s, and a0 b0 c0 a1 b1 c1 when asked for). Every float is written as ``repr`` writes it (the
shortest text that reads back as the same float: ``float(text) == value``, so ``3554.8655`` stays
``3554.8655``); NaN (no arc centre, no feed) is an empty field, as pandas writes it.

The text is built with numpy rather than a ``repr`` call per value (:func:`_float_text`): each
field is a row of a byte table padded with NUL bytes, the fields are gathered side by side into
one byte matrix per block of rows and the NULs are deleted at the end. A value is formatted once
per run of equal rows: the columns go in groups (x0 y0 z0 are the x1 y1 z1 of the row before,
the arc centre, plane..dwell_s), and a group's text is made only for the rows where it changes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
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

_COMMA, _NL, _DOT, _MINUS, _ZERO = b",\n.-0"
_P10 = 10.0 ** np.arange(23)  # exact: every power of ten up to 1e22 is a float
_I10 = 10 ** np.arange(19, dtype=np.int64)
#: below this many values, ``repr`` per value beats the numpy formatting
_FEW = 24


def _str_table(strings: Sequence[str]) -> np.ndarray:
    """The ASCII ``strings`` as a NUL-padded byte table (m, W)."""
    b = np.array(strings, dtype=bytes)
    if b.dtype.itemsize == 0 or not b.size:  # all empty
        return np.zeros((len(strings), 1), np.uint8)
    return b.view(np.uint8).reshape(len(strings), -1)


def _int_digits(q: np.ndarray, neg: np.ndarray | None) -> np.ndarray:
    """Decimal text of the non-negative int64 ``q`` with a ``-`` where ``neg``: a right-aligned
    NUL-padded byte table (m, W)."""
    nd = np.maximum(np.searchsorted(_I10, q, side="right"), 1)  # digits
    width = int(nd.max()) + (0 if neg is None else int(neg.any()))
    out = np.empty((q.size, width), np.uint8)
    q = q.copy()
    for p in range(width):  # p-th character from the right
        q, d = np.divmod(q, 10)
        c = d.astype(np.uint8)
        c += _ZERO
        if p >= int(nd.min()):
            c[p >= nd] = 0
            if neg is not None:
                c[neg & (p == nd)] = _MINUS
        out[:, width - 1 - p] = c
    return out


def _fixed_text(r: np.ndarray, k: np.ndarray, neg: np.ndarray) -> np.ndarray:
    """Text ``[-]int.frac`` of ``r / 10**k`` (int64 r >= 0, k >= 1 decimals, all written):
    a NUL-padded byte table (m, W), the points in one column."""
    ip, fr = np.divmod(r, _I10[k])
    left = _int_digits(ip, neg)
    f = int(k.max())
    right = np.empty((r.size, f + 1), np.uint8)
    right[:, 0] = _DOT
    q = fr * _I10[f - k]  # f digits
    for t in range(f - 1, -1, -1):  # t-th decimal
        q, d = np.divmod(q, 10)
        c = d.astype(np.uint8)
        c += _ZERO
        c[t >= k] = 0
        right[:, 1 + t] = c
    return np.hstack([left, right])


def _float_text(v: np.ndarray) -> np.ndarray:
    """``repr`` of each float ('' for NaN) as a NUL-padded byte table (m, W).

    A value ``|v|`` in [1e-4, 1e15] (or 0) is written from ``r = rint(|v| * 10**K)``, with the
    largest ``K <= 19`` that keeps ``r`` below 2**49 or so: when ``r < 2**50`` and ``r / 10**K ==
    |v|`` (exact operands, correctly rounded: the float that the text of ``r * 10**-K`` reads
    as), that text is the only one with K decimals that reads back as ``v`` (they are 1 apart in
    units of 10**-K, the floats that read as ``v`` less than 2**-3), and ``repr``'s, the shortest,
    is the one with the fewest decimals: ``r`` less its trailing zeros, keeping one decimal, in
    positional notation since the value is in [1e-4, 1e16). Any other value (more digits, tiny,
    huge, inf) is written by ``repr``.
    """
    m = v.size
    if m <= _FEW:
        return _str_table(["" if x != x else repr(x) for x in v.tolist()])
    a = np.abs(v)
    with np.errstate(all="ignore"):
        kf = np.floor(np.log10(2.0**49 / a))  # 0 -> inf, inf -> -inf, nan -> nan
        np.nan_to_num(kf, copy=False, nan=0.0, posinf=19.0, neginf=0.0)
        k = np.clip(kf, 0, 19).astype(np.intp)
        s = _P10[k]
        r = np.rint(a * s)
        fast = (r < 2.0**50) & (r / s == a) & ((a >= 1e-4) | (a == 0.0))
    slow = ~(fast | np.isnan(v))
    tables: list[tuple[np.ndarray | None, np.ndarray]] = []
    if fast.any():
        ri = r[fast].astype(np.int64) * 10
        kk = k[fast] + 1  # one decimal more: 10.0 keeps its ".0"
        for step in (16, 8, 4, 2, 1):  # drop the trailing zeros but one decimal
            z = (kk > step) & (ri % _I10[step] == 0)
            if z.any():
                ri[z] //= _I10[step]
                kk[z] -= step
        tables.append((None if fast.all() else fast, _fixed_text(ri, kk, np.signbit(v[fast]))))
    if slow.any():  # repr once per distinct value
        u, inv = np.unique(v[slow].view(np.int64), return_inverse=True)
        text = _str_table(list(map(float.__repr__, u.view(np.float64).tolist())))
        tables.append((slow, _take_rows(text, inv)))
    if len(tables) == 1 and tables[0][0] is None:
        return tables[0][1]
    width = max((t.shape[1] for _, t in tables), default=1)
    out = np.zeros((m, width), np.uint8)
    for sel, t in tables:
        out[sel, : t.shape[1]] = t
    return out


def _int_text(x: np.ndarray) -> np.ndarray:
    """Decimal text of each integer as a NUL-padded byte table (m, W)."""
    if x.size <= _FEW:
        return _str_table(list(map(str, x.tolist())))
    x = x.astype(np.int64)
    if int(x.min()) < 0:
        if int(x.min()) <= -_I10[18]:
            return _str_table(list(map(str, x.tolist())))
        return _int_digits(np.abs(x), x < 0)
    return _int_digits(x, None)


def _take_rows(t: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``t[index]`` for a byte table ``t`` (m, W), each row gathered as one item."""
    t = np.ascontiguousarray(t)
    w = t.shape[1]
    return np.take(t.view(f"V{w}").ravel(), index).view(np.uint8).reshape(-1, w)


def _changed(v: np.ndarray) -> np.ndarray:
    """Rows whose value (bit for bit: -0.0 is not 0.0, NaN is NaN) differs from the row before."""
    b = v.view(np.int64) if v.dtype == np.float64 else v
    new = np.empty(v.shape[0], bool)
    new[0] = True
    np.not_equal(b[1:], b[:-1], out=new[1:])
    return new


def _hstack(tables: list[np.ndarray]) -> np.ndarray:
    """The byte tables side by side, each followed by a comma."""
    n = tables[0].shape[0]
    out = np.empty((n, sum(t.shape[1] + 1 for t in tables)), np.uint8)
    o = 0
    for t in tables:
        w = t.shape[1]
        out[:, o : o + w] = t
        out[:, o + w] = _COMMA
        o += w + 1
    return out


def _column_text(v: np.ndarray) -> np.ndarray:
    """Text table of the column ``v`` (float or int), one row per row of ``v``, each value
    formatted once per run."""
    v = np.ascontiguousarray(v)
    if v.dtype.kind == "f":
        v = v.astype(np.float64, copy=False)
    new = _changed(v)
    fmt = _float_text if v.dtype.kind == "f" else _int_text
    t = fmt(v[new])
    if t.shape[0] == v.shape[0]:
        return t
    return _take_rows(t, np.cumsum(new) - 1)


def _group(columns: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(table, index): the text of the columns (each followed by a comma) made for the rows
    where any of them changes, and the table row of each row."""
    n = columns[0].shape[0]
    new = np.zeros(n, bool)
    new[0] = True
    for c in columns:
        new |= _changed(np.ascontiguousarray(c))
    rows = None if new.all() else np.flatnonzero(new)
    tables = []
    for c in columns:
        if c.dtype == np.bool_:
            tables.append(_take_rows(_BOOL, (c if rows is None else c[rows]).astype(np.int8)))
        else:
            tables.append(_column_text(c if rows is None else c[rows]))
    return _hstack(tables), (np.arange(n) if rows is None else np.cumsum(new) - 1)


def _chained(start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(table, start index, end index) of the start and end points (n, 3) of the rows: a start
    that is the end of the row before has the table row of that end."""
    t, index = _group([end[:, 0], end[:, 1], end[:, 2]])
    n = start.shape[0]
    s = np.ascontiguousarray(start).view(np.int64)
    e = np.ascontiguousarray(end).view(np.int64)
    fresh = np.empty(n, bool)
    fresh[0] = True
    np.any(s[1:] != e[:-1], axis=1, out=fresh[1:])
    rows = np.flatnonzero(fresh)
    ts = _hstack([_column_text(start[rows, i]) for i in range(3)])
    w = max(t.shape[1], ts.shape[1])
    both = np.zeros((t.shape[0] + ts.shape[0], w), np.uint8)
    both[: t.shape[0], w - t.shape[1] :] = t
    both[t.shape[0] :, w - ts.shape[1] :] = ts
    sindex = np.empty(n, np.intp)
    sindex[1:] = index[:-1]
    sindex[rows] = t.shape[0] + np.arange(rows.size)
    return both, sindex, index


_KIND = _hstack([_str_table(KIND_NAMES)])  # with its comma
_BOOL = _str_table(["False", "True"])


def motion_rows(m: Motion, rotary: bool) -> str:
    """The CSV rows (no header) of one Motion chunk."""
    n = len(m)
    if not n:
        return ""
    pos, sidx, eidx = _chained(m.start, m.end)
    line = _hstack([_column_text(m.line)])
    block = _hstack([_column_text(m.block)])
    centre = _group([m.center[:, 0], m.center[:, 1], m.center[:, 2]])
    tail = _group([m.plane, m.feed_mm_min, m.spindle_rpm, m.tool, m.coolant, m.dwell_s])
    fields = [
        (line, None), (block, None), (_KIND, m.kind), (pos, sidx), (pos, eidx), centre, tail,
    ]  # fmt: skip
    if rotary:
        rot, ridx, reidx = _chained(m.rotary_start_deg, m.rotary_end_deg)
        fields += [(rot, ridx), (rot, reidx)]
    out = np.empty((n, sum(t.shape[1] for t, _ in fields)), np.uint8)
    o = 0
    for t, index in fields:
        w = t.shape[1]
        out[:, o : o + w] = t if index is None else _take_rows(t, index)
        o += w
    out[:, -1] = _NL
    return out.tobytes().translate(None, b"\0").decode("ascii")


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
