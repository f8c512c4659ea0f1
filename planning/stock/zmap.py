"""Z-map stock model (seed 001 2.1): one height per grid point, lowered under each cutter move.

The stock is a regular grid of points at the centres of square cells of side ``spacing_mm``; each
point holds the top of the material above it (a Z-map cannot hold overhangs, which a 3-axis cutter
with a vertical shank cannot leave either). A move of the cutter lowers every point under its swept
envelope (see :mod:`planning.stock._kernels` for the flat, ball and bull geometry, including Choi's
formulas); the volume removed is the sum of the height drops times the cell area. Each move touches
only the patch of grid covering its footprint, so the cost of a move is its footprint in cells.
Moves run through a compiled kernel (:mod:`planning.stock._numba`) when numba is installed, else
through the numpy kernel here; both compute the same geometry (tests compare them).

Starting shapes: a box (:meth:`ZMap.box`), a height field (:meth:`ZMap.from_heights`), or a mesh /
STL part (:meth:`ZMap.from_mesh`, top-most surface per point).

Example
-------
>>> stock = ZMap.box(0, 100, 0, 50, bottom_mm=-20, top_mm=0, spacing_mm=0.5)
>>> cutter = Cutter("flat", radius_mm=5)
>>> removed = stock.cut(cutter, (0, 25, -1), (100, 25, -1))   # a 1 mm deep slot, mm^3
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planning.errors import PlanningError
from planning.stock import _kernels as _k
from planning.stock import _mesh, _numba
from planning.stock.pieces import PathCut, split_pieces

_KIND_CODES = {"flat": _k.FLAT, "ball": _k.BALL, "bull": _k.BULL}
#: grid points beyond this count are refused (8 bytes each: 400 MB)
MAX_GRID_POINTS = 50_000_000


@dataclass(frozen=True)
class Cutter:
    """Axisymmetric end mill as the Z-map sees it (tip at the programmed point).

    ``kind`` flat (corner radius 0), ball (corner radius = radius) or bull (0 < rc < radius).
    """

    kind: Literal["flat", "ball", "bull"]
    radius_mm: float
    corner_radius_mm: float = 0.0

    def __post_init__(self) -> None:
        r, rc = self.radius_mm, self.corner_radius_mm
        if self.kind not in _KIND_CODES:
            raise PlanningError(f"cutter kind '{self.kind}': expected flat, ball or bull")
        if not (math.isfinite(r) and r > 0):
            raise PlanningError(f"cutter radius_mm = {r}: must be > 0 (mm)")
        if self.kind == "ball" and rc == 0.0:
            object.__setattr__(self, "corner_radius_mm", r)
            rc = r
        ok = {
            "flat": rc == 0,
            "ball": math.isclose(rc, r, rel_tol=1e-9),
            "bull": 0 < rc < r,
        }[self.kind]
        if not ok:
            raise PlanningError(
                f"cutter {self.kind} corner_radius_mm = {rc}: flat needs 0, ball R = {r}, "
                f"bull 0 < rc < {r} (mm)"
            )

    @classmethod
    def from_tool(cls, tool: object) -> Cutter:
        """From an :class:`analysis.config.EndMill` (a face mill is refused)."""
        kind = getattr(tool, "kind", None)
        if kind not in _KIND_CODES:
            raise PlanningError(
                f"tool kind '{kind}': the Z-map models flat, ball and bull end mills only"
            )
        # attr-defined: any tool of a Z-map kind has these (no isinstance on model classes)
        return cls(kind, tool.diameter_mm / 2, tool.corner_radius_mm)  # type: ignore[attr-defined]

    def profile_mm(self, rho_mm: ArrayLike) -> NDArray[np.float64]:
        """Height of the lower surface above the tip at radius ``rho_mm``, mm (inf beyond R)."""
        rho = np.asarray(rho_mm, dtype=float)
        return _k.profile_mm(
            _KIND_CODES[self.kind], self.radius_mm, self.corner_radius_mm, rho * rho
        )


class ZMap:
    """A Z-map stock: ``heights_mm[j, i]`` is the top of the material at ``(x_mm[i], y_mm[j])``.

    Mutable on purpose: cutting lowers it in place (the stock "at any moment" is the object itself,
    :meth:`copy` keeps a snapshot). Heights never go below ``bottom_mm`` (the stock's underside).

    Parameters
    ----------
    heights_mm : array_like, shape (ny, nx), mm
    x0_mm, y0_mm : float, mm
        Corner of the grid: cell (j, i) spans ``[x0 + i s, x0 + (i+1) s] x [y0 + j s, ...]`` and
        its point is the cell centre.
    spacing_mm : float, mm
    bottom_mm : float, mm
        Underside of the stock; a cutter below it removes nothing more.
    """

    def __init__(
        self,
        heights_mm: ArrayLike,
        x0_mm: float,
        y0_mm: float,
        spacing_mm: float,
        bottom_mm: float,
    ) -> None:
        h = np.array(heights_mm, dtype=np.float64, order="C", copy=True)
        if h.ndim != 2 or h.size == 0:
            raise PlanningError(
                f"heights_mm has shape {h.shape}: expected (ny, nx) with ny, nx > 0"
            )
        if not (math.isfinite(spacing_mm) and spacing_mm > 0):
            raise PlanningError(f"spacing_mm = {spacing_mm}: must be > 0 (mm)")
        if not np.all(np.isfinite(h)):
            raise PlanningError("heights_mm holds NaN or inf: every grid point needs a height (mm)")
        if np.any(h < bottom_mm - 1e-9):
            raise PlanningError(
                f"heights_mm min {h.min():.4g} is below bottom_mm = {bottom_mm} (mm)"
            )
        self.heights_mm = h
        self.x0_mm = float(x0_mm)
        self.y0_mm = float(y0_mm)
        self.spacing_mm = float(spacing_mm)
        self.bottom_mm = float(bottom_mm)
        ny, nx = h.shape
        self.x_mm = self.x0_mm + (np.arange(nx, dtype=np.float64) + 0.5) * self.spacing_mm
        self.y_mm = self.y0_mm + (np.arange(ny, dtype=np.float64) + 0.5) * self.spacing_mm
        self._ycol = self.y_mm[:, None]
        #: use the compiled kernel (planning.stock._numba) when numba is installed
        self.compiled = True

    # ------------------------------------------------------------------ construction

    @staticmethod
    def _grid_size(extent_mm: float, spacing_mm: float, name: str) -> int:
        if not (math.isfinite(spacing_mm) and spacing_mm > 0):
            raise PlanningError(f"spacing_mm = {spacing_mm}: must be > 0 (mm)")
        if not (math.isfinite(extent_mm) and extent_mm > 0):
            raise PlanningError(f"stock {name} extent = {extent_mm}: must be > 0 (mm)")
        return max(1, round(extent_mm / spacing_mm))

    @classmethod
    def box(
        cls,
        xmin_mm: float,
        xmax_mm: float,
        ymin_mm: float,
        ymax_mm: float,
        bottom_mm: float,
        top_mm: float,
        spacing_mm: float,
    ) -> ZMap:
        """A rectangular block; the extents are rounded to whole cells of ``spacing_mm``."""
        nx = cls._grid_size(xmax_mm - xmin_mm, spacing_mm, "x")
        ny = cls._grid_size(ymax_mm - ymin_mm, spacing_mm, "y")
        if nx * ny > MAX_GRID_POINTS:
            raise PlanningError(
                f"stock grid {nx} x {ny} at spacing_mm = {spacing_mm} exceeds "
                f"{MAX_GRID_POINTS} points: use a coarser spacing (mm)"
            )
        if not top_mm > bottom_mm:
            raise PlanningError(f"stock top_mm = {top_mm} must be above bottom_mm = {bottom_mm}")
        return cls(np.full((ny, nx), float(top_mm)), xmin_mm, ymin_mm, spacing_mm, bottom_mm)

    @classmethod
    def from_heights(
        cls,
        heights_mm: ArrayLike,
        x0_mm: float,
        y0_mm: float,
        spacing_mm: float,
        bottom_mm: float | None = None,
    ) -> ZMap:
        """A height-field start (e.g. a cast near-net shape); bottom defaults to its minimum."""
        h = np.asarray(heights_mm, dtype=float)
        bottom = float(np.min(h)) if bottom_mm is None else bottom_mm
        return cls(h, x0_mm, y0_mm, spacing_mm, bottom)

    @classmethod
    def from_mesh(
        cls,
        mesh: object,
        spacing_mm: float,
        margin_mm: float = 0.0,
        bottom_mm: float | None = None,
    ) -> ZMap:
        """The top-most surface of a triangle mesh (``trimesh.Trimesh`` or an STL path).

        Grid points the mesh does not cover get ``bottom_mm`` (default: the mesh's lowest z).
        Rasterised here, vectorised over triangles, because trimesh's ray queries need rtree or
        embree and a height field only needs the highest triangle over each point.
        """
        import trimesh

        if isinstance(mesh, str | Path):
            try:
                loaded = trimesh.load(str(mesh), force="mesh")
            except Exception as exc:  # trimesh raises many types on a bad file
                raise PlanningError(f"{mesh}: cannot read the stock mesh: {exc}") from None
            mesh = loaded
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise PlanningError("stock mesh has no triangles")
        lo, hi = mesh.bounds
        bottom = float(lo[2]) if bottom_mm is None else float(bottom_mm)
        x0, y0 = lo[0] - margin_mm, lo[1] - margin_mm
        nx = cls._grid_size(hi[0] - lo[0] + 2 * margin_mm, spacing_mm, "x")
        ny = cls._grid_size(hi[1] - lo[1] + 2 * margin_mm, spacing_mm, "y")
        h = _mesh.rasterise_top(np.asarray(mesh.triangles), x0, y0, spacing_mm, nx, ny, bottom)
        return cls(np.maximum(h, bottom), x0, y0, spacing_mm, bottom)

    def copy(self) -> ZMap:
        """An independent snapshot of the stock."""
        out = ZMap(self.heights_mm, self.x0_mm, self.y0_mm, self.spacing_mm, self.bottom_mm)
        out.compiled = self.compiled
        return out

    # ------------------------------------------------------------------ queries

    @property
    def cell_area_mm2(self) -> float:
        return self.spacing_mm * self.spacing_mm

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) grid points."""
        ny, nx = self.heights_mm.shape
        return ny, nx

    @property
    def extent_mm(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the grid, mm."""
        ny, nx = self.shape
        s = self.spacing_mm
        return (self.x0_mm, self.x0_mm + nx * s, self.y0_mm, self.y0_mm + ny * s)

    def volume_mm3(self) -> float:
        """Material above ``bottom_mm``, mm^3."""
        return float((self.heights_mm - self.bottom_mm).sum() * self.cell_area_mm2)

    def height_at(self, x_mm: ArrayLike, y_mm: ArrayLike) -> NDArray[np.float64]:
        """Height of the grid point nearest to each (x, y), mm (NaN outside the grid)."""
        x = np.asarray(x_mm, dtype=float)
        y = np.asarray(y_mm, dtype=float)
        i = np.floor((x - self.x0_mm) / self.spacing_mm).astype(int)
        j = np.floor((y - self.y0_mm) / self.spacing_mm).astype(int)
        ny, nx = self.shape
        ok = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        out = np.full(np.broadcast(i, j).shape, np.nan)
        out[ok] = self.heights_mm[j[ok], i[ok]]
        return out

    def _patch(self, xlo: float, xhi: float, ylo: float, yhi: float) -> tuple[int, int, int, int]:
        """Index ranges (i0, i1, j0, j1) of the grid points inside [xlo, xhi] x [ylo, yhi]."""
        s = self.spacing_mm
        ny, nx = self.heights_mm.shape
        cx = self.x0_mm + 0.5 * s
        cy = self.y0_mm + 0.5 * s
        i0 = max(0, math.ceil((xlo - cx) / s - 1e-9))
        i1 = min(nx, math.floor((xhi - cx) / s + 1e-9) + 1)
        j0 = max(0, math.ceil((ylo - cy) / s - 1e-9))
        j1 = min(ny, math.floor((yhi - cy) / s + 1e-9) + 1)
        return i0, i1, j0, j1

    def max_height_near(
        self, start_mm: ArrayLike, end_mm: ArrayLike, radius_mm: float
    ) -> NDArray[np.float64]:
        """Stock height over the points within ``radius_mm`` of the horizontal path, per point.

        Returns the heights of the footprint patch, ``-inf`` outside the footprint (shape of the
        patch); used for holder clearance checks.
        """
        x0, y0, _ = (float(v) for v in np.asarray(start_mm, dtype=float))
        x1, y1, _ = (float(v) for v in np.asarray(end_mm, dtype=float))
        i0, i1, j0, j1 = self._patch(
            min(x0, x1) - radius_mm, max(x0, x1) + radius_mm,
            min(y0, y1) - radius_mm, max(y0, y1) + radius_mm,
        )  # fmt: skip
        if i0 >= i1 or j0 >= j1:
            return np.empty((0, 0))
        h = self.heights_mm[j0:j1, i0:i1]
        env = _k.envelope(
            _k.FLAT, radius_mm, 0.0, self.x_mm[i0:i1] - x0, self._ycol[j0:j1] - y0,
            x1 - x0, y1 - y0, 0.0, 0.0,
        )  # fmt: skip
        return np.where(np.isfinite(env), h, -np.inf)

    # ------------------------------------------------------------------ cutting

    def cut(self, cutter: Cutter, start_mm: ArrayLike, end_mm: ArrayLike) -> float:
        """Move the cutter tip in a straight line from ``start_mm`` to ``end_mm``; removed mm^3."""
        p0 = np.asarray(start_mm, dtype=float).reshape(1, 3)
        p1 = np.asarray(end_mm, dtype=float).reshape(1, 3)
        return float(self.cut_pieces(cutter, p0, p1)[0])

    def cut_path(
        self,
        cutter: Cutter,
        starts_mm: ArrayLike,
        ends_mm: ArrayLike,
        piece_mm: float = math.inf,
        progress: Callable[[int], None] | None = None,
    ) -> PathCut:
        """Cut a sequence of linear moves in order; pieces no longer than ``piece_mm``.

        Parameters
        ----------
        starts_mm, ends_mm : array_like, shape (n, 3), mm
            Tip positions at the start and end of each move.
        piece_mm : float, mm
            Longest piece a move is cut in (the removed volume is reported per piece).
        progress : callable, optional
            Called with the number of pieces done, every 4096 pieces.
        """
        move, p0, p1 = split_pieces(
            np.asarray(starts_mm, float), np.asarray(ends_mm, float), piece_mm
        )
        n = len(np.asarray(starts_mm).reshape(-1, 3))
        removed = self.cut_pieces(cutter, p0, p1, progress)
        # float with weights (numpy's stubs say int); no copy
        per_move = np.bincount(move, weights=removed, minlength=n).astype(np.float64, copy=False)
        return PathCut(move, p0, p1, removed, per_move)

    def cut_pieces(
        self,
        cutter: Cutter,
        starts_mm: NDArray[np.float64],
        ends_mm: NDArray[np.float64],
        progress: Callable[[int], None] | None = None,
        depth_mm: NDArray[np.float64] | None = None,
        arcs: NDArray[np.float32] | None = None,
    ) -> NDArray[np.float64]:
        """Cut linear moves in order as given (no splitting); removed volume per move, mm^3.

        ``depth_mm``, if given (shape (k,)), receives the deepest height drop of each move, mm
        (the axial depth of cut the move met); ``arcs``, if given (shape (k, 3 *
        ``_numba.MAX_ARCS``)), the cutter's engaged arcs at each move's middle before it cuts
        (entry rad, exit rad, depth mm each; NaN: none found, no XY motion, or a ball end mill;
        see ``_numba.leading_arc``).
        """
        p0 = np.asarray(starts_mm, dtype=float).reshape(-1, 3)
        p1 = np.asarray(ends_mm, dtype=float).reshape(-1, 3)
        removed = np.zeros(len(p0))
        kind = _KIND_CODES[cutter.kind]
        r, rc = cutter.radius_mm, cutter.corner_radius_mm
        if arcs is not None and kind == _k.BALL:
            arcs[:] = np.nan  # the periphery at the tip's height is a point: no arc
            arcs = None
        if self.compiled and _numba.AVAILABLE and len(p0):
            pts = np.ascontiguousarray(np.concatenate([p0, p1], axis=1))
            drops = np.zeros(len(p0)) if depth_mm is None else depth_mm
            arcs_out = np.zeros((0, 3 * _numba.MAX_ARCS), np.float32) if arcs is None else arcs
            step = 16384 if progress is not None else len(p0)
            for a in range(0, len(p0), step):
                b = min(a + step, len(p0))
                _numba.cut_pieces(
                    self.heights_mm, self.x0_mm, self.y0_mm, self.spacing_mm, self.bottom_mm,
                    kind, float(r), float(rc), pts[a:b], removed[a:b], drops[a:b], arcs_out[a:b],
                )  # fmt: skip
                if progress is not None:
                    progress(b)
            return removed
        cut_one = self._cut_one
        rows = np.concatenate([p0, p1], axis=1).tolist()  # python floats: cheaper per piece
        track = depth_mm is not None
        arc = _numba.leading_arc
        for k, (x0, y0, z0, x1, y1, z1) in enumerate(rows):
            if arcs is not None:
                arc(self.heights_mm, self.x0_mm, self.y0_mm, self.spacing_mm,
                    x0, y0, z0, x1, y1, z1, r, rc, arcs[k])  # fmt: skip
            removed[k], drop = cut_one(kind, r, rc, x0, y0, z0, x1, y1, z1, track)
            if depth_mm is not None:
                depth_mm[k] = drop
            if progress is not None and k % 4096 == 4095:
                progress(k + 1)
        return removed

    def _cut_one(
        self,
        kind: int,
        r: float,
        rc: float,
        x0: float,
        y0: float,
        z0: float,
        x1: float,
        y1: float,
        z1: float,
        track_drop: bool = False,
    ) -> tuple[float, float]:
        """Lower the grid under one linear move; return (removed volume mm^3, deepest drop mm).

        The deepest height drop (the axial depth of cut met) costs a pass over the patch, so it
        is computed only with ``track_drop`` (else 0).
        """
        i0, i1, j0, j1 = self._patch(
            min(x0, x1) - r, max(x0, x1) + r, min(y0, y1) - r, max(y0, y1) + r
        )
        if i0 >= i1 or j0 >= j1:
            return 0.0, 0.0
        h = self.heights_mm[j0:j1, i0:i1]
        zlow = max(z0 if z0 < z1 else z1, self.bottom_mm)
        if h.max() <= zlow:  # the cutter passes above everything here (air move)
            return 0.0, 0.0
        drop = 0.0
        qx = self.x_mm[i0:i1] - x0
        qy = self._ycol[j0:j1] - y0
        dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
        before = float(h.sum())
        if kind == _k.FLAT and dz == 0.0:
            # Level flat cut, the common roughing move: the envelope is the tip height over the
            # points within R of the path segment. Axis-parallel moves (zigzag roughing) have a
            # separable distance, so most of the work stays 1-D.
            if dy == 0.0:
                ex = qx - np.minimum(np.maximum(qx * (1.0 / dx), 0.0), 1.0) * dx if dx else qx
                d2 = ex * ex + qy * qy
            elif dx == 0.0:
                ey = qy - np.minimum(np.maximum(qy * (1.0 / dy), 0.0), 1.0) * dy
                d2 = qx * qx + ey * ey
            else:
                l2 = dx * dx + dy * dy
                t = qx * (dx / l2) + qy * (dy / l2)
                np.maximum(t, 0.0, out=t)
                np.minimum(t, 1.0, out=t)
                ex = qx - t * dx
                ey = qy - t * dy
                d2 = ex * ex
                d2 += ey * ey
            cut = d2 <= r * r
            cut &= h > zlow
            if track_drop:
                drop = max(float(np.max(h, where=cut, initial=zlow)) - zlow, 0.0)
            np.putmask(h, cut, zlow)  # masked ufuncs (where=) are several times slower
        else:
            env = _k.envelope(kind, r, rc, qx, qy, dx, dy, dz, z0)
            np.maximum(env, self.bottom_mm, out=env)
            if track_drop:
                drop = max(float(np.max(h - env)), 0.0)
            np.minimum(h, env, out=h)
        # h only went down, so the sums' difference is the removed volume (cheaper than
        # summing a difference array; the rounding is ~1e-16 of the patch's sum)
        removed = max(before - float(h.sum()), 0.0)
        return removed * self.spacing_mm * self.spacing_mm, drop
