"""Independent check of a roughing program: cut it on a Z-map and measure what is left.

The program *text* is interpreted by :mod:`planning.nc` (not the planner's own move list), every
move - rapids included, arcs as chords within 1 um (:func:`planning.nc.linearize`) - is cut on a
:class:`planning.stock.zmap.ZMap` box of the stock, and the result
is compared with the offset surface (finish allowance applied):

* material left: at every Z-map point above the offset surface, its distance to the surface
  (normal distance to the tangent plane at the nearest of dense surface samples, a KD-tree
  query), whose maximum must not exceed the allowed cusp;
* gouge: how far any Z-map point went below the offset surface (vertical), which must be ~0;
* rapids: material removed by a rapid move is a crash and is reported.

The moves before the tool first reaches the safe height are skipped: planning.nc's interpreter
starts at the origin (the stock corner at z = 0 here), which is a convention, not a real position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from analysis.validation import JsonObject
from planning.errors import PlanningError
from planning.nc import DWELL, RAPID, Motion, Program, interpret, linearize
from planning.stock import Cutter, ZMap
from planning.surface import FergusonSurface


@dataclass(frozen=True, eq=False)
class CheckResult:
    """Outcome of :func:`check_program` (all mm, mm^3).

    max_left_mm: largest distance from remaining material to the offset surface;
    max_left_vertical_mm: largest height of material above the offset surface;
    max_gouge_mm: deepest point below the offset surface (0 when none);
    rapid_removed_mm3: material a rapid move hit (0 when none);
    worst_xy_mm: where the most material is left; ok: within cusp + tolerance, no gouge, no crash.
    """

    spacing_mm: float
    cusp_limit_mm: float
    tolerance_mm: float
    max_left_mm: float
    max_left_vertical_mm: float
    max_gouge_mm: float
    rapid_removed_mm3: float
    removed_mm3: float
    worst_xy_mm: tuple[float, float]
    ok: bool
    zmap: ZMap
    left_mm: np.ndarray  # (ny, nx) material above the offset surface (normal distance), mm

    def summary(self) -> JsonObject:
        return {
            "spacing_mm": self.spacing_mm,
            "cusp_limit_mm": self.cusp_limit_mm,
            "tolerance_mm": self.tolerance_mm,
            "max_left_mm": round(self.max_left_mm, 4),
            "max_left_vertical_mm": round(self.max_left_vertical_mm, 4),
            "max_gouge_mm": round(self.max_gouge_mm, 4),
            "rapid_removed_mm3": round(self.rapid_removed_mm3, 3),
            "removed_mm3": round(self.removed_mm3, 1),
            "worst_xy_mm": [round(v, 2) for v in self.worst_xy_mm],
            "ok": self.ok,
        }


class SurfaceHeights:
    """Height z(x, y) and distance to a (graph-like) Ferguson surface from dense samples."""

    def __init__(self, surface: FergusonSurface, per_patch: int = 16):
        p, n = surface.sample(per_patch)
        self.surface = surface
        self.points = p.reshape(-1, 3)
        self.normals = n.reshape(-1, 3)
        self._tree = cKDTree(self.points)

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Exact surface height above (x, y) (Newton on the xy map), mm."""
        return self.surface.height_at(np.asarray(x, float), np.asarray(y, float))

    def distance_above(self, pts: np.ndarray) -> np.ndarray:
        """Normal distance of points (n, 3) above the surface (tangent plane at nearest sample)."""
        _, i = self._tree.query(pts)
        dist: npt.NDArray[np.float64] = np.einsum("ij,ij->i", pts - self.points[i], self.normals[i])
        return dist


def simulate(
    motion: Motion,
    stock: tuple[float, float, float, float, float, float],
    radius_mm: float | dict[int, float],
    spacing_mm: float,
    safe_z_mm: float,
) -> tuple[ZMap, float, float]:
    """Cut ``motion`` on a Z-map of the stock box (x0, x1, y0, y1, z0, z1).

    ``radius_mm``: the flat end mill's radius, or one per tool number (T word).
    Returns (zmap, removed by feed moves mm^3, removed by rapids mm^3).
    """
    x0, x1, y0, y1, z0, z1 = stock
    zm = ZMap.box(x0, x1, y0, y1, z0, z1, spacing_mm)
    reached = np.flatnonzero(motion.end[:, 2] >= safe_z_mm - 1e-6)
    if reached.size == 0:
        raise PlanningError(
            f"the program never reaches the safe height z = {safe_z_mm} mm: nothing to check"
        )
    m = motion[np.arange(reached[0] + 1, len(motion))]
    lin = linearize(m[m.kind != DWELL])  # arcs as chords within 1 um
    tool = m.tool[m.kind != DWELL][lin.source]
    removed = np.zeros(len(lin.start))
    # Runs of one tool, in program order.
    cuts = np.flatnonzero(np.diff(tool)) + 1
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(tool)]):
        t = int(tool[a])
        if isinstance(radius_mm, dict):
            if t not in radius_mm:
                raise PlanningError(f"program uses tool T{t}: no radius given for it (mm)")
            r = radius_mm[t]
        else:
            r = radius_mm
        removed[a:b] = zm.cut_pieces(Cutter("flat", r), lin.start[a:b], lin.end[a:b])
    rapid = float(removed[lin.kind == RAPID].sum())
    return zm, float(removed.sum()) - rapid, rapid


def check_program(
    program: Program | str,
    offset_surface: FergusonSurface,
    stock: tuple[float, float, float, float, float, float],
    radius_mm: float | dict[int, float],
    cusp_limit_mm: float,
    safe_z_mm: float,
    spacing_mm: float = 0.5,
    tolerance_mm: float = 0.05,
) -> CheckResult:
    """Cut the program on a Z-map and compare with the offset surface (see module docstring)."""
    motion = interpret(program, strict=True)
    zm, removed, rapid = simulate(motion, stock, radius_mm, spacing_mm, safe_z_mm)
    surf = SurfaceHeights(offset_surface)
    gx, gy = np.meshgrid(zm.x_mm, zm.y_mm)
    zs = surf.height(gx, gy)
    h = zm.heights_mm
    above = h > zs
    pts = np.stack([gx[above], gy[above], h[above]], 1)
    left = np.zeros_like(h)
    if pts.size:
        left[above] = np.maximum(surf.distance_above(pts), 0.0)
    gouge = float(np.nanmax(np.maximum(zs - h, 0.0)))
    k = np.unravel_index(int(np.nanargmax(left)), left.shape)
    max_left = float(left[k])
    vert = float(np.nanmax(np.where(above, h - zs, 0.0)))
    ok = max_left <= cusp_limit_mm + tolerance_mm and gouge <= tolerance_mm and rapid <= 1e-6
    return CheckResult(
        spacing_mm,
        cusp_limit_mm,
        tolerance_mm,
        max_left,
        vert,
        gouge,
        rapid,
        removed,
        (float(gx[k]), float(gy[k])),
        ok,
        zm,
        left,
    )
