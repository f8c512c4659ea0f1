"""Contours of a Ferguson surface at a height z (seed 000, 2.3): closed loops with islands.

The paper marches along the plane/patch intersection patch by patch and joins the pieces by their
end points. Here the same curves are found in two steps that are easier to make exact and robust:

1. the composite surface is sampled on one dense net spanning all patches, and the region
   ``z(s, t) >= level`` of that net is traced as filled polygons with holes (contourpy, the
   contouring library behind matplotlib). Because the net spans every patch, pieces are joined
   across patch edges by construction, saddles are resolved per cell, and loops that run into the
   edge of the surface are closed along that edge;
2. every vertex on the level is pulled onto the exact surface by Newton steps in (s, t) along the
   gradient of z (|z - level| < 1e-7 mm after convergence), and edges are split at their projected
   parameter midpoint until the midpoint lies within ``tolerance_mm`` of the chord in xy.

The result, a :class:`Section`, is the part's cross-section at z as a shapely MultiPolygon:
exteriors counter-clockwise, holes (islands of lower ground, pockets) clockwise. Its boundary is
the contour, exact on the surface to ``tolerance_mm`` (xy chord deviation, checked at midpoints).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import contourpy
import numpy as np
import numpy.typing as npt
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

from planning.errors import PlanningError

if TYPE_CHECKING:
    import contourpy._contourpy as cpy
from planning.surface.ferguson import FergusonSurface

_NEWTON_STEPS = 12
_MAX_REFINE_PASSES = 12


@dataclass(frozen=True, eq=False)
class Section:
    """The part's cross-section at height ``z_mm``: where the surface is at or above z.

    Attributes
    ----------
    z_mm : float, mm.
    region : shapely MultiPolygon (xy, mm); exteriors CCW, holes CW.
    tolerance_mm : float, the xy deviation of the polygon boundary from the true contour.
    """

    z_mm: float
    region: MultiPolygon
    tolerance_mm: float

    @property
    def loops(self) -> list[npt.NDArray[np.float64]]:
        """Every contour loop as an (n, 2) array, closed (first point repeated), oriented."""
        out = []
        for poly in self.region.geoms:
            out.append(np.asarray(poly.exterior.coords)[:, :2])
            out.extend(np.asarray(r.coords)[:, :2] for r in poly.interiors)
        return out

    @property
    def area_mm2(self) -> float:
        return float(self.region.area)


def _project(
    surface: FergusonSurface,
    s: npt.NDArray[np.float64],
    t: npt.NDArray[np.float64],
    level: float,
    lock_s: npt.NDArray[np.bool_],
    lock_t: npt.NDArray[np.bool_],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Newton steps in (s, t) onto z(s, t) = level; locked coordinates stay on the surface edge."""
    s, t = s.copy(), t.copy()
    for _ in range(_NEWTON_STEPS):
        r, rs, rt = surface.derivatives(s, t)
        gs = np.where(lock_s, 0.0, rs[:, 2])
        gt = np.where(lock_t, 0.0, rt[:, 2])
        g2 = gs * gs + gt * gt
        ok = g2 > 1e-18
        step = np.where(ok, (level - r[:, 2]) / np.where(ok, g2, 1.0), 0.0)
        # Limit a step to half a patch so a flat spot cannot throw a point far away.
        ds = np.clip(step * gs, -0.5, 0.5)
        dt = np.clip(step * gt, -0.5, 0.5)
        s = np.clip(s + ds, 0.0, surface.s_max)
        t = np.clip(t + dt, 0.0, surface.t_max)
        if np.max(np.abs(ds) + np.abs(dt), initial=0.0) < 1e-12:
            break
    return s, t


