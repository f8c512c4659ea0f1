"""Ferguson (bicubic Hermite) composite surfaces built from a grid of points (seed 000, 2.1-2.2).

One Ferguson patch is ``r(u, v) = sum_ij a_ij u^i v^j`` with ``u, v`` in ``[0, 1]``; its 16 vector
coefficients follow from the positions, the ``u``- and ``v``-tangents and the twist vectors at its
four corner grid points (Hermite form ``r = H(u)^T G H(v)``). A composite surface is the grid of
such patches sharing corner data, so it is C1 across patch edges.

Tangents and twists come from the grid itself: each grid line is interpolated by a not-a-knot cubic
spline in the grid index (scipy ``CubicSpline``), whose derivative gives the tangent at the grid
points; the twist is the derivative of the ``u``-tangents along ``v``. This is the classic way of
setting a Ferguson net from points only (Faux & Pratt); the composite surface then interpolates
every grid point and is C2 along grid lines.

Parameters are *global*: ``s`` in ``[0, nu - 1]`` and ``t`` in ``[0, nv - 1]``; patch ``(i, j)`` is
``s`` in ``[i, i + 1]``, ``t`` in ``[j, j + 1]``. Lengths are mm.

The surface of a 3-axis part must be a graph over the xy plane: :func:`FergusonSurface.from_points`
rejects grids whose projection folds (the xy Jacobian changes sign or vanishes), NaNs and grids
smaller than 2 x 2. Normals point up (to the side the tool comes from).

Other inputs labs have: a height field on a rectilinear grid (:meth:`from_height_field`) and an STL
mesh sampled by vertical rays through trimesh (:meth:`from_stl`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

from planning.errors import PlanningError

# Hermite basis as a matrix: H(u) = M @ [1, u, u^2, u^3]. Rows: h0 (P0), h1 (P1), h2 (T0), h3 (T1).
_M: npt.NDArray[np.float64] = np.array(
    [
        [1.0, 0.0, -3.0, 2.0],
        [0.0, 0.0, 3.0, -2.0],
        [0.0, 1.0, -2.0, 1.0],
        [0.0, 0.0, -1.0, 1.0],
    ]
)


def _basis(u: npt.NDArray[np.float64], order: int) -> npt.NDArray[np.float64]:
    """Hermite basis values (order 0) or derivatives (1, 2) at ``u``; shape (n, 4)."""
    one, zero = np.ones_like(u), np.zeros_like(u)
    if order == 0:
        mono = np.stack([one, u, u * u, u**3], axis=1)
    elif order == 1:
        mono = np.stack([zero, one, 2 * u, 3 * u * u], axis=1)
    else:
        mono = np.stack([zero, zero, 2 * one, 6 * u], axis=1)
    return mono @ _M.T


def _spline_derivative(values: npt.NDArray[np.float64], axis: int) -> npt.NDArray[np.float64]:
    """d/d(index) of a not-a-knot cubic spline through ``values`` along ``axis`` (2: chord)."""
    n = values.shape[axis]
    if n == 2:
        d = np.diff(values, axis=axis)
        return np.concatenate([d, d], axis=axis)
    bc: Literal["not-a-knot", "natural"] = "not-a-knot" if n > 3 else "natural"
    slope: npt.NDArray[np.float64] = CubicSpline(
        np.arange(n, dtype=float), values, axis=axis, bc_type=bc
    )(np.arange(n, dtype=float), 1)
    return slope


@dataclass(frozen=True, eq=False)
class FergusonSurface:
    """A composite Ferguson surface over an ``nu x nv`` grid (``(nu-1) x (nv-1)`` patches).

    Attributes
    ----------
    points : ndarray, shape (nu, nv, 3), mm — the grid points the surface interpolates.
    r_u, r_v : ndarray, shape (nu, nv, 3), mm per unit parameter — tangents at the grid points.
    r_uv : ndarray, shape (nu, nv, 3) — twist vectors at the grid points.
    up : float — +1 or -1, the sign making ``up * (r_u x r_v)`` point to +z.
    """

    points: npt.NDArray[np.float64]
    r_u: npt.NDArray[np.float64]
    r_v: npt.NDArray[np.float64]
    r_uv: npt.NDArray[np.float64]
    up: float = 1.0

    # -------------------------------------------------------------------------------- building
    @classmethod
    def from_points(
        cls, points: npt.NDArray[np.float64], *, where: str = "surface grid"
    ) -> FergusonSurface:
        """Fit the composite surface through a grid of points, shape (nu, nv, 3), mm.

        Raises PlanningError for a grid that is too small, holds NaN/inf, or folds over itself
        in xy (not machinable from above with 3 axes).
        """
        p = np.asarray(points, dtype=float)
        if p.ndim != 3 or p.shape[2] != 3 or p.shape[0] < 2 or p.shape[1] < 2:
            raise PlanningError(
                f"{where}: points have shape {p.shape}; expected (nu >= 2, nv >= 2, 3) in mm"
            )
        bad = np.argwhere(~np.isfinite(p))
        if bad.size:
            i, j, k = bad[0]
            raise PlanningError(
                f"{where}: point [{i}, {j}] {'xyz'[k]} = {p[i, j, k]}: every grid coordinate "
                f"must be a finite number in mm ({len(bad)} bad values)"
            )
        r_u = _spline_derivative(p, 0)
        r_v = _spline_derivative(p, 1)
        r_uv = _spline_derivative(r_u, 1)
        surf = cls(p, r_u, r_v, r_uv, 1.0)
        up = surf._check_folds(where)
        return cls(p, r_u, r_v, r_uv, up)

    @classmethod
    def from_height_field(
        cls,
        x_mm: npt.NDArray[np.float64],
        y_mm: npt.NDArray[np.float64],
        z_mm: npt.NDArray[np.float64],
        *,
        where: str = "height field",
    ) -> FergusonSurface:
        """Surface through heights ``z_mm[i, j]`` at ``(x_mm[i], y_mm[j])``; x, y increasing."""
        x, y, z = (np.asarray(a, dtype=float) for a in (x_mm, y_mm, z_mm))
        if x.ndim != 1 or y.ndim != 1 or z.shape != (x.size, y.size):
            raise PlanningError(
                f"{where}: z_mm has shape {z.shape}; expected (len(x_mm), len(y_mm)) = "
                f"({x.size}, {y.size})"
            )
        for name, a in (("x_mm", x), ("y_mm", y)):
            if a.size < 2 or not np.all(np.diff(a) > 0):
                raise PlanningError(
                    f"{where}: {name} = {a.tolist()[:6]}...: needs >= 2 strictly increasing values"
                )
        gx, gy = np.meshgrid(x, y, indexing="ij")
        return cls.from_points(np.stack([gx, gy, z], axis=2), where=where)

    @classmethod
    def from_stl(cls, path: str | Path, spacing_mm: float) -> FergusonSurface:
        """Sample the top of an STL part on a grid about ``spacing_mm`` apart and fit a surface.

        The top-most triangle over each grid point is found by planning.stock.zmap's mesh rasteriser
        (trimesh loads the file; its own ray queries would need rtree or embree). The grid spans
        the mesh's xy bounds exactly; where no triangle covers a point the height is the mesh's
        lowest z (the part stands on that plane).
        """
        import trimesh

        from planning.stock import ZMap

        if not np.isfinite(spacing_mm) or not spacing_mm > 0:
            raise PlanningError(f"{path}: spacing_mm = {spacing_mm}: must be > 0 (mm)")
        try:
            mesh = trimesh.load_mesh(str(path), force="mesh")
        except Exception as exc:  # trimesh raises many kinds for unreadable files
            raise PlanningError(f"{path}: cannot read STL part: {exc}") from None
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise PlanningError(f"{path}: STL part has no triangles")
        (x0, y0, _), (x1, y1, _) = mesh.bounds
        # One spacing per axis that divides the extent, so the grid reaches both edges.
        nx = max(int(round((x1 - x0) / spacing_mm)), 1)
        ny = max(int(round((y1 - y0) / spacing_mm)), 1)
        sx, sy = (x1 - x0) / nx, (y1 - y0) / ny
        s = min(sx, sy)
        zm = ZMap.from_mesh(mesh, s, margin_mm=s / 2)
        x = np.linspace(x0, x1, nx + 1)
        y = np.linspace(y0, y1, ny + 1)
        # Heights at the grid nodes from the Z-map cells (nearest cell centre).
        z = zm.height_at(*np.meshgrid(x, y, indexing="ij"))
        if not np.all(np.isfinite(z)):
            raise PlanningError(f"{path}: could not sample the STL top on a {s:.3g} mm grid")
        return cls.from_height_field(x, y, z, where=str(path))

    def _check_folds(self, where: str) -> float:
        """+1/-1 orientation of the xy projection; PlanningError where it folds or degenerates."""
        k = 4
        s, t = self.param_grid(k)
        _, rs, rt = self.derivatives(s.ravel(), t.ravel())
        det = (rs[:, 0] * rt[:, 1] - rs[:, 1] * rt[:, 0]).reshape(s.shape)
        scale = np.sqrt(np.sum(rs[:, :2] ** 2, 1) * np.sum(rt[:, :2] ** 2, 1)).reshape(s.shape)
        sign = 1.0 if np.sum(det > 0) >= np.sum(det < 0) else -1.0
        badmask = sign * det <= 1e-9 * np.maximum(scale, 1e-300)
        if badmask.any():
            a, b = np.argwhere(badmask)[0]
            i, j = min(int(s[a, b]), self.nu - 2), min(int(t[a, b]), self.nv - 2)
            x, y = self.evaluate(np.array([s[a, b]]), np.array([t[a, b]]))[0, :2]
            raise PlanningError(
                f"{where}: the grid folds over itself in xy at patch [{i}, {j}] near "
                f"x = {x:.3f} mm, y = {y:.3f} mm (xy Jacobian {det[a, b]:.3g}, "
                f"{int(badmask.sum())} of {badmask.size} samples): a 3-axis part surface must be "
                "a graph z(x, y) with grid rows and columns that do not cross"
            )
        return sign

    # ------------------------------------------------------------------------------ properties
    @property
    def nu(self) -> int:
        return int(self.points.shape[0])

    @property
    def nv(self) -> int:
        return int(self.points.shape[1])

    @property
    def s_max(self) -> float:
        return float(self.nu - 1)

    @property
    def t_max(self) -> float:
        return float(self.nv - 1)

    def param_grid(self, per_patch: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Global parameters of a dense net, ``per_patch`` steps per patch; shapes (m_u, m_v)."""
        su = np.linspace(0.0, self.s_max, (self.nu - 1) * per_patch + 1)
        tv = np.linspace(0.0, self.t_max, (self.nv - 1) * per_patch + 1)
        return np.meshgrid(su, tv, indexing="ij")

    # ------------------------------------------------------------------------------ evaluation
    def _gather(
        self, s: npt.NDArray[np.float64], t: npt.NDArray[np.float64]
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Hermite geometry matrices G, shape (n, 4, 4, 3), and local u, v for global s, t."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.s_max)
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.t_max)
        i = np.minimum(np.floor(s).astype(np.intp), self.nu - 2)
        j = np.minimum(np.floor(t).astype(np.intp), self.nv - 2)
        u, v = s - i, t - j
        P, Ru, Rv, Ruv = self.points, self.r_u, self.r_v, self.r_uv
        i1, j1 = i + 1, j + 1
        G = np.stack(
            [
                np.stack([P[i, j], P[i, j1], Rv[i, j], Rv[i, j1]], 1),
                np.stack([P[i1, j], P[i1, j1], Rv[i1, j], Rv[i1, j1]], 1),
                np.stack([Ru[i, j], Ru[i, j1], Ruv[i, j], Ruv[i, j1]], 1),
                np.stack([Ru[i1, j], Ru[i1, j1], Ruv[i1, j], Ruv[i1, j1]], 1),
            ],
            1,
        )
        return G, u, v

    def evaluate(
        self, s: npt.NDArray[np.float64], t: npt.NDArray[np.float64]
    ) -> npt.NDArray[np.float64]:
        """Points r(s, t), shape (n, 3) mm, for global parameters of shape (n,)."""
        G, u, v = self._gather(np.ravel(s), np.ravel(t))
        r: npt.NDArray[np.float64] = np.einsum("na,nabk,nb->nk", _basis(u, 0), G, _basis(v, 0))
        return r

    def derivatives(
        self, s: npt.NDArray[np.float64], t: npt.NDArray[np.float64]
    ) -> tuple[npt.NDArray[np.float64], ...]:
        """(r, r_s, r_t), each shape (n, 3): point and first derivatives (mm per unit parameter)."""
        G, u, v = self._gather(np.ravel(s), np.ravel(t))
        bu0, bu1, bv0, bv1 = _basis(u, 0), _basis(u, 1), _basis(v, 0), _basis(v, 1)
        r = np.einsum("na,nabk,nb->nk", bu0, G, bv0)
        rs = np.einsum("na,nabk,nb->nk", bu1, G, bv0)
        rt = np.einsum("na,nabk,nb->nk", bu0, G, bv1)
        return r, rs, rt

    def normals(
        self, s: npt.NDArray[np.float64], t: npt.NDArray[np.float64]
    ) -> npt.NDArray[np.float64]:
        """Unit normals n = (s x t) / |s x t| (seed 000 2.2), turned to point up; shape (n, 3)."""
        _, rs, rt = self.derivatives(s, t)
        n = np.cross(rs, rt) * self.up
        norm = np.linalg.norm(n, axis=1, keepdims=True)
        if np.any(norm == 0):
            raise PlanningError("surface normal undefined: degenerate tangents (|s x t| = 0)")
        unit: npt.NDArray[np.float64] = n / norm
        return unit

    def grid_normals(self) -> npt.NDArray[np.float64]:
        """Unit normals at the grid points, shape (nu, nv, 3)."""
        gs, gt = np.meshgrid(np.arange(self.nu, dtype=float), np.arange(self.nv, dtype=float))
        n = self.normals(gs.T.ravel(), gt.T.ravel())
        return n.reshape(self.nu, self.nv, 3)

    def offset(self, distance_mm: float) -> FergusonSurface:
        """The offset surface by ``distance_mm`` along the up normal (seed 000 2.2).

        Each grid point moves along its unit normal, and a new composite surface is fitted through
        the moved points, as the paper does. Between grid points the result approximates the
        exact offset r + d n to the interpolation error of the net.
        """
        if not np.isfinite(distance_mm) or distance_mm < 0:
            raise PlanningError(f"offset distance = {distance_mm}: must be >= 0 (mm)")
        moved = self.points + distance_mm * self.grid_normals()
        return FergusonSurface.from_points(moved, where=f"offset surface (d = {distance_mm} mm)")

    def sample(self, per_patch: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Dense points and unit normals, shapes (m_u, m_v, 3) each."""
        s, t = self.param_grid(per_patch)
        _, rs, rt = self.derivatives(s.ravel(), t.ravel())
        r = self.evaluate(s.ravel(), t.ravel())
        n = np.cross(rs, rt) * self.up
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return r.reshape(*s.shape, 3), n.reshape(*s.shape, 3)

    def locate(
        self, x_mm: npt.NDArray[np.float64], y_mm: npt.NDArray[np.float64], iterations: int = 10
    ) -> npt.NDArray[np.float64]:
        """Global parameters (n, 2) of the surface points above (x, y); NaN off the surface.

        Newton steps on the xy map from the nearest point of a dense net (a KD-tree); the xy map
        is one-to-one because folds are refused at construction.
        """
        from scipy.spatial import cKDTree

        if not hasattr(self, "_net"):
            s, t = self.param_grid(4)
            p = self.evaluate(s.ravel(), t.ravel())
            object.__setattr__(self, "_net", (cKDTree(p[:, :2]), s.ravel(), t.ravel()))
        # attr-defined: _net is cached on the frozen instance just above, on first use
        tree, ns, nt = self._net  # type: ignore[attr-defined]
        q = np.stack([np.ravel(x_mm), np.ravel(y_mm)], 1).astype(float)
        _, i = tree.query(q)
        s, t = ns[i].copy(), nt[i].copy()
        for _ in range(iterations):
            r, rs, rt = self.derivatives(s, t)
            fx, fy = r[:, 0] - q[:, 0], r[:, 1] - q[:, 1]
            det = rs[:, 0] * rt[:, 1] - rs[:, 1] * rt[:, 0]
            ds = (fx * rt[:, 1] - fy * rt[:, 0]) / det
            dt = (fy * rs[:, 0] - fx * rs[:, 1]) / det
            s = np.clip(s - ds, 0.0, self.s_max)
            t = np.clip(t - dt, 0.0, self.t_max)
        r = self.evaluate(s, t)
        off = np.hypot(r[:, 0] - q[:, 0], r[:, 1] - q[:, 1]) > 1e-6
        st = np.stack([s, t], 1)
        st[off] = np.nan
        return st

    def height_at(
        self, x_mm: npt.NDArray[np.float64], y_mm: npt.NDArray[np.float64]
    ) -> npt.NDArray[np.float64]:
        """z of the surface above each (x, y), mm, same shape as x; NaN off the surface."""
        st = self.locate(x_mm, y_mm)
        ok = np.isfinite(st[:, 0])
        z = np.full(len(st), np.nan)
        z[ok] = self.evaluate(st[ok, 0], st[ok, 1])[:, 2]
        return z.reshape(np.shape(x_mm))

    def bounds_xy(self, per_patch: int = 8) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the surface, mm."""
        p, _ = self.sample(per_patch)
        return (
            float(p[..., 0].min()),
            float(p[..., 0].max()),
            float(p[..., 1].min()),
            float(p[..., 1].max()),
        )
