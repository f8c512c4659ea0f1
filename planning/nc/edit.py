"""Feed editing of existing programs: new F words, and moves split into pieces with their own F.

The feed post-processor decides, per motion segment, where to change the feed along it. It hands
:func:`split_moves` a plan ``{segment_index: [(t_end, feed_mm_min), ...]}`` (``t_end`` increasing
fractions of the segment's path, the last one 1.0) and gets back a new
:class:`~planning.nc.Program` that moves along exactly the same path:

* a one-piece plan ``[(1.0, f)]`` only sets the block's F word;
* a line is cut at the fractions; an arc (helix) at the fractions of its sweep, each piece an arc
  about the same centre written with I/J/K (relative, or absolute under G90.1) — R-format blocks
  are rewritten to I/J/K because R is ill-conditioned near 180 degrees;
* the first piece is the original block with only its axis, centre and F words changed (its N
  word, G/M codes, other words and comments stay); the following pieces are new blocks formatted
  like it (same N word, separator, number style), holding only axis, centre and F words;
* positions and feeds are written in the block's units (G20/G21) and distance mode (G90/G91) and
  work offset, taken from the modal state before the block;
* when the last piece's F differs from the feed the original program had in force after the
  block, an ``F`` block restoring it follows, so blocks further on that rely on the modal feed
  keep their feed.

Blocks that cannot be split faithfully raise :class:`~planning.nc.NCError`: canned cycles (many
segments per block), G28/G30 and G53 moves, blocks that stop or end the program (M0/M1/M2/M30),
feed moves under inverse-time feed G93, and moves that turn a rotary axis.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Unpack

import numpy as np

from planning.nc._codes import INCH_MM
from planning.nc._lexer import Token
from planning.nc.arcs import PLANE_AXES, arc_sweep_rad
from planning.nc.errors import NCError
from planning.nc.interpreter import Interpreter
from planning.nc.motion import ARC_CCW, ARC_CW, LINE, Motion
from planning.nc.program import NumberStyle, Program, Value
from planning.nc.run import InterpreterOptions, interpret
from planning.nc.state import ModalState

if TYPE_CHECKING:
    from analysis.config import MachineConfig

Plan = Mapping[int, Sequence[tuple[float, float]]]


def set_feed(program: Program, block: int, feed_mm_min: float, *, inch: bool = False) -> None:
    """Set (or add) the F word of ``block`` in place; ``inch`` when the block runs under G20.

    Only the F word changes. The new feed is modal: later blocks without F inherit it (use
    :func:`split_moves`, which restores the original modal feed, when that matters).
    """
    if not feed_mm_min > 0:
        raise NCError(
            f"feed must be > 0 mm/min, got {feed_mm_min}", file=program.file, line=block + 1
        )
    program.set_word(block, "F", feed_mm_min / INCH_MM if inch else feed_mm_min)


def _check_plan(pieces: Sequence[tuple[float, float]], seg: int, file: str, line: int) -> None:
    ts = [float(t) for t, _ in pieces]
    feeds = [float(f) for _, f in pieces]
    if not pieces or not math.isclose(ts[-1], 1.0, abs_tol=1e-12):
        raise NCError(
            f"plan for segment {seg} must end at t = 1.0, got {ts[-1:]}", file=file, line=line
        )
    if any(b <= a for a, b in zip([0.0, *ts], ts)):
        raise NCError(
            f"plan for segment {seg}: fractions must increase in (0, 1], got {ts}",
            file=file,
            line=line,
        )
    if not all(f > 0 and math.isfinite(f) for f in feeds):
        raise NCError(
            f"plan for segment {seg}: feeds must be > 0 mm/min, got {feeds}", file=file, line=line
        )


def split_moves(
    program: Program,
    plan: Plan,
    machine: MachineConfig | None = None,
    *,
    strict: bool = True,
    restore_feed: bool = True,
    **options: Unpack[InterpreterOptions],
) -> Program:
    """A new program with the feed plan applied (see the module docstring).

    ``plan`` keys are indices into ``interpret(program, machine, strict=strict, **options)``.
    The input program is not modified.
    """
    motion = interpret(program, machine, strict=strict, **options)
    n = len(motion)
    by_block: dict[int, int] = {}
    for seg in plan:
        if not 0 <= seg < n:
            raise NCError(
                f"plan names segment {seg}; the program has {n} segments", file=program.file
            )
        b = int(motion.block[seg])
        lo, hi = np.searchsorted(motion.block, [b, b + 1])
        line = b + 1
        if hi - lo != 1:
            raise NCError(
                f"block {b} makes {hi - lo} segments (canned cycle?); only blocks with "
                "one line or arc move can be split",
                file=program.file,
                line=line,
            )
        if motion.kind[seg] not in (LINE, ARC_CW, ARC_CCW):
            raise NCError(f"segment {seg} is not a feed move", file=program.file, line=line)
        if motion.has_rotary_travel[seg]:
            raise NCError(
                "moves of the rotary axes (A/B/C) are not split", file=program.file, line=line
            )
        _check_plan(plan[seg], seg, program.file, line)
        by_block[b] = seg

    out = Program(
        list(program.lines),
        program.file,
        program.newline,
        program.final_newline,
        _style=program.style,
    )
    it = Interpreter(machine, strict=strict, file=program.file, **options)
    edits: dict[int, list[str | dict[str, Value]]] = {}
    pos = 0
    sweeps = arc_sweep_rad(motion)
    for b in sorted(by_block):
        it.skip(program.lines[pos:b], first_line=pos + 1)
        before = it.state.copy()
        it.skip(program.lines[b : b + 1], first_line=b + 1)
        pos = b + 1
        if it.state.feed_mode == 93:
            raise NCError(
                "blocks under inverse-time feed G93 are not split (their F is 1/min)",
                file=program.file,
                line=b + 1,
            )
        seg = by_block[b]
        edits[b] = _pieces(out, b, before, it, motion, seg, float(sweeps[seg]), plan[seg])
        last_feed = float(plan[seg][-1][1])
        orig = it.state.feed_mm_min
        scale = INCH_MM if it.state.inch else 1.0
        if restore_feed and orig == orig and _next_uses_modal_feed(program, motion, seg, by_block):
            fmt = out.style.format
            if fmt(last_feed / scale, "F") != fmt(orig / scale, "F"):
                edits[b].append({"F": orig / scale})
    out.replace_blocks(edits)
    return out


def _next_uses_modal_feed(
    program: Program, motion: Motion, seg: int, edited: Mapping[int, int]
) -> bool:
    """Whether the next feed move after ``seg`` runs at the modal feed left by ``seg``'s block."""
    later = np.nonzero(motion.is_feed[seg + 1 :])[0]
    if later.size == 0:
        return False
    b = int(motion.block[seg + 1 + later[0]])
    return b not in edited and program.get_word(b, "F") is None


