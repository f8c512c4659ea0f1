"""A roughing plan as canonical motion and as an NC program (through planning.nc's writer).

Moves, per pass of each level (levels in cutting order, passes outside in):

* rapid up to the safe height (stock top + clearance), rapid over the pass start, rapid down to
  ``hi + clearance`` (hi: the top of the material the level cuts; nothing of the part stands above
  the pass start, since passes keep at least r from the section at the level and higher
  sections nest inside it);
* an open pass (one that starts where the tool's reach leaves the material, so in air): plunge at
  the plunge feed to the level, then cut;
* a closed pass (a full loop in material): ramp down along the loop itself at ``ramp_angle_deg``,
  wrapping round it as often as the depth needs (a helix following the contour), then one full
  loop at the level from where the ramp ended;
* retract to the safe height.

With ``rough.arc_fit_tol_mm > 0`` every cutting stretch (ramp, loop, open pass) is handed to
:func:`planning.rough._arcs.fit_arcs` after rounding its vertices to the written precision
(``_DECIMALS``): runs that follow a circle within the tolerance become ``ARC_CW``/``ARC_CCW``
segments (plane 17; helical on a ramp, Z linear in angle between the run's end heights), nearly
straight runs one line. The arcs' ends are rounded vertices and their centres lie exactly on the
chord bisector, so the writer's rounding of the centre keeps the start and end radii within
0.0015 mm of each other (under the interpreter's 0.002 mm). Plan path lengths (``plan.path_mm``,
the paper's measure) come from the polylines and do not change.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from planning.nc import LINE, RAPID, Motion, MotionBuilder, NumberStyle, Program
from planning.nc import motion_to_program as _write
from planning.nc.output import for_dialect
from planning.rough._arcs import fit_arcs
from planning.rough.part import Part
from planning.rough.planner import RoughPlan

if TYPE_CHECKING:
    from analysis.config import MachineConfig

_DECIMALS = 3  # written precision (mm); arc fits work on vertices rounded to it


@dataclass(frozen=True)
class MoveSettings:
    feed_mm_min: float
    plunge_mm_min: float
    spindle_rpm: float
    safe_z_mm: float
    clearance_mm: float
    ramp_angle_deg: float
    arc_fit_tol_mm: float = 0.0

    @classmethod
    def of(cls, part: Part) -> MoveSettings:
        c, r = part.config.cutting, part.config.rough
        return cls(
            c.feed_mm_min,
            c.plunge_feed_mm_min or c.feed_mm_min / 2,
            c.spindle_rpm,
            part.config.stock.z_max_mm + r.clearance_mm,
            r.clearance_mm,
            r.ramp_angle_deg,
            r.arc_fit_tol_mm,
        )


def _walk(ring: np.ndarray, s0: float, length: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along a closed ring (first == last, (n, 2)) from arc length s0 over ``length``.

    Returns (xy (m, 2), arc length from the walk start (m,)), wrapping round as often as needed.
    """
    seg = np.linalg.norm(np.diff(ring, axis=0), axis=1)
    per = float(seg.sum())
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    laps = int(math.ceil((s0 % per + length) / per)) + 1
    # Vertices of `laps` copies of the ring, as arc length from the ring start.
    s_all = np.concatenate([cum[:-1] + k * per for k in range(laps)] + [[laps * per]])
    xy_all = np.concatenate([ring[:-1]] * laps + [ring[:1]])
    a, b = s0 % per, s0 % per + length
    inner = (s_all > a) & (s_all < b)
    s_pts = np.concatenate([[a], s_all[inner], [b]])
    x = np.interp(s_pts, s_all, xy_all[:, 0])
    y = np.interp(s_pts, s_all, xy_all[:, 1])
    return np.stack([x, y], 1), s_pts - a


