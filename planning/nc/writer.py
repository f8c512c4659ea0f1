"""Writing canonical motion out as an NC program.

:func:`motion_to_program` turns a :class:`~planning.nc.Motion` (e.g. a planned roughing path) into a
:class:`~planning.nc.Program` in G21/G90/G91.1/G94 that interprets back to the same motion (to the
written precision): modal G0/G1/G2/G3 only when they change, F only when the feed changes, I/J/K
relative to each arc's start, tool changes ``T M6``, spindle ``S M3/M4``/``M5``, coolant
``M8/M9``, dwells ``G4``. Coordinates are rounded to ``style.decimals`` and every later value is
computed from the rounded one, so no error accumulates.

Editing an existing program keeps its layout: see :class:`~planning.nc.Program`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from planning.nc import dialects
from planning.nc.arcs import PLANE_AXES
from planning.nc.motion import ARC_CCW, ARC_CW, DWELL, LINE, RAPID, Motion
from planning.nc.program import NumberStyle, Program

_G = {RAPID: "G0", LINE: "G1", ARC_CW: "G2", ARC_CCW: "G3"}


def motion_to_program(
    motion: Motion,
    *,
    style: NumberStyle | None = None,
    dialect: str = dialects.DEFAULT,
    program_number: int | None = None,
    comment: str | None = None,
    start_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
    end: bool = True,
    file: str = "<program>",
) -> Program:
    """An NC program whose interpretation reproduces ``motion``.

    ``start_mm`` is where the machine is before the program (the interpreter's start, 0 0 0);
    when a segment does not start where the previous one ended, a ``G0`` is inserted. Dwells are
    written as ``dialect`` reads them: ``G4 X<s>`` (Fanuc), ``G4 P<s>`` (GRBL, LinuxCNC) or
    ``G4 P<ms>``. ``end`` appends ``M30``.
    """
    rules = dialects.get(dialect)
    st = style or NumberStyle()
    out: list[str] = ["%"]
    if program_number is not None:
        out.append(f"O{program_number:04d}" + (f" ({_clean(comment)})" if comment else ""))
    elif comment:
        out.append(f"({_clean(comment)})")
    out.append("G21 G90 G91.1 G94 G17")
    w = _Writer(out, st.format, start_mm)
    for k in range(len(motion)):
        w.settings(motion, k)
        if int(motion.kind[k]) == DWELL:
            out.append(_dwell(float(motion.dwell_s[k]), rules))
        else:
            w.move(motion, k)
    if end:
        out += ["M5", "M30"] if w.rpm else ["M30"]
    out.append("%")
    return Program.from_blocks(out, file=file, style=st)


class _Writer:
    """The blocks of a motion, segment by segment, with what has been written so far (modal
    codes, and the coordinates as the interpreter will read them back: rounded)."""

    def __init__(
        self, out: list[str], fmt: Callable[[float], str], start_mm: Sequence[float]
    ) -> None:
        self.out = out
        self.fmt = fmt
        self.pos = [float(fmt(c)) for c in start_mm]
        self.rot = [0.0, 0.0, 0.0]  # A B C as written so far (the interpreter starts at 0)
        self.mode: int | None = None
        self.plane, self.feed, self.tool, self.rpm, self.coolant = 17, math.nan, 0, 0.0, False

    def coords(self, p: Sequence[float], r: Sequence[float] | None = None) -> list[str]:
        """The axis words that move the written position to ``p`` (and the rotary axes to
        ``r``)."""
        fmt, pos, rot = self.fmt, self.pos, self.rot
        words = []
        for ax, letter in enumerate("XYZ"):
            txt = fmt(float(p[ax]))
            if float(txt) != pos[ax]:
                words.append(letter + txt)
                pos[ax] = float(txt)
        if r is None:
            return words
        for ax, letter in enumerate("ABC"):
            txt = fmt(float(r[ax]))
            if float(txt) != rot[ax]:
                words.append(letter + txt)
                rot[ax] = float(txt)
        return words

    def settings(self, motion: Motion, k: int) -> None:
        """Tool, spindle, coolant and plane of segment ``k``, where they change."""
        fmt, out = self.fmt, self.out
        if int(motion.tool[k]) != self.tool:
            self.tool = int(motion.tool[k])
            out.append(f"T{self.tool} M6")
        srpm = float(motion.spindle_rpm[k])
        if srpm != self.rpm:
            out.append("M5" if srpm == 0 else f"S{fmt(abs(srpm))} {'M3' if srpm > 0 else 'M4'}")
            self.rpm = srpm
        if bool(motion.coolant[k]) != self.coolant:
            self.coolant = bool(motion.coolant[k])
            out.append("M8" if self.coolant else "M9")
        if int(motion.plane[k]) != self.plane:
            self.plane = int(motion.plane[k])
            out.append(f"G{self.plane}")

    def move(self, motion: Motion, k: int) -> None:
        """Segment ``k`` (not a dwell): a G0 to its start if it is not where the last ended,
        then the move with its modal code, centre and feed where they change."""
        fmt, out, pos, rot = self.fmt, self.out, self.pos, self.rot
        kind = int(motion.kind[k])
        s, r0 = motion.start[k], motion.rotary_start_deg[k]
        if any(float(fmt(float(s[a]))) != pos[a] for a in range(3)) or any(
            float(fmt(float(r0[a]))) != rot[a] for a in range(3)
        ):
            w = self.coords(s, r0)
            out.append(" ".join(([] if self.mode == RAPID else ["G0"]) + w))
            self.mode = RAPID
        words = [] if kind == self.mode else [_G[kind]]
        start = list(pos)
        moved = self.coords(motion.end[k], motion.rotary_end_deg[k])
        words += moved or ["X" + fmt(pos[0])]  # a zero-length move still needs an axis word
        if kind in (ARC_CW, ARC_CCW):
            ia, ib, _ = PLANE_AXES[self.plane]
            c = motion.center[k]
            words += [
                "IJK"[ia] + fmt(float(c[ia]) - start[ia]),
                "IJK"[ib] + fmt(float(c[ib]) - start[ib]),
            ]
        if kind != RAPID:
            f = float(motion.feed_mm_min[k])
            if self.feed != self.feed or fmt(f) != fmt(self.feed):
                words.append("F" + fmt(f))
                self.feed = f
        out.append(" ".join(words))
        self.mode = kind


def _clean(text: str) -> str:
    """Comment text safe inside ( ): no parentheses, one line."""
    return " ".join(text.replace("(", "[").replace(")", "]").split())


def _dwell(t_s: float, rules: dialects.Dialect) -> str:
    if rules.post.dwell_word == "X":
        return f"G4 X{format(t_s, '.3f')}"
    return f"G4 P{t_s * 1000.0:.0f}" if rules.dwell_p_ms else f"G4 P{t_s:.3f}"
