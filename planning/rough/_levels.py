"""Geometry of one Z level (seed 000 2.4): region, offset passes, area, path length, cusp table.

Conventions (all mm, xy in the part's work coordinates):

* ``S(z)``: the offset part surface's cross-section at z, clipped to the stock footprint.
* ``C(z)``: what a flat end mill of radius r leaves standing at z when it clears everything it can
  outside ``S(z)``: the morphological closing ``(S + r) - r``. Equal to ``S`` where S is convex.
* A level z cut inside the shoulder (lo, hi) removes the region ``A(lo) - C(z)``, where
  ``A(lo) = C(lo)`` if lo is a level already cut, else the whole stock footprint (nothing below has
  been cut yet), over the height ``h = hi - z``.
* Passes (2.4.1) are the boundaries of ``S(z)`` offset outwards by ``f1 r`` then every ``step r``
  (``f1 = 1``, ``step = 1.5`` in the paper), as far as needed to cover ``A(lo)``, each clipped to
  the tool's reach of ``A(lo)`` (centre closer than r), ordered from the outermost in, and
  oriented so the part is always on the right of the tool: climb milling with an M3 spindle.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import shapely
from scipy.spatial import cKDTree
from shapely.geometry import LineString, MultiPolygon, Polygon, box
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

from planning.errors import PlanningError
from planning.surface import FergusonSurface
from planning.surface.contours import SectionMaker, as_multipolygon

_QUAD_SEGS = 16
_SAMPLE_MM = 0.5  # spacing of boundary samples for the cover distance
# A shoulder's cache key: its lower level (None: the top one), or ("x", lo) for a given region
_Key = float | None | tuple[str, float | None]


@dataclass(frozen=True, eq=False)
class LevelPass:
    """One continuous cutting pass at a level.

    xy_mm : ndarray, shape (n, 2), mm, in cutting order (closed passes repeat the first point).
    ring : offset index k (0 = nearest the part). closed : a full loop (entered by a ramp).
    """

    xy_mm: np.ndarray
    ring: int
    closed: bool

    @property
    def length_mm(self) -> float:
        return float(np.sum(np.linalg.norm(np.diff(self.xy_mm, axis=0), axis=1)))


@dataclass(frozen=True, eq=False)
class LevelPaths:
    """The passes of one level and the numbers Table 1 reports."""

    z_mm: float
    lo_mm: float | None  # None: nothing below cut yet (region bounded by the stock)
    area_mm2: float
    passes: tuple[LevelPass, ...]

    @property
    def path_mm(self) -> float:
        return float(sum(p.length_mm for p in self.passes))

    @property
    def n_closed(self) -> int:
        return sum(p.closed for p in self.passes)

    @property
    def link_xy_mm(self) -> float:
        """Sum of xy distances from each pass end to the next pass start, mm."""
        if len(self.passes) < 2:
            return 0.0
        ends = np.array([p.xy_mm[-1] for p in self.passes[:-1]])
        starts = np.array([p.xy_mm[0] for p in self.passes[1:]])
        return float(np.sum(np.linalg.norm(starts - ends, axis=1)))


def _boundary_samples(geom: BaseGeometry, step: float) -> npt.NDArray[np.float64]:
    """Points every ``step`` mm along all boundaries of a (multi)polygon, (n, 2)."""
    b = shapely.segmentize(geom.boundary, step)
    xy: npt.NDArray[np.float64] = shapely.get_coordinates(b)
    return xy


class LevelGeometry:
    """Sections, regions and passes of one offset surface for one flat end mill.

    Parameters
    ----------
    surface : the offset part surface (finish allowance already applied).
    stock_xy : (x_min, x_max, y_min, y_max), mm.
    tool_radius_mm : r.
    first_factor, step_factor : first offset f1 r and further offsets step r.
    tolerance_mm : contour accuracy.
    """

    def __init__(
        self,
        surface: FergusonSurface,
        stock_xy: tuple[float, float, float, float],
        tool_radius_mm: float,
        first_factor: float = 1.0,
        step_factor: float = 1.5,
        tolerance_mm: float = 0.01,
        maker: SectionMaker | None = None,
    ) -> None:
        self.surface = surface
        self.maker = maker or SectionMaker(surface, tolerance_mm)
        x0, x1, y0, y1 = stock_xy
        self.stock = box(x0, y0, x1, y1)
        self.r = float(tool_radius_mm)
        self.first = first_factor * self.r
        self.step = step_factor * self.r
        self._sec: dict[float, MultiPolygon] = {}
        self._clo: dict[float, MultiPolygon] = {}
        self._tree: dict[float, tuple[cKDTree, BaseGeometry]] = {}
        self._reach: dict[_Key, BaseGeometry] = {}
        self._cover_pts: dict[_Key, np.ndarray] = {}
        self._rings: dict[float, list[list[LineString]]] = {}
        self._area_of: dict[float | None, MultiPolygon | Polygon] = {}

    # ------------------------------------------------------------------------------ regions
    def section(self, z: float) -> MultiPolygon:
        """S(z) clipped to the stock."""
        if z not in self._sec:
            reg = self.maker.section(z).region.intersection(self.stock)
            self._sec[z] = as_multipolygon(reg)
        return self._sec[z]

    def closed(self, z: float) -> MultiPolygon:
        """C(z): what the tool leaves standing at z (closing of S(z) by r), in the stock."""
        if z not in self._clo:
            s = self.section(z)
            c = s.buffer(self.r, quad_segs=_QUAD_SEGS).buffer(-self.r, quad_segs=_QUAD_SEGS)
            self._clo[z] = as_multipolygon(c.union(s).intersection(self.stock))
        return self._clo[z]

    def contour_points(self, z: float) -> np.ndarray:
        """Points (m, 2) of the contour at z inside the stock (not on its edge), mm."""
        reg = self.maker.section(z).region
        if reg.is_empty:
            return np.zeros((0, 2))
        pts = _boundary_samples(reg, 2.0)  # the cusp varies slowly along a contour
        inner = self.stock.buffer(-1e-6)
        keep: npt.NDArray[np.bool_] = shapely.contains_xy(inner, pts[:, 0], pts[:, 1])
        return pts[keep]

    def above(self, lo: float | None) -> MultiPolygon | Polygon:
        """A(lo): footprint of the material between lo and the next level above."""
        if lo is None:
            return self.stock
        return self.closed(lo)

    def region(
        self, z: float, lo: float | None, lo_region: BaseGeometry | None = None
    ) -> BaseGeometry:
        """The area a level z removes in shoulder (lo, hi): A(lo) - C(z)."""
        a = self.above(lo) if lo_region is None else lo_region
        return a.difference(self.closed(z))

    # ------------------------------------------------------------------------------ passes
    def _reference(self, z: float) -> BaseGeometry:
        s = self.section(z)
        if s.is_empty:  # above the part: clear around the stock centre
            return self.stock.centroid.buffer(1e-3)
        return s

    def _ref_tree(self, z: float) -> tuple[cKDTree, BaseGeometry]:
        if z not in self._tree:
            ref = self._reference(z)
            self._tree[z] = (cKDTree(_boundary_samples(ref, _SAMPLE_MM)), ref)
        return self._tree[z]

    def _cover_points(self, key: _Key, a: BaseGeometry) -> np.ndarray:
        """Samples every 1 mm along the boundary of A(lo)."""
        if key not in self._cover_pts:
            self._cover_pts[key] = _boundary_samples(a, 1.0)
        return self._cover_pts[key]

    def cover_distance(
        self, z: float, lo: float | None, lo_region: BaseGeometry | None = None
    ) -> float:
        """Largest distance from the reference contour to material of A(lo), mm.

        Outside the reference the distance to it only grows towards the boundary of A, except
        inside holes of the reference (pockets), where it can peak inside: those are sampled on a
        grid. Boundary samples 1 mm apart miss at most 0.5 mm (the distance is 1-Lipschitz), which
        is added.
        """
        tree, ref = self._ref_tree(z)
        a = self.above(lo) if lo_region is None else lo_region
        pts = self._cover_points(lo if lo_region is None else ("x", lo), a)
        holes = [Polygon(r) for p in getattr(ref, "geoms", [ref]) for r in p.interiors]
        if holes:
            inner = shapely.union_all(holes).intersection(a)
            if not inner.is_empty:
                step = self.r / 4
                x0, y0, x1, y1 = inner.bounds
                gx, gy = np.meshgrid(np.arange(x0, x1 + step, step), np.arange(y0, y1 + step, step))
                ok = shapely.contains_xy(inner, gx.ravel(), gy.ravel())
                pts = np.concatenate([pts, np.stack([gx.ravel()[ok], gy.ravel()[ok]], 1)])
        out = ~shapely.contains_xy(ref, pts[:, 0], pts[:, 1])
        if not out.any():
            return 0.0
        d, _ = tree.query(pts[out])
        return float(np.max(d)) + 0.5

    def rings(self, z: float, k_max: int) -> list[list[LineString]]:
        """Oriented offset boundaries of the reference contour, ring k at f1 r + k step."""
        have = self._rings.setdefault(z, [])
        ref = self._reference(z)
        while len(have) <= k_max:
            k = len(have)
            grown = ref.buffer(self.first + k * self.step, quad_segs=_QUAD_SEGS)
            lines = []
            for poly in as_multipolygon(grown).geoms:
                # Part on the right of the tool: outer boundaries clockwise, holes anticlockwise.
                p = orient(poly, sign=-1.0)
                lines.append(LineString(p.exterior.coords))
                lines.extend(LineString(r.coords) for r in p.interiors)
            have.append(lines)
        return have[: k_max + 1]

    def _reach_of(self, lo: _Key, a: BaseGeometry) -> BaseGeometry:
        key = lo
        if key not in self._reach:
            # Centres closer than r to the material (a hair less, so grazing passes drop out).
            reach = a.buffer(self.r * (1 - 1e-3), quad_segs=_QUAD_SEGS)
            shapely.prepare(reach)
            self._reach[key] = reach
        return self._reach[key]

    def level(
        self, z: float, lo: float | None, lo_region: BaseGeometry | None = None
    ) -> LevelPaths:
        """Passes, area and path length of level z cut in a shoulder whose lower level is lo."""
        a = self.above(lo) if lo_region is None else lo_region
        # Sections nest (z > lo: C(z) inside C(lo) inside the stock), so no boolean is needed.
        area = max(float(a.area) - float(self.closed(z).area), 0.0)
        if area <= 1e-6:
            return LevelPaths(z, lo, 0.0, ())
        dist = self.cover_distance(z, lo, lo_region)
        reach_needed = self.first + self.r
        k_max = max(0, int(np.ceil((dist - reach_needed) / self.step - 1e-9)))
        reach = self._reach_of(lo, a) if lo_region is None else self._reach_of(("x", lo), a)
        passes: list[LevelPass] = []
        pos = None
        for k in range(k_max, -1, -1):  # outside in
            pieces = []
            for line in self.rings(z, k_max)[k]:
                cut = line.intersection(reach)
                if cut.is_empty:
                    continue
                merged = shapely.line_merge(cut, directed=True)
                for g in getattr(merged, "geoms", [merged]):
                    if isinstance(g, LineString) and g.length > 1e-6:
                        pieces.append(g)
            pieces = _order(pieces, pos)
            for g in pieces:
                xy = np.asarray(g.coords)[:, :2]
                closed = bool(g.is_closed)
                passes.append(LevelPass(xy, k, closed))
                pos = xy[-1]
        return LevelPaths(z, lo, area, tuple(passes))


def _order(pieces: list[LineString], pos: np.ndarray | None) -> list[LineString]:
    """Greedy nearest-start order; closed loops start at their vertex nearest the tool."""
    out = []
    todo = list(pieces)
    while todo:
        if pos is None:
            i = 0
        else:
            d = [np.hypot(*(np.asarray(p.coords[0])[:2] - pos)) for p in todo]
            i = int(np.argmin(d))
        g = todo.pop(i)
        if g.is_closed and pos is not None:
            c = np.asarray(g.coords)[:-1]
            j = int(np.argmin(np.hypot(c[:, 0] - pos[0], c[:, 1] - pos[1])))
            c = np.concatenate([c[j:], c[:j], c[j : j + 1]])
            g = LineString(c)
        out.append(g)
        pos = np.asarray(g.coords[-1])[:2]
    return out


class CuspTable:
    """Largest cusp of a shoulder between two levels, by the paper's estimate or measured.

    ``model = "paper"`` (seed 000 Fig. 6): h_cusp = (h1 - h2) cos(beta), h1 the upper level, h2 the
    height of a surface point B below it and beta the angle between the surface normal at B and
    the vertical. The paper evaluates it along the path where the lower level's tool touched the
    surface; here it is evaluated at every surface point of the shoulder band ``lo <= z_B < hi``
    (dense samples inside the stock), whose maximum equals the paper's value whenever it sits on
    the lower contour and stays safe where the slope changes inside the band (flat floors,
    saddles, the bottom shoulder). It is the distance to the tangent plane at B, so it
    underestimates the true leftover where the surface is convex (it falls away from that plane).

    ``model = "exact"``: the distance from the top of each column of material the shoulder leaves,
    the point (x_B, y_B, h1), to the surface itself (KD-tree over the dense samples, then the
    tangent plane of the nearest one) - what a Z-map of the result measures.
    """

    def __init__(
        self,
        surface: FergusonSurface,
        stock_xy: tuple[float, float, float, float],
        per_patch: int = 8,
        model: str = "paper",
        contour: Callable[[float], np.ndarray] | None = None,
    ) -> None:
        if model not in ("paper", "exact"):
            raise PlanningError(f"rough.cusp_model = {model!r}: expected 'paper' or 'exact'")
        p, n = surface.sample(per_patch)
        x0, x1, y0, y1 = stock_xy
        inside = (p[..., 0] >= x0) & (p[..., 0] <= x1) & (p[..., 1] >= y0) & (p[..., 1] <= y1)
        order = np.argsort(p[..., 2][inside])
        self.xyz = p[inside][order]
        self.z = self.xyz[:, 2]
        self.cosb = np.abs(n[..., 2][inside])[order]
        self.model = model
        # All samples (also outside the stock) for distances to the surface.
        self._pts = p.reshape(-1, 3)
        self._nrm = n.reshape(-1, 3)
        self._tree = cKDTree(self._pts)
        self._col: dict[float, np.ndarray] = {}
        # The band's largest cusp sits on its lower contour, which samples only come near: the
        # exact contour points of each lower level are added (contour(z) -> (m, 2) xy, mm).
        self._contour = contour
        self._lo_pts: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self.z_bottom_mm = float(self.z[0]) if self.z.size else float("nan")
        self.z_top_mm = float(self.z[-1]) if self.z.size else float("nan")

    def _values(self, hi: float, stop: int) -> np.ndarray:
        """Cusp contribution of the samples ``[:stop]`` (those below hi) for upper level hi."""
        if self.model == "paper":
            paper: npt.NDArray[np.float64] = (hi - self.z[:stop]) * self.cosb[:stop]
            return paper
        if hi not in self._col:
            below = int(np.searchsorted(self.z, hi, side="left"))
            q = self.xyz[:below].copy()
            q[:, 2] = hi
            _, i = self._tree.query(q)
            d = np.einsum("ij,ij->i", q - self._pts[i], self._nrm[i])
            self._col[hi] = np.maximum(d, 0.0)
        return self._col[hi][:stop]

    def _lower_contour(self, lo: float) -> tuple[np.ndarray, np.ndarray]:
        """Points (m, 3) of the contour at lo and cos(beta) there (nearest sample's normal)."""
        if lo not in self._lo_pts:
            xy = np.zeros((0, 2)) if self._contour is None else self._contour(lo)
            xyz = np.column_stack([xy, np.full(len(xy), lo)])
            if len(xyz):
                _, i = self._tree.query(xyz)
                cosb = np.abs(self._nrm[i, 2])
            else:
                cosb = np.zeros(0)
            self._lo_pts[lo] = (xyz, cosb)
        return self._lo_pts[lo]

    def _contour_value(self, lo: float, hi: float) -> float:
        xyz, cosb = self._lower_contour(lo)
        if len(xyz) == 0:
            return 0.0
        if self.model == "paper":
            return float((hi - lo) * cosb.max())
        q = xyz.copy()
        q[:, 2] = hi
        _, i = self._tree.query(q)
        return float(max(np.max(np.einsum("ij,ij->i", q - self._pts[i], self._nrm[i])), 0.0))

    def cusp(self, lo: float, hi: float) -> float:
        """Largest cusp (mm) of the shoulder between levels lo < hi."""
        a, b = np.searchsorted(self.z, [lo, hi], side="left")
        band = float(np.max(self._values(hi, b)[a:b])) if b > a else 0.0
        return max(band, self._contour_value(lo, hi))

    def matrix(self, heights: np.ndarray) -> np.ndarray:
        """cusp(heights[a], heights[b]) for all a < b (upper triangle), heights sorted, mm."""
        n = len(heights)
        out = np.zeros((n, n))
        idx = np.searchsorted(self.z, heights, side="left")
        for b in range(1, n):
            v = self._values(float(heights[b]), int(idx[b]))
            if v.size == 0:
                continue
            suffix = np.maximum.accumulate(v[::-1])[::-1]  # max over z >= z_i
            rows = np.arange(b)
            ok = idx[rows] < idx[b]
            out[rows[ok], b] = suffix[idx[rows[ok]]]
        for a in range(n - 1):
            xyz, cosb = self._lower_contour(float(heights[a]))
            if len(xyz) == 0:
                continue
            his = np.asarray(heights[a + 1 :], float)
            if self.model == "paper":
                val = (his - heights[a]) * cosb.max()
            else:
                q = np.repeat(xyz[None], len(his), axis=0)
                q[:, :, 2] = his[:, None]
                q = q.reshape(-1, 3)
                _, i = self._tree.query(q)
                d = np.einsum("ij,ij->i", q - self._pts[i], self._nrm[i])
                val = np.maximum(d.reshape(len(his), -1).max(axis=1), 0.0)
            out[a, a + 1 :] = np.maximum(out[a, a + 1 :], val)
        return out