def _seg_dist(
    p: npt.NDArray[np.float64], a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """Distance of points p from segments a-b, all (n, 2)."""
    ab = b - a
    L2 = np.sum(ab * ab, 1)
    w = np.clip(np.sum((p - a) * ab, 1) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    dist: npt.NDArray[np.float64] = np.linalg.norm(p - (a + w[:, None] * ab), axis=1)
    return dist


def _refine_ring(
    surface: FergusonSurface,
    st: npt.NDArray[np.float64],
    level: float,
    tol: float,
    z_node: npt.NDArray[np.float64],
) -> npt.NDArray[np.float64]:
    """One traced ring (param coords, (n, 2), not closed) -> exact xy ring, (m, 2)."""
    eps = 1e-9
    smax, tmax = surface.s_max, surface.t_max
    s, t = st[:, 0].copy(), st[:, 1].copy()
    on_s = (np.abs(s) < eps) | (np.abs(s - smax) < eps)
    on_t = (np.abs(t) < eps) | (np.abs(t - tmax) < eps)
    # Corners of the filled region on the surface edge (not on the level) are kept as they are.
    keep = (on_s | on_t) & (z_node > level + 1e-9)
    lock_s, lock_t = on_s, on_t
    proj = ~keep
    s[proj], t[proj] = _project(surface, s[proj], t[proj], level, lock_s[proj], lock_t[proj])
    for _ in range(_MAX_REFINE_PASSES):
        n = s.size
        j = (np.arange(n) + 1) % n
        ms, mt = 0.5 * (s + s[j]), 0.5 * (t + t[j])
        m_lock_s = lock_s & lock_s[j] & (np.abs(s - s[j]) < eps)
        m_lock_t = lock_t & lock_t[j] & (np.abs(t - t[j]) < eps)
        m_keep = keep & keep[j]
        mp = ~m_keep
        ms[mp], mt[mp] = _project(surface, ms[mp], mt[mp], level, m_lock_s[mp], m_lock_t[mp])
        xy = surface.evaluate(s, t)[:, :2]
        mxy = surface.evaluate(ms, mt)[:, :2]
        dev = _seg_dist(mxy, xy, xy[j])
        split = dev > tol
        if not split.any():
            break
        idx = np.flatnonzero(split)
        order = np.argsort(np.concatenate([np.arange(n), idx + 0.5]), kind="stable")
        s = np.concatenate([s, ms[idx]])[order]
        t = np.concatenate([t, mt[idx]])[order]
        lock_s = np.concatenate([lock_s, m_lock_s[idx]])[order]
        lock_t = np.concatenate([lock_t, m_lock_t[idx]])[order]
        keep = np.concatenate([keep, m_keep[idx]])[order]
    return surface.evaluate(s, t)[:, :2]


def _dedupe(ring: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Drop repeated consecutive vertices and the closing repeat of a traced ring."""
    keep = np.ones(len(ring), bool)
    keep[1:] = np.any(np.abs(np.diff(ring, axis=0)) > 1e-12, axis=1)
    ring = ring[keep]
    if len(ring) > 1 and np.all(np.abs(ring[0] - ring[-1]) < 1e-12):
        ring = ring[:-1]
    return ring


class SectionMaker:
    """Cross-sections of one surface at many heights, sharing the dense net.

    Parameters
    ----------
    surface : the (offset) part surface.
    tolerance_mm : xy deviation allowed between polygon and true contour, mm.
    per_patch : samples per patch edge of the tracing net (more resolves smaller features).
    """

    def __init__(self, surface: FergusonSurface, tolerance_mm: float = 0.01, per_patch: int = 8):
        if not tolerance_mm > 0:
            raise PlanningError(f"contour tolerance_mm = {tolerance_mm}: must be > 0 (mm)")
        self.surface = surface
        self.tolerance_mm = float(tolerance_mm)
        s, t = surface.param_grid(per_patch)
        self._s_axis, self._t_axis = s[:, 0], t[0, :]
        self._z = surface.evaluate(s.ravel(), t.ravel())[:, 2].reshape(s.shape)
        self._gen = contourpy.contour_generator(
            self._s_axis, self._t_axis, self._z.T, fill_type="OuterOffset"
        )
        self.z_min_mm = float(self._z.min())
        self.z_max_mm = float(self._z.max())

    def _z_at_nodes(self, st: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Net heights at traced vertices that sit on net nodes (else -inf)."""
        ds = self._s_axis[1] - self._s_axis[0]
        dt = self._t_axis[1] - self._t_axis[0]
        fi, fj = st[:, 0] / ds, st[:, 1] / dt
        i, j = np.rint(fi).astype(int), np.rint(fj).astype(int)
        on = (np.abs(fi - i) < 1e-6) & (np.abs(fj - j) < 1e-6)
        i = np.clip(i, 0, len(self._s_axis) - 1)
        j = np.clip(j, 0, len(self._t_axis) - 1)
        return np.where(on, self._z[i, j], -np.inf)

    def section(self, z_mm: float) -> Section:
        """The cross-section (surface at or above ``z_mm``) as a :class:`Section`."""
        level = float(z_mm)
        if not np.isfinite(level):
            raise PlanningError(f"contour height z = {z_mm}: must be a finite number (mm)")
        polys: list[Polygon] = []
        if level < self.z_max_mm:
            upper = self.z_max_mm + 1.0
            # fill_type "OuterOffset" (the generator above): points and offsets per polygon
            filled = cast("cpy.FillReturn_OuterOffset", self._gen.filled(level, upper))
            all_pts, all_offs = filled
            for pts, offs in zip(all_pts, all_offs):
                rings = []
                for a, b in zip(offs[:-1], offs[1:]):
                    ring = _dedupe(np.asarray(pts[a:b], float))
                    if len(ring) < 3:
                        continue
                    xy = _refine_ring(
                        self.surface, ring, level, self.tolerance_mm, self._z_at_nodes(ring)
                    )
                    rings.append(xy)
                if not rings:
                    continue
                poly: BaseGeometry = Polygon(rings[0], rings[1:])
                if not poly.is_valid:
                    poly = shapely.make_valid(poly)
                polys.extend(_polygons(poly))
        region = shapely.union_all(polys) if polys else MultiPolygon()
        return Section(level, as_multipolygon(region, sign=1.0), self.tolerance_mm)


def _polygons(geom: BaseGeometry) -> list[Polygon]:
    """The polygonal parts of any shapely geometry."""
    if isinstance(geom, Polygon):
        return [geom] if not geom.is_empty else []
    if hasattr(geom, "geoms"):
        return [p for g in geom.geoms for p in _polygons(g)]
    return []


def as_multipolygon(geom: BaseGeometry, sign: float = 1.0) -> MultiPolygon:
    """A MultiPolygon with every part oriented (sign +1: exterior CCW, holes CW)."""
    return MultiPolygon([orient(p, sign=sign) for p in _polygons(geom) if p.area > 0])


def section(surface: FergusonSurface, z_mm: float, tolerance_mm: float = 0.01) -> Section:
    """One cross-section of ``surface`` at ``z_mm`` (see :class:`SectionMaker` for many)."""
    return SectionMaker(surface, tolerance_mm).section(z_mm)
