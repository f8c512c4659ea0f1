"""Moves of the interpreter (private): segment output, targets, feeds (G94 and G93), lines, arcs,
dwells, G38 probe moves and G28/G30/G29 reference returns.

:class:`Moves` is a part of :class:`~planning.nc.interpreter.Interpreter`: it works on the
interpreter's :class:`~planning.nc._context.Context` (state, options, error helpers). Segments go
to a :class:`~planning.nc.motion.MotionBuilder` (``out``) as one flat float row and one flat int
row each.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import cast

from planning.nc import _lexer
from planning.nc._codes import INCH_MM, gname
from planning.nc._context import Context, Point, Sink
from planning.nc.arcs import (
    LINUXCNC_CENTER_TOL_INCH,
    LINUXCNC_CENTER_TOL_MM,
    LINUXCNC_RADIUS_TOL_MM,
    PLANE_AXES,
    TWO_PI,
    arc_length_mm,
    center_from_r,
    check_radius,
    check_radius_linuxcnc,
)
from planning.nc.motion import ARC_CCW, ARC_CW, DWELL, LINE, RAPID

NAN = math.nan
_NOWHERE = (NAN, NAN, NAN)
_TINY_UNITS = 1e-7  # LinuxCNC: an axis moves if it moves more than this (program units)
Vec = Sequence[float]  # a point or direction (x, y, z) or rotary angles (a, b, c)


class Moves:
    """Motion execution of the Interpreter (a part: works on ``ctx``): lines, arcs, dwells,
    probe moves and reference returns; :meth:`seg`, :meth:`target` and :meth:`need_feed` serve
    the canned cycles too."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx

    def seg(
        self, out: Sink, kind: int, p0: Vec, p1: Vec, c: Vec, feed: float, dwell_s: float,
        line: int, block: int, r1: Vec | None = None, r0: Vec | None = None,
    ) -> None:  # fmt: skip
        """One segment; the rotary axes go from ``r0`` (None: the state's) to ``r1`` (None:
        stay)."""
        st = self.ctx.state
        if r0 is None:
            r0 = st.rotary_deg
        out.fbuf.extend((*p0, *p1, *c, feed, st.spindle_dir * st.spindle_speed_rpm, dwell_s,
                         *r0, *(r0 if r1 is None else r1)))  # fmt: skip
        out.ibuf.extend((kind, st.plane, st.tool, st.coolant, line, block))

    def dwell(self, raw: str, v: dict[str, str], line: int, block: int, out: Sink) -> None:
        d = self.ctx.rules
        if "P" in v:
            t = d.dwell_seconds(float(v["P"]))
            letter = "P"
        elif "X" in v and d.dwell_x:
            t, letter = float(v["X"]), "X"
        elif not d.dwell_x:
            raise self.ctx.fail(raw, 0, f"G4 dwell needs P ({'ms' if d.dwell_p_ms else 's'})", line)
        else:
            raise self.ctx.fail(raw, 0, "G4 dwell needs P (ms on Fanuc, s on GRBL) or X (s)", line)
        if t < 0:
            raise self.ctx.fail(raw, letter, "dwell time must be >= 0 s", line)
        p = self.ctx.state.position_mm
        self.seg(out, DWELL, p, p, _NOWHERE, NAN, t, line, block)

    def target(self, v: dict[str, str], scale: float, g53: bool) -> Point:
        st = self.ctx.state
        x, y, z = st.position_mm
        if g53:
            ox = oy = oz = 0.0
        else:
            ox, oy, oz = st.origin_mm
        if st.absolute or g53:
            if "X" in v:
                x = float(v["X"]) * scale + ox
            if "Y" in v:
                y = float(v["Y"]) * scale + oy
            if "Z" in v:
                z = float(v["Z"]) * scale + oz
        else:
            if "X" in v:
                x += float(v["X"]) * scale
            if "Y" in v:
                y += float(v["Y"]) * scale
            if "Z" in v:
                z += float(v["Z"]) * scale
        return x, y, z

    def need_feed(
        self, raw: str, line: int, length_mm: float | None = None,
        lcnc_len: tuple[float, float] | None = None,
    ) -> float:  # fmt: skip
        """The feed of a feed move, mm/min; under G93 from the move's ``length_mm`` (None: a
        canned cycle, which G93 does not allow). LinuxCNC (``lcnc_len``: its length of the move
        and mm per its unit): its rate is at least 0.1 units/min, so a short move may take longer
        than 1/F."""
        ctx = self.ctx
        if ctx.state.feed_mode != 93:
            f = ctx.state.feed_mm_min
            if f != f:
                raise ctx.fail(raw, 0, "feed move with no feed rate set (program F first)", line)
            return f
        if length_mm is None:
            raise ctx.fail(raw, 0, "canned cycles cannot run under inverse-time feed G93", line)
        if ctx.inverse_f != ctx.inverse_f:
            raise self.ctx.fail(
                raw, 0, "under inverse-time feed G93 every feed move needs its own F (1/min)", line
            )
        if lcnc_len is not None:
            length, unit = lcnc_len
            rate = max(0.1, length / unit * self.ctx.inverse_f)  # LinuxCNC's, units/min
            if not (length > 0.0 and length_mm > 0.0):
                return rate * unit  # it moves nowhere at that rate
            f = length_mm * rate * unit / length  # the travel in LinuxCNC's time
        elif not length_mm > 0.0:
            raise self.ctx.fail(
                raw,
                0,
                "inverse-time (G93) feed move that moves no axis: its time 1/F cannot be "
                "represented",
                line,
            )
        else:
            f = length_mm * self.ctx.inverse_f
        if f > self.ctx.feed_max_mm_min:
            self.ctx.note(
                raw,
                "F",
                f"inverse-time feed gives {f:g} mm/min, above the machine's feed_max_mm_min "
                f"{self.ctx.feed_max_mm_min:g}",
                line,
            )
        return f

    def _lcnc_length(self, p0: Vec, p1: Vec, r0: Vec, r1: Vec) -> tuple[float, float]:
        """LinuxCNC's length of a straight move (``find_straight_length``): along X Y Z if they
        move, else the rotary degrees; with the mm per its unit."""
        unit = INCH_MM if self.ctx.state.inch else 1.0
        tiny = _TINY_UNITS * unit
        if abs(p1[0] - p0[0]) > tiny or abs(p1[1] - p0[1]) > tiny or abs(p1[2] - p0[2]) > tiny:
            return math.dist(p0, p1), unit
        return math.dist(r0, r1), 1.0

    def _linuxcnc_rotary_feed(
        self, feed: float, lin_mm: float, r0: Vec, r1: Vec, p0: Vec, p1: Vec
    ) -> float:
        """LinuxCNC's G94 feed of a move that turns a rotary axis, as the Motion's feed along
        the combined travel: F is along X Y Z when they move (the rotary axes follow), else in
        degrees/min, whatever the length units."""
        rot = math.dist(r0, r1)
        unit = INCH_MM if self.ctx.state.inch else 1.0
        tiny = _TINY_UNITS * unit
        if abs(p1[0] - p0[0]) > tiny or abs(p1[1] - p0[1]) > tiny or abs(p1[2] - p0[2]) > tiny:
            return feed * math.hypot(lin_mm, rot) / lin_mm
        return self.ctx.state.feed_word  # the F number, deg/min (travel = the rotary degrees)

    def move(
        self, raw: str, v: dict[str, str], scale: float, line: int, block: int, out: Sink,
        mode: int, g53: bool,
    ) -> None:  # fmt: skip
        ctx = self.ctx
        st = ctx.state
        rules = ctx.rules
        p0 = st.position_mm
        p1 = self.target(v, scale, g53)
        r0 = st.rotary_deg
        r1 = r0 if ctx.rotary_to is None else ctx.rotary_to
        if g53:
            if mode not in (0, 1):
                raise ctx.fail(raw, 0, "G53 needs G0 or G1 in force", line)
            if rules.g53_needs_absolute and not st.absolute:
                raise ctx.fail(raw, 0, "G53 cannot be used in incremental mode G91", line)
        if mode == 38:
            self._probe_checks(raw, line, p0, p1)
            mode = 1  # a feed move to the target: where it stops depends on the part
        if mode <= 1:  # inlined _seg: this is the hot path of big programs
            if mode == 0:
                kind, feed = RAPID, NAN
            else:
                kind, feed = LINE, st.feed_mm_min
                if feed != feed:
                    along = rules.feed_along_xyz
                    lcnc = self._lcnc_length(p0, p1, r0, r1) if along else None
                    feed = self.need_feed(raw, line, math.dist((*p0, *r0), (*p1, *r1)), lcnc)
                elif r1 is not r0 and rules.feed_along_xyz:
                    feed = self._linuxcnc_rotary_feed(feed, math.dist(p0, p1), r0, r1, p0, p1)
            rpm = st.spindle_dir * st.spindle_speed_rpm
            out.fbuf.extend((*p0, *p1, NAN, NAN, NAN, feed, rpm, 0.0, *r0, *r1))
            out.ibuf.extend((kind, st.plane, st.tool, st.coolant, line, block))
        else:
            cw = mode == 2
            c = self._arc_center(raw, v, scale, line, p0, p1, cw)
            kind = ARC_CW if cw else ARC_CCW
            if rules.feed_along_xyz or rules.arc_turns_p or st.feed_mode == 93:
                self._arc(raw, v, line, block, out, kind, p0, p1, c, r0, r1)
            else:  # the common arc
                feed = self.need_feed(raw, line)
                self.seg(out, kind, p0, p1, c, feed, 0.0, line, block, r1)
        st.position_mm = p1
        st.rotary_deg = r1

    def _probe_checks(self, raw: str, line: int, p0: Vec, p1: Vec) -> None:
        """G38.2..G38.5: refused when asked (``probing="refuse"``), and LinuxCNC's and GRBL's
        errors: no feed, inverse time, cutter compensation on, a target (nearly) where it is."""
        st = self.ctx.state
        if self.ctx.probing == "refuse":
            raise self.ctx.fail(raw, 0, "G38.x probe move: where it stops depends on the part, "
                                "so the stock cannot be simulated through it (run the probing "
                                "on its own)", line)  # fmt: skip
        if st.feed_mode == 93:
            raise self.ctx.fail(raw, 0, "G38.x cannot probe under inverse-time feed G93", line)
        if not st.feed_mm_min > 0:
            raise self.ctx.fail(raw, 0, "G38.x probe move with no feed rate (program F first)",
                                line)  # fmt: skip
        if st.cutter_comp != 40:
            raise self.ctx.fail(raw, 0, "G38.x cannot probe with cutter compensation on", line)
        too_close = self.ctx.rules.probe_min_mm  # LinuxCNC's 0.01 in / 0.254 mm
        if math.dist(p0, p1) <= too_close:
            raise self.ctx.fail(raw, 0, "G38.x target too close to the start (LinuxCNC: within "
                                "0.254 mm; GRBL: the same point)", line)  # fmt: skip

    def _arc(
        self, raw: str, v: dict[str, str], line: int, block: int, out: Sink, kind: int,
        p0: Point, p1: Point, c: Point, r0: Point, r1: Point,
    ) -> None:  # fmt: skip
        """An arc under G93 or LinuxCNC's rules: its length for the inverse-time feed, the feed
        of a move with rotary axes, and LinuxCNC's P turns (full circles first, then the arc)."""
        st = self.ctx.state
        cw = kind == ARC_CW
        d = self.ctx.rules
        turns = self._turns(raw, v, line) if d.arc_turns_p and "P" in v else 1
        arc = arc_length_mm(p0, p1, c, st.plane, cw)
        ia, ib, ic = PLANE_AXES[st.plane]
        total = 1.0
        if turns > 1:  # helix over (turns - 1) full circles and the arc itself
            r = math.hypot(p0[ia] - c[ia], p0[ib] - c[ib])
            sweep = math.sqrt(max(arc * arc - (p1[ic] - p0[ic]) ** 2, 0.0)) / r
            total = sweep + TWO_PI * (turns - 1)
            arc = math.hypot(r * total, p1[ic] - p0[ic])
        length = math.hypot(arc, math.dist(r0, r1))
        if st.feed_mode == 93:
            unit = INCH_MM if st.inch else 1.0
            feed = self.need_feed(raw, line, length, (arc, unit) if d.feed_along_xyz else None)
        else:
            feed = self.need_feed(raw, line)
        if r1 != r0 and d.feed_along_xyz and st.feed_mode != 93 and arc > 0.0:
            feed *= length / arc  # LinuxCNC's F is along the arc, the rotary axes follow
        if turns == 1:
            self.seg(out, kind, p0, p1, c, feed, 0.0, line, block, r1)
            return
        ends = [TWO_PI * k / total for k in range(1, turns)] + [1.0]
        f0, a = 0.0, p0
        for f1 in ends:
            if f1 == 1.0:
                b = p1
            else:
                q = list(p0)
                q[ic] = p0[ic] + f1 * (p1[ic] - p0[ic])
                b = (q[0], q[1], q[2])
            ca = list(c)
            ca[ic] = a[ic]
            ra = tuple(x0 + f0 * (x1 - x0) for x0, x1 in zip(r0, r1))
            rb = tuple(x0 + f1 * (x1 - x0) for x0, x1 in zip(r0, r1))
            self.seg(out, kind, a, b, tuple(ca), feed, 0.0, line, block, rb, ra)
            f0, a = f1, b

    def _turns(self, raw: str, v: dict[str, str], line: int) -> int:
        """LinuxCNC's G2/G3 P: the number of turns (a whole number >= 1)."""
        p = float(v["P"])
        n = round(p)
        if abs(n - p) > 0.001:
            raise self.ctx.fail(raw, "P", f"G2/G3 P (turns) must be whole, got {v['P']}", line)
        if n < 1:
            raise self.ctx.fail(raw, "P", f"G2/G3 P (turns) must be 1 or more, got {v['P']}", line)
        return n

    # ------------------------------------------------------------------ G28 / G30 / G29
    def home(
        self, raw: str, v: dict[str, str], scale: float, line: int, block: int, out: Sink,
        key: int, k: int,
    ) -> None:  # fmt: skip
        """G28 / G30 (word ``k`` of the block): the named axes rapid to the intermediate point,
        then to the reference point (machine coordinates); the others stay. G29: back from the
        reference point through the last G28/G30 intermediate point to the programmed point."""
        st = self.ctx.state
        code = gname(key)
        if key == 290:
            self._from_reference(raw, v, scale, line, block, out, k)
            return
        if key == 300 and "P" in v and float(v["P"]) != 2.0:
            raise self.ctx.fail(
                raw, "P", "only the second reference point (G30 P2) is configured", line
            )
        named = [a for a in range(3) if "XYZ"[a] in v]
        rot_mid = self.ctx.rotary_to  # LinuxCNC: A B C words name rotary axes to return too
        if named or rot_mid is not None:
            mid = self.target(v, scale, False)
        elif self.ctx.rules.home_all_axes:  # no axis word = all axes straight to the point
            named, mid = [0, 1, 2], st.position_mm
            if self.ctx.rules.home_rotary:
                rot_mid = st.rotary_deg
        else:
            raise self.ctx.fail(
                raw, k, f"{code} needs the axes to return (X, Y, Z), e.g. G91 {code} Z0", line
            )
        ref = st.reference_mm if key == 280 else st.second_reference_mm
        if ref is None:
            ref = (0.0, 0.0, 0.0)
            st.reference_assumed = True
            if not self.ctx.reference_warned:
                self.ctx.reference_warned = True
                self.ctx.note(
                    raw,
                    k,
                    f"no machine given: the {code} point is taken as machine zero = work zero "
                    "(0, 0, 0) mm (give a machine config with reference_mm)",
                    line,
                )
        end = list(mid)
        inter = list(st.intermediate_mm)
        for a in named:
            end[a] = float(ref[a])
            inter[a] = mid[a]
        st.intermediate_mm = (inter[0], inter[1], inter[2])
        rot_end = None
        if rot_mid is not None:  # LinuxCNC: the rotary axes have reference points too
            rref = st.reference_rotary_deg if key == 280 else st.second_reference_rotary_deg
            named_rot = [i for i, c in enumerate("ABC") if c in v] or range(3)
            rot_end = cast(
                Point, tuple(rref[i] if i in named_rot else rot_mid[i] for i in range(3))
            )
        self._two_rapids(mid, cast(Point, tuple(end)), line, block, out, rot_mid, rot_end)

    def _two_rapids(
        self, mid: Point, end: Point, line: int, block: int, out: Sink,
        rot_mid: Point | None = None, rot_end: Point | None = None,
    ) -> None:  # fmt: skip
        st = self.ctx.state
        p0 = st.position_mm
        r0 = st.rotary_deg
        r_mid = r0 if rot_mid is None else rot_mid
        r_end = r_mid if rot_end is None else rot_end
        for a, b, ra, rb in ((p0, mid, r0, r_mid), (mid, end, r_mid, r_end)):
            if a != b or ra != rb:
                self.seg(out, RAPID, a, b, _NOWHERE, NAN, 0.0, line, block, rb, ra)
        st.position_mm = end
        st.rotary_deg = r_end

    def _from_reference(
        self, raw: str, v: dict[str, str], scale: float, line: int, block: int, out: Sink, k: int
    ) -> None:
        """G29 (Fanuc): the named axes rapid to the last G28/G30 intermediate point, then to the
        programmed point (G91: relative to the intermediate point); the others stay."""
        st = self.ctx.state
        if 290 in self.ctx.rules.code_errors:
            raise self.ctx.fail(raw, k, self.ctx.rules.code_errors[290], line)
        named = [a for a in range(3) if "XYZ"[a] in v]
        if not named:
            raise self.ctx.fail(raw, k, "G29 needs the axes to move (X, Y, Z)", line)
        for a in named:
            if st.intermediate_mm[a] != st.intermediate_mm[a]:
                raise self.ctx.fail(
                    raw, "XYZ"[a], f"G29 {'XYZ'[a]}: no G28/G30 has set an intermediate point "
                    "for this axis yet", line,
                )  # fmt: skip
        mid = list(st.position_mm)
        for a in named:
            mid[a] = st.intermediate_mm[a]
        if st.absolute:
            end = self.target(v, scale, False)
        else:
            end = cast(Point, tuple(
                mid[a] + float(v["XYZ"[a]]) * scale if a in named else mid[a] for a in range(3)
            ))  # fmt: skip
        self._two_rapids(cast(Point, tuple(mid)), cast(Point, tuple(end)), line, block, out)

    # ------------------------------------------------------------------ arcs
    def _arc_center(
        self, raw: str, v: dict[str, str], scale: float, line: int, p0: Point, p1: Point,
        cw: bool,
    ) -> Point:  # fmt: skip
        st = self.ctx.state
        ia, ib, ic = PLANE_AXES[st.plane]
        tol = self.ctx.arc_tolerance_mm
        lcnc = self.ctx.rules.arc_spiral
        if lcnc:
            tol = LINUXCNC_RADIUS_TOL_MM
        ijk = "IJK"
        la, lb, ln = ijk[ia], ijk[ib], ijk[ic]
        has_r = "R" in v
        has_ijk = la in v or lb in v
        if ln in v:
            self.ctx.problem(
                raw,
                _lexer.find_word(raw, ln),
                f"{ln} is not an in-plane centre word for G{st.plane} arcs",
                line,
            )
        a0, b0, a1, b1 = p0[ia], p0[ib], p1[ia], p1[ib]
        try:
            if has_r and has_ijk:
                raise ValueError("give the arc by R or by I/J/K, not both")
            if has_r:
                r = float(v["R"]) * scale
                ca, cb = center_from_r(a0, b0, a1, b1, r, cw, tol)
            elif has_ijk:
                if st.arc_absolute:
                    if not (la in v and lb in v):
                        raise ValueError(f"G90.1 (absolute centre) needs both {la} and {lb}")
                    off = st.origin_mm
                    ca = float(v[la]) * scale + off[ia]
                    cb = float(v[lb]) * scale + off[ib]
                else:
                    ca = a0 + float(v.get(la, "0")) * scale
                    cb = b0 + float(v.get(lb, "0")) * scale
                if lcnc:
                    spiral = self.ctx.spiral_tol_mm
                    if spiral is None:
                        spiral = LINUXCNC_CENTER_TOL_MM
                        if st.inch:
                            spiral = LINUXCNC_CENTER_TOL_INCH * INCH_MM
                    check_radius_linuxcnc(a0, b0, a1, b1, ca, cb, spiral, tol)
                else:
                    check_radius(a0, b0, a1, b1, ca, cb, tol)
            else:
                raise ValueError(f"arc needs its centre ({la}, {lb}) or a radius R")
        except ValueError as exc:
            which = "R" if has_r else (la if la in v else lb if lb in v else 0)
            raise self.ctx.fail(raw, which, str(exc), line) from None
        c = [0.0, 0.0, 0.0]
        c[ia], c[ib], c[ic] = ca, cb, p0[ic]
        return c[0], c[1], c[2]
