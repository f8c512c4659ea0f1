"""Canned cycles of the interpreter (private): G81..G83 blocks drilled as the dialect's control
drills them (:mod:`planning.nc.canned`), LinuxCNC's positioning and pecks in program units.

:class:`Cycles` is a part of :class:`~planning.nc.interpreter.Interpreter`: it works on the
interpreter's :class:`~planning.nc._context.Context` and puts its moves out through
:class:`~planning.nc._moves.Moves` (segments, feeds, targets).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import cast

from planning.nc._context import Context, Point, Sink
from planning.nc._moves import _NOWHERE, Moves
from planning.nc.arcs import PLANE_AXES
from planning.nc.canned import Move, drill_hole, drill_hole_linuxcnc
from planning.nc.motion import LINE, RAPID

NAN = math.nan


class Cycles:
    """Canned-cycle blocks of the Interpreter (a part: works on ``ctx``, moves with
    ``moves``)."""

    def __init__(self, ctx: Context, moves: Moves) -> None:
        self.ctx = ctx
        self.moves = moves

    # ------------------------------------------------------------------ canned cycles
    def canned(
        self, raw: str, v: dict[str, str], scale: float, line: int, block: int, out: Sink
    ) -> None:
        """Run one block in a canned-cycle mode: update R/Z/Q/P from its words (G90: absolute;
        G91: R from the initial level, Z from R) and drill L holes (default 1) at its X/Y. In G18
        and G19 the drilling axis is Y and X (the plane's normal), the hole position the other
        two words.

        Errors become NCError naming the first of Z R Q L in the block.
        """
        st = self.ctx.state
        cy = st.canned
        ia, ib, ic = PLANE_AXES[st.plane]
        drill = "XYZ"[ic]
        pos = st.position_mm
        oc = st.origin_mm[ic]
        lcnc = self.ctx.rules.cycles_rs274ngc
        feed = self.moves.need_feed(raw, line)  # an NCError already (outside the try below)
        if lcnc and st.motion != cy.mode:  # LinuxCNC: a new cycle needs its words again
            self._starting(raw, v, drill, line)
        if cy.initial_z_mm != cy.initial_z_mm:
            cy.initial_z_mm = pos[ic]
            # LinuxCNC keeps it in program units (rounded: our position carries float noise)
            cy.initial_number = round((pos[ic] - oc) / scale, 10)
        try:
            repeats = self._cycle_words(v, drill, scale, oc)
            vab = {k: v[k] for k in ("XYZ"[ia], "XYZ"[ib]) if k in v}
            if lcnc:
                self._holes_linuxcnc(vab, scale, repeats, feed, line, block, out)
            else:
                for _ in range(repeats):
                    t = self.moves.target(vab, scale, False)
                    p = st.position_mm
                    moves = drill_hole(
                        st.motion, (p[ia], p[ib], p[ic]), t[ia], t[ib], cy.r_mm, cy.z_mm,
                        cy.initial_z_mm, retract_initial=st.retract_initial, q_mm=cy.q_mm,
                        dwell_s=cy.dwell_s, peck_clearance_mm=self.ctx.peck_clearance_mm,
                    )  # fmt: skip
                    self._holes(out, moves, feed, line, block, ia, ib, ic)
            cy.mode = st.motion
        except ValueError as exc:
            which = next((L for L in (drill, "R", "Q", "L") if L in v), 0)
            raise self.ctx.fail(raw, which, str(exc), line) from None

    def _starting(self, raw: str, v: dict[str, str], drill: str, line: int) -> None:
        """LinuxCNC: a cycle that starts needs its R, bottom (and P, Q) words again."""
        motion = self.ctx.state.motion
        for letter, why in (("R", "the R plane"), (drill, "the hole bottom")):
            if letter not in v:
                raise self.ctx.fail(raw, 0, f"G{motion} needs {why} ({letter} word) when the "
                                    "cycle starts", line)  # fmt: skip
        if motion == 82 and "P" not in v:
            raise self.ctx.fail(raw, 0, "G82 needs the dwell time P when it starts", line)
        if motion == 83 and "Q" not in v:
            raise self.ctx.fail(raw, 0, "G83 needs the peck depth Q when it starts", line)

    def _cycle_words(self, v: dict[str, str], drill: str, scale: float, oc: float) -> int:
        """The cycle's R, bottom, Q and P from the block's words (``oc``: the origin along the
        drilling axis, mm); returns the repeat count L. Raises ValueError."""
        st = self.ctx.state
        cy = st.canned
        lcnc = self.ctx.rules.cycles_rs274ngc
        if "R" in v:
            cy.r_number = float(v["R"])
            r = cy.r_number * scale
            cy.r_mm = r + oc if st.absolute else cy.initial_z_mm + r
        if drill in v:
            cy.z_number = float(v[drill])
            z = cy.z_number * scale
            if st.absolute:
                cy.z_mm = z + oc
            elif cy.r_mm == cy.r_mm:
                cy.z_mm = cy.r_mm + z
        if "Q" in v:
            cy.q_number = float(v["Q"])
            if lcnc and not cy.q_number > 0.0:
                raise ValueError(f"G83 needs a peck depth Q > 0, got {v['Q']}")
            cy.q_mm = abs(cy.q_number * scale)
        if "P" in v:
            cy.dwell_s = self.ctx.rules.dwell_seconds(float(v["P"]))
        if cy.r_mm != cy.r_mm:
            raise ValueError("canned cycle needs the R plane (R word)")
        if cy.z_mm != cy.z_mm:
            raise ValueError(f"canned cycle needs the hole bottom ({drill} word)")
        if "L" not in v:
            return 1
        repeats = float(v["L"])
        low = 1 if lcnc else 0
        if repeats < low or repeats != int(repeats) or repeats > 9999:
            raise ValueError(f"repeat count L must be a whole number {low}..9999, got {v['L']}")
        return int(repeats)

    def _holes_linuxcnc(
        self, vab: dict[str, str], scale: float, repeats: int, feed: float, line: int,
        block: int, out: Sink,
    ) -> None:  # fmt: skip
        """The holes of one block as LinuxCNC's ``convert_cycle_xy`` computes them: along the
        drilling axis in program units from the words as written (so its comparisons, e.g. the
        last G83 peck, come out as LinuxCNC's), converted to machine mm at the end."""
        st = self.ctx.state
        cy = st.canned
        ia, ib, ic = PLANE_AXES[st.plane]
        pos = st.position_mm
        oc = st.origin_mm[ic]
        old = cy.initial_number
        if st.absolute:
            r, bottom = cy.r_number, cy.z_number
        else:
            r = cy.r_number + old
            bottom = r + cy.z_number
        if r < bottom:
            raise ValueError(
                f"hole bottom {bottom:.6g} is above the R plane {r:.6g} (program units)"
            )
        # LinuxCNC compares exact program values; ours carry float noise (1e-9: far below any
        # real difference, far above the noise)
        here = (pos[ic] - oc) / scale
        first_above = here - r > 1e-9
        if r - old > 1e-9:  # below R: straight up to it first
            up = (pos[ia], pos[ib], r * scale + oc)
            self._holes(out, [(RAPID, (pos[ia], pos[ib], pos[ic]), up, 0.0)], feed, line, block,
                        ia, ib, ic)  # fmt: skip
            old = r
            first_above = False
        clear = old if st.retract_initial else r
        if self.ctx.peck_default:  # LinuxCNC's G83_RAPID_DELTA: 0.010 in (times 25.4 in mm)
            delta = 0.010 if st.inch else 0.010 * 25.4
        else:
            delta = self.ctx.peck_clearance_mm / scale
        for n in range(repeats):
            t = self.moves.target(vab, scale, False)
            p = st.position_mm
            moves = drill_hole_linuxcnc(
                st.motion, (p[ia], p[ib], p[ic]), t[ia], t[ib], r, bottom, clear,
                approach=here if n == 0 and first_above else None, q=cy.q_number,
                dwell_s=cy.dwell_s, peck_clearance=delta, scale=scale, offset=oc,
            )  # fmt: skip
            self._holes(out, moves, feed, line, block, ia, ib, ic)

    def _holes(
        self, out: Sink, moves: Iterable[Move], feed: float, line: int, block: int, ia: int,
        ib: int, ic: int,
    ) -> None:  # fmt: skip
        """Emit canned-cycle moves given in plane coordinates (a, b, drilling axis)."""
        st = self.ctx.state
        for kind, q0, q1, dwell_s in moves:
            f = feed if kind == LINE else NAN
            if ic == 2:
                p0, p1 = q0, q1
            else:
                a0, a1 = [0.0] * 3, [0.0] * 3
                a0[ia], a0[ib], a0[ic] = q0
                a1[ia], a1[ib], a1[ic] = q1
                p0, p1 = cast(Point, tuple(a0)), cast(Point, tuple(a1))
            self.moves.seg(out, kind, p0, p1, _NOWHERE, f, dwell_s, line, block)
            st.position_mm = p1