def _pieces(
    prog: Program,
    b: int,
    st: ModalState,
    it: Interpreter,
    motion: Motion,
    seg: int,
    sweep: float,
    pieces: Sequence[tuple[float, float]],
) -> list[str | dict[str, Value]]:
    """Block texts / word mappings replacing block ``b`` (state ``st`` in force before it)."""
    raw = prog.lines[b]
    toks = prog.words(b)
    letters = {t.letter for t in toks}
    _refuse_unsplit(prog, b, toks)
    scale = INCH_MM if st.inch else 1.0
    off = np.array(st.origin_mm)  # active work offset plus G92 / G52 (G10 set by program too)
    p0, p1 = motion.start[seg], motion.end[seg]
    moving = [a for a in range(3) if p1[a] != p0[a] or "XYZ"[a] in letters]
    points, centre = _piece_ends(motion, seg, sweep, pieces)
    if centre is not None:
        moving = sorted(set(moving) | {centre[0], centre[1]})
    # at least 0.1 um (mm) / 10 uin (inch) so rounded arc pieces stay well inside the radius
    # tolerance whatever the source's own precision
    style = prog.style
    fmt = NumberStyle(max(style.decimals, 5 if st.inch else 4), style.trailing_dot).format
    words_list: list[dict[str, Value]] = []
    prev = np.array(p0, dtype=float)
    # what the controller will see as the start of each piece: the rounded previous end
    original = {t.letter: t.number for t in prog.words(b)}
    for (t, feed), q in zip(pieces, points):
        words: dict[str, Value] = {}
        written = prev.copy()
        for a in moving:
            v = (q[a] - off[a]) / scale if st.absolute else (q[a] - prev[a]) / scale
            txt = fmt(v, "XYZ"[a])
            if t == 1.0 and st.absolute and "XYZ"[a] in original:
                txt = original["XYZ"[a]]  # the end point exactly as the source wrote it
            words["XYZ"[a]] = txt
            val = float(txt) * scale
            written[a] = val + off[a] if st.absolute else prev[a] + val
        if centre is not None:
            ia, ib, c = centre
            for a in (ia, ib):
                v = (c[a] - off[a]) / scale if st.arc_absolute else (c[a] - prev[a]) / scale
                words["IJK"[a]] = fmt(v, "IJK"[a])
        words["F"] = fmt(feed / scale, "F")
        words_list.append(words)
        prev = written
    # first piece: the original block with only these words changed
    first = Program([raw], prog.file, _style=prog.style)
    for letter in "RIJK":
        if letter in letters:
            first.remove_word(0, letter)
    for letter, value in words_list[0].items():
        first.set_word(0, letter, value)
    return [first.lines[0], *words_list[1:]]


def _refuse_unsplit(prog: Program, b: int, toks: Sequence[Token]) -> None:
    """G53 moves and blocks that stop or end the program are not split."""
    for t in toks:
        code = (t.letter, float(t.number))
        if code == ("G", 53.0) or code in {("M", 0.0), ("M", 1.0), ("M", 2.0), ("M", 30.0)}:
            why = "G53 moves" if t.letter == "G" else "blocks that stop or end the program"
            raise NCError(
                f"{why} are not split",
                file=prog.file,
                line=b + 1,
                column=t.column,
                word=t.text.strip(),
            )


def _piece_ends(
    motion: Motion, seg: int, sweep: float, pieces: Sequence[tuple[float, float]]
) -> tuple[list[np.ndarray], tuple[int, int, np.ndarray] | None]:
    """The end of each piece of segment ``seg`` (at fractions ``t`` of its line, or of the arc's
    ``sweep`` radians), and for an arc its in-plane axes and centre."""
    p0, p1 = motion.start[seg], motion.end[seg]
    kind = int(motion.kind[seg])
    if kind == LINE:
        return [p0 + t * (p1 - p0) for t, _ in pieces], None
    ia, ib, ic = PLANE_AXES[int(motion.plane[seg])]
    c = motion.center[seg]
    r = math.hypot(p0[ia] - c[ia], p0[ib] - c[ib])
    th0 = math.atan2(p0[ib] - c[ib], p0[ia] - c[ia])
    sgn = 1.0 if kind == ARC_CCW else -1.0
    points = []
    for t, _ in pieces:
        q = np.array(p1, dtype=float) if t == 1.0 else np.empty(3)
        if t != 1.0:
            th = th0 + sgn * t * sweep
            q[ia], q[ib] = c[ia] + r * math.cos(th), c[ib] + r * math.sin(th)
            q[ic] = p0[ic] + t * (p1[ic] - p0[ic])
        points.append(q)
    return points, (ia, ib, c)
