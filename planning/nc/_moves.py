"""Moves of the interpreter (private): segment output, targets, feeds (G94 and G93), lines, arcs,
dwells and G28/G30 reference returns.

:class:`Moves` is a mixin of :class:`~planning.nc.interpreter.Interpreter`; it uses the
interpreter's ``state``, options and the error helpers of :class:`~planning.nc._words.WordRules`.
Segments go to a :class:`~planning.nc.motion.MotionBuilder` (``out``) as one flat float row and
one flat int row each.
"""

from __future__ import annotations

import math

from planning.nc import _lexer
from planning.nc._codes import gname
from planning.nc.arcs import PLANE_AXES, arc_length_mm, center_from_r, check_radius
from planning.nc.canned import drill_hole
from planning.nc.motion import ARC_CCW, ARC_CW, DWELL, LINE, RAPID
from planning.nc.state import ModalState

NAN = math.nan


class Moves:
    """Motion execution of the Interpreter (mixin): lines, arcs, dwells and canned cycles."""

    state: ModalState
    dialect: str
    arc_tolerance_mm: float
    work_offsets_mm: dict[int, tuple[float, float, float]]
    _reference_mm: dict[int, tuple[float, float, float] | None]
    _reference_warned: bool
    _inverse_f: float
    _feed_max_mm_min: float
    _rotary_to: tuple[float, float, float] | None
    peck_clearance_mm: float

    def _seg(
        self, out, kind: int, p0, p1, c, feed: float, dwell_s: float, line: int, block: int,
        r1=None,
    ) -> None:  # fmt: skip
        """One segment; the rotary axes go from the state's position to ``r1`` (None: stay)."""
        st = self.state
        r0 = st.rotary_deg
        out.fbuf.extend((*p0, *p1, *c, feed, st.spindle_dir * st.spindle_speed_rpm, dwell_s,
                         *r0, *(r0 if r1 is None else r1)))  # fmt: skip
        out.ibuf.extend((kind, st.plane, st.tool, st.coolant, line, block))

    def _dwell(self, raw: str, v: dict[str, str], line: int, block: int, out) -> None:
        if "P" in v:
            t = float(v["P"])
            t = t / 1000.0 if self.dialect == "fanuc" else t
            letter = "P"
        elif "X" in v:
            t, letter = float(v["X"]), "X"
        else:
            raise self._fail(raw, 0, "G4 dwell needs P (ms on Fanuc, s on GRBL) or X (s)", line)
        if t < 0:
            raise self._fail(raw, letter, "dwell time must be >= 0 s", line)
        p = self.state.position_mm
        self._seg(out, DWELL, p, p, (NAN, NAN, NAN), NAN, t, line, block)

    def _target(self, v: dict[str, str], scale: float, g53: bool) -> tuple[float, float, float]:
        st = self.state
        x, y, z = st.position_mm
        if g53:
            ox = oy = oz = 0.0
        else:
            ox, oy, oz = self.work_offsets_mm.get(st.work_offset, (0.0, 0.0, 0.0))
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

    def _need_feed(self, raw: str, line: int, length_mm: float | None = None) -> float:
        """The feed of a feed move, mm/min; under G93 from the move's ``length_mm`` (None: a
        canned cycle, which G93 does not allow)."""
        if self.state.feed_mode != 93:
            f = self.state.feed_mm_min
            if f != f:
                raise self._fail(raw, 0, "feed move with no feed rate set (program F first)", line)
            return f
        if length_mm is None:
            raise self._fail(raw, 0, "canned cycles cannot run under inverse-time feed G93", line)
        if self._inverse_f != self._inverse_f:
            raise self._fail(
                raw, 0, "under inverse-time feed G93 every feed move needs its own F (1/min)", line
            )
        if not length_mm > 0.0:
            raise self._fail(
                raw,
                0,
                "inverse-time (G93) feed move that moves no axis: its time 1/F cannot be "
                "represented",
                line,
            )
        f = length_mm * self._inverse_f
        if f > self._feed_max_mm_min:
            self._note(
                raw,
                "F",
                f"inverse-time feed gives {f:g} mm/min, above the machine's feed_max_mm_min "
                f"{self._feed_max_mm_min:g}",
                line,
            )
        return f

    def _move(self, raw, v, scale, line, block, out, mode: int, g53: bool) -> None:
        st = self.state
        p0 = st.position_mm
        p1 = self._target(v, scale, g53)
        r0 = st.rotary_deg
        r1 = r0 if self._rotary_to is None else self._rotary_to
        if g53 and mode not in (0, 1):
            raise self._fail(raw, 0, "G53 needs G0 or G1 in force", line)
        if mode <= 1:  # inlined _seg: this is the hot path of big programs
            if mode == 0:
                kind, feed = RAPID, NAN
            else:
                kind, feed = LINE, st.feed_mm_min
                if feed != feed:
                    feed = self._need_feed(raw, line, math.dist((*p0, *r0), (*p1, *r1)))
            rpm = st.spindle_dir * st.spindle_speed_rpm
            out.fbuf.extend((*p0, *p1, NAN, NAN, NAN, feed, rpm, 0.0, *r0, *r1))
            out.ibuf.extend((kind, st.plane, st.tool, st.coolant, line, block))
        else:
            c = self._arc_center(raw, v, scale, line, p0, p1, mode == 2)
            length = None
            if st.feed_mode == 93:
                length = math.hypot(
                    arc_length_mm(p0, p1, c, st.plane, mode == 2), math.dist(r0, r1)
                )
            feed = self._need_feed(raw, line, length)
            kind = ARC_CW if mode == 2 else ARC_CCW
            self._seg(out, kind, p0, p1, c, feed, 0.0, line, block, r1)
        st.position_mm = p1
        st.rotary_deg = r1

    def _home(self, raw, v, scale, line, block, out, key: int, k: int) -> None:
        """G28 / G30 (word ``k`` of the block): the named axes rapid to the intermediate point,
        then to the reference point (machine coordinates); the others stay. G29: back from the
        reference point through the last G28/G30 intermediate point to the programmed point."""
        st = self.state
        code = gname(key)
        if key == 290:
            self._from_reference(raw, v, scale, line, block, out, k)
            return
        if key == 300 and "P" in v and float(v["P"]) != 2.0:
            raise self._fail(
                raw, "P", "only the second reference point (G30 P2) is configured", line
            )
        named = [a for a in range(3) if "XYZ"[a] in v]
        if named:
            mid = self._target(v, scale, False)
        elif self.dialect == "grbl":  # GRBL: no axis word = all axes straight to the point
            named, mid = [0, 1, 2], st.position_mm
        else:
            raise self._fail(
                raw, k, f"{code} needs the axes to return (X, Y, Z), e.g. G91 {code} Z0", line
            )
        ref = self._reference_mm[key]
        if ref is None:
            ref = (0.0, 0.0, 0.0)
            st.reference_assumed = True
            if not self._reference_warned:
                self._reference_warned = True
                self._note(
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
        self._two_rapids(mid, tuple(end), line, block, out)

    def _two_rapids(self, mid, end, line, block, out) -> None:
        p0 = self.state.position_mm
        nowhere = (NAN, NAN, NAN)
        for a, b in ((p0, mid), (mid, end)):
            if a != b:
                self._seg(out, RAPID, a, b, nowhere, NAN, 0.0, line, block)
        self.state.position_mm = end

    def _from_reference(self, raw, v, scale, line, block, out, k: int) -> None:
        """G29 (Fanuc): the named axes rapid to the last G28/G30 intermediate point, then to the
        programmed point (G91: relative to the intermediate point); the others stay."""
        st = self.state
        if self.dialect == "grbl":
            raise self._fail(raw, k, "G29 is not a GRBL command", line)
        named = [a for a in range(3) if "XYZ"[a] in v]
        if not named:
            raise self._fail(raw, k, "G29 needs the axes to move (X, Y, Z)", line)
        for a in named:
            if st.intermediate_mm[a] != st.intermediate_mm[a]:
                raise self._fail(
                    raw, "XYZ"[a], f"G29 {'XYZ'[a]}: no G28/G30 has set an intermediate point "
                    "for this axis yet", line,
                )  # fmt: skip
        mid = list(st.position_mm)
        for a in named:
            mid[a] = st.intermediate_mm[a]
        if st.absolute:
            end = self._target(v, scale, False)
        else:
            end = tuple(
                mid[a] + float(v["XYZ"[a]]) * scale if a in named else mid[a] for a in range(3)
            )
        self._two_rapids(tuple(mid), tuple(end), line, block, out)

    def _arc_center(self, raw, v, scale, line, p0, p1, cw: bool) -> tuple[float, float, float]:
        st = self.state
        ia, ib, ic = PLANE_AXES[st.plane]
        tol = self.arc_tolerance_mm
        ijk = "IJK"
        la, lb, ln = ijk[ia], ijk[ib], ijk[ic]
        has_r = "R" in v
        has_ijk = la in v or lb in v
        if ln in v:
            self._problem(
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
                    off = self.work_offsets_mm.get(st.work_offset, (0.0, 0.0, 0.0))
                    ca = float(v[la]) * scale + off[ia]
                    cb = float(v[lb]) * scale + off[ib]
                else:
                    ca = a0 + float(v.get(la, "0")) * scale
                    cb = b0 + float(v.get(lb, "0")) * scale
                check_radius(a0, b0, a1, b1, ca, cb, tol)
            else:
                raise ValueError(f"arc needs its centre ({la}, {lb}) or a radius R")
        except ValueError as exc:
            which = "R" if has_r else (la if la in v else lb if lb in v else 0)
            raise self._fail(raw, which, str(exc), line) from None
        c = [0.0, 0.0, 0.0]
        c[ia], c[ib], c[ic] = ca, cb, p0[ic]
        return c[0], c[1], c[2]

    def _canned(
        self, raw: str, v: dict[str, str], scale: float, line: int, block: int, out
    ) -> None:
        """Run one block in a canned-cycle mode: update R/Z/Q/P from its words (G90: absolute;
        G91: R from the initial level, Z from R) and drill L holes (default 1) at its X/Y.

        Errors become NCError naming the first of Z R Q L in the block.
        """
        st = self.state
        cy = st.canned
        x0, y0, z0 = st.position_mm
        oz = self.work_offsets_mm.get(st.work_offset, (0.0, 0.0, 0.0))[2]
        if cy.initial_z_mm != cy.initial_z_mm:
            cy.initial_z_mm = z0
        feed = self._need_feed(raw, line)  # an NCError already (outside the ValueError handler)
        try:
            if "R" in v:
                r = float(v["R"]) * scale
                cy.r_mm = r + oz if st.absolute else cy.initial_z_mm + r
            if "Z" in v:
                z = float(v["Z"]) * scale
                if st.absolute:
                    cy.z_mm = z + oz
                elif cy.r_mm == cy.r_mm:
                    cy.z_mm = cy.r_mm + z
            if "Q" in v:
                cy.q_mm = abs(float(v["Q"]) * scale)
            if "P" in v:
                p = float(v["P"])
                cy.dwell_s = p / 1000.0 if self.dialect == "fanuc" else p
            if cy.r_mm != cy.r_mm:
                raise ValueError("canned cycle needs the R plane (R word)")
            if cy.z_mm != cy.z_mm:
                raise ValueError("canned cycle needs the hole bottom (Z word)")
            repeats = 1
            if "L" in v:
                repeats = float(v["L"])
                if repeats < 0 or repeats != int(repeats) or repeats > 9999:
                    raise ValueError(f"repeat count L must be a whole number 0..9999, got {v['L']}")
                repeats = int(repeats)
            vxy = {k: v[k] for k in ("X", "Y") if k in v}
            for _ in range(repeats):
                x, y, _z = self._target(vxy, scale, False)
                moves = drill_hole(
                    st.motion,
                    st.position_mm,
                    x,
                    y,
                    cy.r_mm,
                    cy.z_mm,
                    cy.initial_z_mm,
                    retract_initial=st.retract_initial,
                    q_mm=cy.q_mm,
                    dwell_s=cy.dwell_s,
                    peck_clearance_mm=self.peck_clearance_mm,
                )
                for kind, p0, p1, dwell_s in moves:
                    f = feed if kind == LINE else NAN
                    self._seg(out, kind, p0, p1, (NAN, NAN, NAN), f, dwell_s, line, block)
                    st.position_mm = p1
        except ValueError as exc:
            which = next((L for L in "ZRQL" if L in v), 0)
            raise self._fail(raw, which, str(exc), line) from None