def plan_motion(plan: RoughPlan, part: Part, tool_numbers: tuple[int, int] = (1, 2)) -> Motion:
    """Canonical motion of a plan (starts at the origin like planning.nc's interpreter)."""
    ms = MoveSettings.of(part)
    mb = MotionBuilder()
    pos = [0.0, 0.0, 0.0]
    tan_a = math.tan(math.radians(ms.ramp_angle_deg))
    same_tool = part.lee_tool is part.tool
    level_idx = 0  # stored in Motion.block so a plot can colour moves by level

    def add(
        kind: int, to: Sequence[float] | np.ndarray, feed: float = np.nan, tool: int = 1
    ) -> None:
        nonlocal pos
        end = [float(to[0]), float(to[1]), float(to[2])]
        if end == pos:
            return
        mb.add(kind, pos, end, feed_mm_min=feed, spindle_rpm=ms.spindle_rpm, tool=tool,
               block=level_idx)  # fmt: skip
        pos = end

    def cut(xy: np.ndarray, z: float | np.ndarray, feed: float, tool: int) -> None:
        """Feed moves through xy (m, 2) from its first point (the current position) at heights
        z (scalar or (m,)): one line per chord, or fitted arcs and lines."""
        nonlocal pos
        zz = np.broadcast_to(np.asarray(z, dtype=float), (xy.shape[0],))
        if ms.arc_fit_tol_mm <= 0:
            for (x, y), zk in zip(xy[1:], zz[1:]):
                add(LINE, (x, y, zk), feed, tool)
            return
        xy = np.round(xy, _DECIMALS)
        xy[0] = pos[:2]  # the stretch starts where the tool is (a rounded vertex already)
        fit = fit_arcs(xy, ms.arc_fit_tol_mm)
        for kind, b, (cx, cy) in zip(fit.kind.tolist(), fit.last.tolist(), fit.center_mm):
            end = (float(xy[b, 0]), float(xy[b, 1]), float(zz[b]))
            if kind == LINE:
                add(LINE, end, feed, tool)
                continue
            # arcs are added even when end == pos (a full circle)
            mb.add(kind, pos, end, (float(cx), float(cy), pos[2]), feed_mm_min=feed,
                   spindle_rpm=ms.spindle_rpm, tool=tool, block=level_idx)  # fmt: skip
            pos = list(end)

    for level_idx, lv in enumerate(plan.levels):  # noqa: B007 (read by add())
        tool = tool_numbers[0] if (lv.tool == 1 or same_tool) else tool_numbers[1]
        z, top = lv.z_mm, lv.hi_mm + ms.clearance_mm
        for p in lv.paths.passes:
            xy = p.xy_mm if ms.arc_fit_tol_mm <= 0 else np.round(p.xy_mm, _DECIMALS)
            add(RAPID, (pos[0], pos[1], ms.safe_z_mm), tool=tool)
            add(RAPID, (xy[0, 0], xy[0, 1], ms.safe_z_mm), tool=tool)
            add(RAPID, (xy[0, 0], xy[0, 1], top), tool=tool)
            if p.closed:
                ramp_len = (top - z) / tan_a
                rxy, rs = _walk(xy, 0.0, ramp_len)
                cut(rxy, top - rs * tan_a, ms.feed_mm_min, tool)
                per = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))
                loop, _ = _walk(xy, ramp_len, per)
                cut(loop, z, ms.feed_mm_min, tool)
            else:
                add(LINE, (xy[0, 0], xy[0, 1], z), ms.plunge_mm_min, tool)
                cut(xy, z, ms.feed_mm_min, tool)
            add(RAPID, (pos[0], pos[1], ms.safe_z_mm), tool=tool)
    return mb.build()


class PlanTotals(TypedDict):
    """A plan's totals (JSON-ready): mm, min; ``heights_mm`` in cutting order."""

    levels: int
    cutting_path_mm: float
    feed_length_mm: float
    entry_length_mm: float
    rapid_length_mm: float
    time_min: float
    max_cusp_mm: float
    heights_mm: list[float]


def plan_totals(plan: RoughPlan, part: Part, motion: Motion | None = None) -> PlanTotals:
    """Totals of a plan: levels, cutting path (the paper's measure), feed and rapid, time."""
    from planning.nc import motion_stats

    m = plan_motion(plan, part) if motion is None else motion
    st = motion_stats(m, rapid_mm_min=part.config.cutting.rapid_mm_min)
    return {
        "levels": len(plan.levels),
        "cutting_path_mm": round(plan.path_mm, 2),
        "feed_length_mm": round(st.cutting_length_mm, 2),
        "entry_length_mm": round(st.cutting_length_mm - plan.path_mm, 2),
        "rapid_length_mm": round(st.rapid_length_mm, 2),
        "time_min": round(st.time_s / 60.0, 3),
        "max_cusp_mm": round(plan.max_cusp_mm, 3),
        "heights_mm": [round(lv.z_mm, 3) for lv in plan.levels],
    }


def plan_program(
    plan: RoughPlan,
    part: Part,
    motion: Motion | None = None,
    dialect: str = "fanuc",
    machine: MachineConfig | None = None,
) -> Program:
    """The NC program of a plan, written by :func:`planning.nc.motion_to_program` (Fanuc style)
    and then for the ``dialect`` controller (:func:`planning.nc.output.for_dialect`; ``machine``
    says whether a GRBL mill has a tool changer)."""
    m = plan_motion(plan, part) if motion is None else motion
    heights = " ".join(f"{lv.z_mm:.2f}" for lv in plan.levels)
    comment = (
        f"cutlab plan rough {part.config.name} method {plan.method}: {len(plan.levels)} levels "
        f"{heights} tool {part.config.tool.name}"
    )
    prog = _write(m, style=NumberStyle(decimals=_DECIMALS), program_number=1, comment=comment)
    return for_dialect(prog, dialect, machine, source="fanuc")
