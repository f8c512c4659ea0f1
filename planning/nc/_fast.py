"""The interpreter's fast path (a part of :class:`planning.nc.interpreter.Interpreter`): runs of
plain G0..G3 blocks executed at once.

A chunk of lines is joined with NUL separators and matched by one compiled regex; runs of at least
:data:`FAST_MIN_RUN` plain blocks (N G X Y Z I J K R F words only, under simple modal state) are
converted with numpy (carry-forward of the words a line leaves out, cumulative sums under G91,
arc centres for the whole run) and appended to the motion with every field the per-block path
fills, bit for bit the same; any block the per-block path would refuse or warn about goes through
it, so errors and warnings come from one place. Why by hand: no library interprets RS-274, and a
per-block Python loop runs at ~200k blocks/s, a third of LinuxCNC's rs274.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Callable, Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from planning.nc._codes import INCH_MM
from planning.nc._context import Context, Sink
from planning.nc.arcs import (
    LINUXCNC_CENTER_TOL_INCH,
    LINUXCNC_CENTER_TOL_MM,
    LINUXCNC_RADIUS_TOL_MM,
    LINUXCNC_SPIRAL_REL_TOL,
    PLANE_AXES,
)
from planning.nc.motion import FULL_CIRCLE_TOL_MM, MotionBuilder

Execute = Callable[[str, int, int, Sink], None]  # the per-block path: (raw, line, block, out)
Cols = tuple[tuple[str, ...], ...]  # the N G X Y Z I J K R F number texts of a chunk's lines
Mask = NDArray[np.bool_]
Floats = NDArray[np.float64]


def _fast_line_re(upper_only: bool) -> re.Pattern[str]:
    """One line of a chunk joined with NUL separators: either a plain G0/G1/G2/G3 block (groups
    N G X Y Z I J K R F, in that order, each optional; spaces and ``( )`` / ``;`` comments as
    the lexer takes them) or anything else (all groups empty). Lines the lexer would reject
    never match the first alternative, so they take the per-block path, which reports them."""
    ws = "[ \t\r\n\f\v]"
    sep = ws + "*+(?:\\([^()\x00]*+\\)" + ws + "*+)*+"  # spaces and comments

    def letter(c: str) -> str:
        return c if upper_only else f"[{c}{c.lower()}]"

    number = "([-+]?(?:[0-9]{1,12}(?:\\.[0-9]*+)?|\\.[0-9]++))"
    body = (
        sep
        + f"(?:{letter('N')}{ws}*+([0-9]{{1,9}}){sep})?+"
        + f"(?:{letter('G')}{ws}*+0?([0-3]){sep})?+"
        + "".join(f"(?:{letter(c)}{ws}*+{number}{sep})?+" for c in "XYZIJKRF")
        + "(?:;[^\x00]*+)?+"
    )
    return re.compile("(?:" + body + "|[^\x00]*+)\x00")


_FAST_UPPER = _fast_line_re(True)  # for ASCII chunks, upper-cased as the lexer does
_fast_any_case = functools.cache(lambda: _fast_line_re(False))  # ~5 ms to compile: when needed
NAN = math.nan
FAST_MIN_RUN = 8  # shorter runs of plain G0..G3 blocks take the per-block path
_COL_F = 9  # column of the F words in the fast regex's groups (N G X Y Z I J K R F)


def _worth_it(lines: list[str], probe: int = 256) -> bool:
    """Whether the first ``probe`` lines are mostly in runs of plain moves that the fast path
    takes (else the chunk goes block by block: the scan would cost more than it saves)."""
    text = "\x00".join(lines[:probe]).upper() + "\x00"
    if text.count("\x00") != min(len(lines), probe):
        return False
    covered = run = 0
    for r in _FAST_UPPER.findall(text):
        if r[2] or r[3] or r[4]:
            run += 1
        else:
            covered += run if run >= FAST_MIN_RUN else 0
            run = 0
    covered += run if run >= FAST_MIN_RUN else 0
    return 2 * covered >= min(len(lines), probe)


def present_mask(col: tuple[str, ...], n: int) -> Mask:
    """Mask of the non-empty texts of ``col`` (often all or none: counted in C first; else from
    the lengths between separators of the joined column: the texts are ASCII numbers)."""
    empty = col.count("")
    if empty == 0:
        return np.ones(n, bool)
    if empty == n:
        return np.zeros(n, bool)
    text = "\x01".join(col).encode("ascii")
    sep = np.flatnonzero(np.frombuffer(text, np.uint8) == 1)
    return np.diff(sep, prepend=-1, append=len(text)) > 1  # a text: 1+ characters between


def _numbers(col: tuple[str, ...]) -> Floats:
    """The non-empty number texts of ``col`` as float64 (Python's ``float``, as the lexer's
    words are read)."""
    texts: Iterable[str] = filter(None, col) if "" in col else col
    return np.fromiter(map(float, texts), np.float64)


class FastRuns:
    """Runs of plain G0..G3 blocks executed at once (a part of the Interpreter: works on
    ``ctx``; what it does not take goes to the per-block path it is given)."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx

    def execute_lines(
        self, lines: list[str], block: int, out: MotionBuilder, execute: Execute
    ) -> None:
        """Execute ``lines`` (blocks ``block``, ``block + 1`` ...): runs of plain G0..G3 blocks
        at once (:meth:`_fast_run`), the others one by one through ``execute``."""
        n = len(lines)
        rows = None
        if n >= FAST_MIN_RUN and (n < 4096 or _worth_it(lines)):
            text = "\x00".join(lines)
            if text.count("\x00") == n - 1:  # no NUL in the lines: one row per line
                if text.isascii():
                    rows = _FAST_UPPER.findall(text.upper() + "\x00")
                else:
                    rows = _fast_any_case().findall(text + "\x00")
                if len(rows) != n:  # cannot happen; be safe
                    rows = None
        if rows is None:
            for k, raw in enumerate(lines, block):
                execute(raw, k + 1, k, out)
            return
        cols: Cols = tuple(zip(*rows))
        del rows
        has = [np.zeros(0, bool), *(present_mask(c, n) for c in cols[1:])]  # N: read where needed
        moves = has[2] | has[3] | has[4]
        # runs of plain moves: [starts[i], ends[i])
        edges = np.flatnonzero(np.diff(moves.view(np.int8), prepend=0, append=0))
        starts, ends = edges[0::2].tolist(), edges[1::2].tolist()
        i = 0
        for a, b in zip(starts, ends):
            if b - a < FAST_MIN_RUN:
                continue
            for k in range(i, a):
                execute(lines[k], block + k + 1, block + k, out)
            self._fast_run(lines, cols, has, a, b, block, out, execute)
            i = b
        for k in range(i, n):
            execute(lines[k], block + k + 1, block + k, out)

    def _fast_run(
        self, lines: list[str], cols: Cols, has: list[Mask], a: int, b: int, block: int,
        out: MotionBuilder, execute: Execute,
    ) -> None:  # fmt: skip
        """Execute lines ``a:b`` of a chunk, all plain G0..G3 blocks with an axis word
        (``cols``: their N G X Y Z I J K R F number texts, "" where absent), vectorised. A block
        whose outcome is not a pure function of its words and the state (modes, missing feed,
        bad or too high F, an arc the per-block path would refuse or warn about, I J K R words
        outside an arc) goes through ``execute``, which also raises the errors."""
        win = b - a  # rows tried at once; small after a fallback (no quadratic rescans)
        while a < b:
            st = self.ctx.state
            if st.ended or st.tape_marks >= 2 or st.feed_mode != 94 or st.motion > 3:
                execute(lines[a], block + a + 1, block + a, out)
                a += 1
                continue
            m = min(b - a, win)
            e = a + m
            scale = INCH_MM if st.inch else 1.0
            mode = self._mode_col(cols, has, a, e)
            feed, fword, fmm, has_f, bad = self._feed_col(cols, has, a, e, scale)
            bad |= (mode >= 1) & np.isnan(feed)
            arc = mode >= 2
            centre_words = [has[5 + i][a:e] for i in range(4)]  # I J K R
            ijkr = centre_words[0] | centre_words[1] | centre_words[2] | centre_words[3]
            bad |= ijkr & ~arc  # I J K R outside an arc: the per-block path reports them
            f = self._positions(cols, has, a, e, scale)
            if arc.any():
                bad |= self._fast_centres(cols, centre_words, a, e, mode, f, scale)
            if bad.any():
                k = int(np.argmax(bad))
                if k == 0:  # the per-block path raises or warns
                    execute(lines[a], block + a + 1, block + a, out)
                    a += 1
                    win = 64
                    continue
                m, e = k, a + k
                f, mode, feed, has_f = f[:k], mode[:k], feed[:k], has_f[:k]
                if fword is not None and fmm is not None:
                    fword, fmm = fword[:k], fmm[:k]
            else:
                win = max(win, 2 * m)
            self._emit(f, mode, feed, block + a, out)
            self._state_after(f, mode, has_f, fword, fmm, cols[0][a:e])
            a = e

    def _mode_col(self, cols: Cols, has: list[Mask], a: int, e: int) -> NDArray[np.int8]:
        """The motion mode (0..3) of rows ``a:e``: their G words, carried forward from the
        state's."""
        m = e - a
        motion = self.ctx.state.motion
        has_g = has[1][a:e]
        if not has_g.any():
            return np.full(m, motion, np.int8)
        gval = np.zeros(m, np.int8)
        g_text = "".join(cols[1][a:e]).encode("ascii")  # one digit 0..3 each
        gval[has_g] = np.frombuffer(g_text, np.uint8) - 48
        idx = np.where(has_g, np.arange(m), -1)
        np.maximum.accumulate(idx, out=idx)
        return np.where(idx >= 0, gval[idx], np.int8(motion)).astype(np.int8)

    def _feed_col(
        self, cols: Cols, has: list[Mask], a: int, e: int, scale: float
    ) -> tuple[Floats, Floats | None, Floats | None, Mask, Mask]:
        """The feeds of rows ``a:e`` (F words carried forward), mm/min; the F words as written
        and in mm/min (None: no F in the rows), the rows with an F and the rows whose F the
        per-block path must take (not > 0, above the machine's maximum)."""
        m = e - a
        has_f = has[_COL_F][a:e]
        bad = np.zeros(m, bool)
        if not has_f.any():
            return np.full(m, self.ctx.state.feed_mm_min), None, None, has_f, bad
        fword = np.full(m, NAN)
        fword[has_f] = _numbers(cols[_COL_F][a:e])
        fmm = fword * scale
        with np.errstate(invalid="ignore"):
            bad |= has_f & ~(fmm > 0.0)
            bad |= has_f & (fmm > self.ctx.feed_max_mm_min)
        idx = np.where(has_f, np.arange(m), -1)
        np.maximum.accumulate(idx, out=idx)
        feed = np.where(idx >= 0, fmm[idx], self.ctx.state.feed_mm_min)
        return feed, fword, fmm, has_f, bad

    def _positions(self, cols: Cols, has: list[Mask], a: int, e: int, scale: float) -> Floats:
        """The segment rows (m, 18) of rows ``a:e`` with their starts and ends (X Y Z words
        carried forward, G90 or G91) and NaN centres; the other columns are to be filled."""
        st = self.ctx.state
        m = e - a
        f = np.empty((m, 18))
        p0 = st.position_mm
        origin = st.origin_mm
        for ax in range(3):
            col = cols[2 + ax][a:e]
            hx = has[2 + ax][a:e]
            end = f[:, 3 + ax]
            if st.absolute:
                if hx.all():
                    np.add(_numbers(col) * scale, origin[ax], out=end)
                elif hx.any():
                    full = np.empty(m)
                    full[hx] = _numbers(col) * scale + origin[ax]
                    idx = np.where(hx, np.arange(m), -1)
                    np.maximum.accumulate(idx, out=idx)
                    end[:] = np.where(idx >= 0, full[idx], p0[ax])
                else:
                    end.fill(p0[ax])
            else:
                # -0.0 is the additive identity (x + 0.0 turns -0.0 into 0.0)
                step = np.full(m + 1, -0.0)
                step[0] = p0[ax]
                if hx.any():
                    step[1:][hx] = _numbers(col) * scale
                end[:] = np.add.accumulate(step)[1:]
            f[0, ax] = p0[ax]
            f[1:, ax] = end[:-1]
        f[:, 6:9] = NAN
        return f

    def _emit(
        self, f: Floats, mode: NDArray[np.int8], feed: Floats, first: int, out: MotionBuilder
    ) -> None:
        """Fill the rows' feed, spindle, dwell and rotary columns and their int row (``first``:
        the block index of the first) and append them to ``out``."""
        st = self.ctx.state
        m = len(mode)
        f[:, 9] = np.where(mode >= 1, feed, NAN)
        f[:, 10] = st.spindle_dir * st.spindle_speed_rpm
        f[:, 11] = 0.0
        f[:, 12:15] = st.rotary_deg
        f[:, 15:18] = st.rotary_deg
        ii = np.empty((m, 6), np.int32)
        ii[:, 0] = mode  # RAPID LINE ARC_CW ARC_CCW = G0 G1 G2 G3
        ii[:, 1] = st.plane
        ii[:, 2] = st.tool
        ii[:, 3] = 1 if st.coolant else 0
        ii[:, 5] = np.arange(first, first + m, dtype=np.int32)
        ii[:, 4] = ii[:, 5] + 1
        # a byte view: no copy on the way (numpy's stubs do not say an array is a Buffer)
        out.fbuf.frombytes(f.reshape(-1).view(np.uint8))  # type: ignore[arg-type]
        out.ibuf.frombytes(ii.reshape(-1).view(np.uint8))  # type: ignore[arg-type]

    def _state_after(
        self, f: Floats, mode: NDArray[np.int8], has_f: Mask, fword: Floats | None,
        fmm: Floats | None, ncol: Sequence[str],
    ) -> None:  # fmt: skip
        """The modal state after the rows (``ncol``: their N word texts)."""
        ctx = self.ctx
        st = ctx.state
        st.position_mm = (float(f[-1, 3]), float(f[-1, 4]), float(f[-1, 5]))
        st.motion = int(mode[-1])
        if fword is not None and fmm is not None and has_f.any():
            last = int(np.flatnonzero(has_f)[-1])
            st.feed_mm_min = float(fmm[last])
            st.feed_word = float(fword[last])
        for k in range(len(mode) - 1, -1, -1):
            if ncol[k]:
                st.sequence_number = int(ncol[k])
                break
        st.stopped = False
        ctx.inverse_f = NAN
        ctx.rotary_to = None

    def _fast_centres(
        self, cols: Cols, centre_words: list[Mask], a: int, e: int, mode: NDArray[np.int8],
        f: Floats, scale: float,
    ) -> Mask:  # fmt: skip
        """Centres of the arc rows of rows ``a:e`` (``mode``: their G0..G3) into ``f[:, 6:9]`` as
        :meth:`~planning.nc._moves.Moves._arc_center` computes them, bit for bit (the same float
        operations in the same order; ``math.hypot`` itself where it is used); returns the mask
        of rows the per-block path must take (it refuses or warns about them)."""
        st = self.ctx.state
        m = e - a
        arc = mode >= 2
        cw_all = mode[arc] == 2
        ia, ib, ic = PLANE_AXES[st.plane]
        tol = LINUXCNC_RADIUS_TOL_MM if self.ctx.rules.arc_spiral else self.ctx.arc_tolerance_mm
        has_a, has_b, has_n = centre_words[ia][arc], centre_words[ib][arc], centre_words[ic][arc]
        has_r = centre_words[3][arc]
        has_ab = has_a | has_b
        rows = np.flatnonzero(arc)
        bad = has_n | (has_r & has_ab) | ~(has_r | has_ab)
        if st.arc_absolute:
            bad |= has_ab & ~(has_a & has_b)
        s = f[rows]
        a0, b0, a1, b1 = s[:, ia], s[:, ib], s[:, 3 + ia], s[:, 3 + ib]
        ca = np.full(rows.size, NAN)
        cb = np.full(rows.size, NAN)

        def words(letter_col: int) -> Floats:  # the arc rows' values, 0.0 where absent
            full = np.zeros(m)
            h = centre_words[letter_col]
            if h.any():
                full[h] = _numbers(cols[5 + letter_col][a:e])
            return full[arc]

        with np.errstate(invalid="ignore", divide="ignore"):
            sel = np.flatnonzero(has_r & ~bad)
            if sel.size:
                ca[sel], cb[sel], wrong = _centres_from_r(
                    a0[sel], b0[sel], a1[sel], b1[sel], words(3)[sel] * scale, cw_all[sel], tol
                )
                bad[sel] |= wrong
            sel = np.flatnonzero(has_ab & ~bad)
            if sel.size:
                ra0, rb0 = a0[sel], b0[sel]
                wa, wb = words(ia)[sel] * scale, words(ib)[sel] * scale
                if st.arc_absolute:
                    off = st.origin_mm
                    xa, xb = wa + off[ia], wb + off[ib]
                else:
                    xa, xb = ra0 + wa, rb0 + wb
                bad[sel] |= self._radii_wrong(ra0, rb0, a1[sel], b1[sel], xa, xb, tol)
                ca[sel], cb[sel] = xa, xb
        c = np.empty((rows.size, 3))
        c[:, ia], c[:, ib], c[:, ic] = ca, cb, s[:, ic]
        f[rows, 6:9] = c
        out = np.zeros(m, bool)
        out[rows] = bad
        return out

    def _radii_wrong(
        self, a0: Floats, b0: Floats, a1: Floats, b1: Floats, ca: Floats, cb: Floats, tol: float
    ) -> Mask:
        """Arcs by centre whose start and end radii the dialect's rule refuses (LinuxCNC: its
        spiral tolerances; else ``tol``), or of (nearly) zero radius."""
        hypot = math.hypot
        n = a0.size
        r0 = np.fromiter(map(hypot, (a0 - ca).tolist(), (b0 - cb).tolist()), np.float64, n)
        r1 = np.fromiter(map(hypot, (a1 - ca).tolist(), (b1 - cb).tolist()), np.float64, n)
        if not self.ctx.rules.arc_spiral:
            wrong: Mask = (np.abs(r1 - r0) > tol) | (r0 <= FULL_CIRCLE_TOL_MM)
            return wrong
        spiral = self.ctx.spiral_tol_mm
        if spiral is None:
            spiral = LINUXCNC_CENTER_TOL_MM
            if self.ctx.state.inch:
                spiral = LINUXCNC_CENTER_TOL_INCH * INCH_MM
        err = np.abs(r0 - r1)
        rel = err / np.maximum(r0, r1)
        wrong = (r0 < tol) | (r1 < tol) | (err > 100.0 * spiral)
        wrong |= (rel > LINUXCNC_SPIRAL_REL_TOL) & (err > spiral)
        return wrong


def _centres_from_r(
    a0: Floats, b0: Floats, a1: Floats, b1: Floats, r: Floats, cw: Mask, tol: float
) -> tuple[Floats, Floats, Mask]:
    """Centres of arcs by radius ``r`` (mm; negative: the long way) from (a0, b0) to (a1, b1), as
    :func:`planning.nc.arcs.center_from_r` computes them; with the mask of the arcs it refuses."""
    da, db = a1 - a0, b1 - b0
    d = np.fromiter(map(math.hypot, da.tolist(), db.tolist()), np.float64, a0.size)
    half = 0.5 * d
    h2 = r * r - half * half
    neg = h2 < 0.0
    bad = (d <= FULL_CIRCLE_TOL_MM) | (r == 0.0) | (neg & (half - np.abs(r) > tol))
    h = np.sqrt(np.where(neg, 0.0, h2))
    sg = np.where((~cw) == (r > 0.0), h / d, -h / d)
    return a0 + 0.5 * da - sg * db, b0 + 0.5 * db + sg * da, bad
