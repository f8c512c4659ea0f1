"""NURBS part surfaces for 5-axis planning (seed 002 section 5): points, normals, curvature, paths.

The evaluation itself is splipy's (a maintained, vectorised B-spline library). One workaround: in
splipy 1.10 the pointwise (``tensor=False``) derivative of a *rational* surface fails with an
IndexError, so a rational surface is evaluated as its non-rational homogeneous surface
(``w x, w y, w z, w``) and the rational derivatives up to second order are formed here with the
quotient rule (Piegl & Tiller, The NURBS Book, eq 4.20), all vectorised over the points.

Conventions: parameters ``u, v`` are in the surface's own knot range; the unit normal is
``n = (S_u x S_v) / |S_u x S_v|`` times ``orientation`` (+1 or -1), chosen so that ``n`` points
out of the material, towards the tool. The normal curvature in a tangent direction ``t`` is
``kappa = II(t) / I(t)``; it is positive where the surface bends towards ``n`` (a concave floor
seen by the tool) and negative where it bends away (a convex bump).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from splipy.basis import BSplineBasis
from splipy.surface import Surface

from planning.errors import PlanningError

# |S_u x S_v| below this (mm^2 per unit parameter^2) means no tangent plane: no normal to cut along.
DEGENERATE_NORMAL_MM2 = 1e-9


@dataclass(frozen=True)
class SurfacePoints:
    """Positions and first/second derivatives at n parameter pairs (all arrays shape (n, 3), mm).

    ``normal`` is the unit normal (orientation applied), ``kappa_*`` come from
    :meth:`NurbsSurface.normal_curvature`.
    """

    u: npt.NDArray[np.float64]
    v: npt.NDArray[np.float64]
    point: npt.NDArray[np.float64]
    su: npt.NDArray[np.float64]
    sv: npt.NDArray[np.float64]
    suu: npt.NDArray[np.float64]
    suv: npt.NDArray[np.float64]
    svv: npt.NDArray[np.float64]
    normal: npt.NDArray[np.float64]


class NurbsSurface:
    """A (possibly rational) tensor-product NURBS surface in mm.

    Parameters
    ----------
    degree : (p, q)
    knots_u, knots_v : full knot vectors (length n_u + p + 1, n_v + q + 1)
    control_points_mm : array, shape (n_u, n_v, 3), mm
    weights : array, shape (n_u, n_v), > 0, or None (non-rational)
    orientation : +1 or -1, flips the normal so that it points towards the tool
    name : used in error messages
    """

    def __init__(
        self,
        degree: tuple[int, int],
        knots_u: npt.NDArray[np.float64],
        knots_v: npt.NDArray[np.float64],
        control_points_mm: npt.NDArray[np.float64],
        weights: npt.NDArray[np.float64] | None = None,
        orientation: int = 1,
        name: str = "surface",
    ) -> None:
        cp = np.asarray(control_points_mm, dtype=float)
        if cp.ndim != 3 or cp.shape[2] != 3:
            raise PlanningError(
                f"{name}: control_points_mm has shape {cp.shape}, expected (nu, nv, 3)"
            )
        p, q = degree
        ku, kv = np.asarray(knots_u, float), np.asarray(knots_v, float)
        for label, k, n, d in (("knots_u", ku, cp.shape[0], p), ("knots_v", kv, cp.shape[1], q)):
            if len(k) != n + d + 1:
                raise PlanningError(
                    f"{name}: {label} has {len(k)} knots; {n} control points of degree {d} "
                    f"need {n + d + 1}"
                )
            if np.any(np.diff(k) < 0):
                raise PlanningError(f"{name}: {label} must be non-decreasing, got {k.tolist()}")
        w = np.ones(cp.shape[:2]) if weights is None else np.asarray(weights, float)
        if w.shape != cp.shape[:2] or np.any(w <= 0):
            raise PlanningError(f"{name}: weights must be > 0 with shape {cp.shape[:2]}")
        self.name = name
        self.orientation = 1 if orientation >= 0 else -1
        self.rational = weights is not None and not np.allclose(w, 1.0)
        self.degree = (p, q)
        bu, bv = BSplineBasis(p + 1, ku), BSplineBasis(q + 1, kv)
        hom = np.concatenate([cp * w[..., None], w[..., None]], axis=2)
        # splipy lists control points with the first parameter running fastest.
        self._hom = Surface(bu, bv, hom.transpose(1, 0, 2).reshape(-1, 4), rational=False)
        self.u_range = (float(ku[p]), float(ku[-p - 1]))
        self.v_range = (float(kv[q]), float(kv[-q - 1]))
        self.control_points_mm = cp

    # ------------------------------------------------------------------------------------------
    def _clip(
        self, u: npt.NDArray[np.float64], v: npt.NDArray[np.float64]
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        u = np.clip(np.atleast_1d(np.asarray(u, float)), *self.u_range)
        v = np.clip(np.atleast_1d(np.asarray(v, float)), *self.v_range)
        u_b, v_b = np.broadcast_arrays(u, v)
        return u_b, v_b

    def _h(
        self, u: npt.NDArray[np.float64], v: npt.NDArray[np.float64], d: tuple[int, int]
    ) -> npt.NDArray[np.float64]:
        if d == (0, 0):
            return np.asarray(self._hom(u, v, tensor=False)).reshape(-1, 4)
        return np.asarray(self._hom.derivative(u, v, d=d, tensor=False)).reshape(-1, 4)

    def evaluate(
        self, u: npt.NDArray[np.float64], v: npt.NDArray[np.float64], normals: bool = True
    ) -> SurfacePoints:
        """Points and derivatives up to second order at paired parameters (shape (n,) each).

        Raises PlanningError naming the first point whose normal is degenerate
        (|S_u x S_v| < 1e-9 mm^2), e.g. a collapsed row of control points.
        """
        u, v = self._clip(u, v)
        u, v = u.ravel(), v.ravel()
        A = self._h(u, v, (0, 0))
        Au, Av = self._h(u, v, (1, 0)), self._h(u, v, (0, 1))
        Auu, Auv, Avv = self._h(u, v, (2, 0)), self._h(u, v, (1, 1)), self._h(u, v, (0, 2))
        w = A[:, 3:]
        S = A[:, :3] / w
        # Quotient rule for rational derivatives (NURBS Book eq 4.20); exact when w == 1.
        Su = (Au[:, :3] - Au[:, 3:] * S) / w
        Sv = (Av[:, :3] - Av[:, 3:] * S) / w
        Suu = (Auu[:, :3] - 2 * Au[:, 3:] * Su - Auu[:, 3:] * S) / w
        Svv = (Avv[:, :3] - 2 * Av[:, 3:] * Sv - Avv[:, 3:] * S) / w
        Suv = (Auv[:, :3] - Au[:, 3:] * Sv - Av[:, 3:] * Su - Auv[:, 3:] * S) / w
        nrm = np.full_like(S, np.nan)
        if normals:
            c = np.cross(Su, Sv)
            length = np.linalg.norm(c, axis=1)
            bad = np.flatnonzero(~(length > DEGENERATE_NORMAL_MM2))
            if bad.size:
                i = int(bad[0])
                raise PlanningError(
                    f"{self.name}: degenerate normal at u = {u[i]:.6g}, v = {v[i]:.6g} "
                    f"(point {np.round(S[i], 4).tolist()} mm): |S_u x S_v| = {length[i]:.3g} "
                    f"mm^2 < {DEGENERATE_NORMAL_MM2:g}; {bad.size} of {len(u)} points affected "
                    "(collapsed control-point row or zero-length edge)"
                )
            nrm = self.orientation * c / length[:, None]
        return SurfacePoints(u, v, S, Su, Sv, Suu, Suv, Svv, nrm)

    def points(
        self, u: npt.NDArray[np.float64], v: npt.NDArray[np.float64]
    ) -> npt.NDArray[np.float64]:
        """Positions at paired parameters, shape (n, 3), mm."""
        u, v = self._clip(u, v)
        A = self._h(u.ravel(), v.ravel(), (0, 0))
        return A[:, :3] / A[:, 3:]

    @staticmethod
    def normal_curvature(
        sp: SurfacePoints, direction: npt.NDArray[np.float64]
    ) -> npt.NDArray[np.float64]:
        """Normal curvature (1/mm) along tangent ``direction`` (shape (n, 3), need not be unit).

        The direction is projected on the tangent plane and written as ``t = S_u du + S_v dv``
        (least squares); kappa = (L du^2 + 2 M du dv + N dv^2) / (E du^2 + 2 F du dv + G dv^2).
        """
        n = sp.normal
        t = direction - (direction * n).sum(1)[:, None] * n
        E, F, G = (sp.su * sp.su).sum(1), (sp.su * sp.sv).sum(1), (sp.sv * sp.sv).sum(1)
        L, M, N = (sp.suu * n).sum(1), (sp.suv * n).sum(1), (sp.svv * n).sum(1)
        # Solve the 2x2 normal equations [E F; F G] [du dv] = [t.Su t.Sv] for every point.
        a, b = (t * sp.su).sum(1), (t * sp.sv).sum(1)
        det = E * G - F * F
        du = (G * a - F * b) / det
        dv = (E * b - F * a) / det
        first = E * du * du + 2 * F * du * dv + G * dv * dv
        second = L * du * du + 2 * M * du * dv + N * dv * dv
        kappa: npt.NDArray[np.float64] = second / first
        return kappa

    # ------------------------------------------------------------------------------------------
    def grid(self, n_u: int, n_v: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Parameter grid (n_u, n_v) covering the surface, each array shape (n_u * n_v,)."""
        uu = np.linspace(*self.u_range, n_u)
        vv = np.linspace(*self.v_range, n_v)
        U, V = np.meshgrid(uu, vv, indexing="ij")
        return U.ravel(), V.ravel()

    def size_mm(self) -> tuple[float, float]:
        """Approximate lengths of the surface along u and v (longest iso-line), mm."""
        U, V = self.grid(33, 33)
        P = self.points(U, V).reshape(33, 33, 3)
        lu = np.linalg.norm(np.diff(P, axis=0), axis=2).sum(0).max()
        lv = np.linalg.norm(np.diff(P, axis=1), axis=2).sum(1).max()
        return float(lu), float(lv)

    def triangulate(
        self, spacing_mm: float
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """A triangle mesh with edges about ``spacing_mm`` long.

        Returns vertices (m, 3) mm, all exactly on the surface, and faces (k, 3) int.
        """
        lu, lv = self.size_mm()
        n_u = max(2, int(np.ceil(lu / spacing_mm)) + 1)
        n_v = max(2, int(np.ceil(lv / spacing_mm)) + 1)
        U, V = self.grid(n_u, n_v)
        verts = self.points(U, V)
        idx = np.arange(n_u * n_v).reshape(n_u, n_v)
        a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
        c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
        faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
        if self.orientation < 0:
            faces = faces[:, ::-1]
        return verts, faces

    def iso_path(
        self, along: str, fixed: float, n_points: int, span: tuple[float, float] = (0.0, 1.0)
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """CC points along one iso-parameter line (the seed's CC paths).

        ``along`` "u": v = ``fixed`` and u runs over ``span`` (fractions of the u range);
        "v": the other way. ``fixed`` is a fraction of the other range. Returns (u, v), each
        shape (n_points,).
        """
        t = np.linspace(span[0], span[1], n_points)
        (u0, u1), (v0, v1) = self.u_range, self.v_range
        if along == "u":
            return u0 + t * (u1 - u0), np.full(n_points, v0 + fixed * (v1 - v0))
        if along == "v":
            return np.full(n_points, u0 + fixed * (u1 - u0)), v0 + t * (v1 - v0)
        raise PlanningError(f"path direction along = {along!r}: expected 'u' or 'v'")


def clamped_uniform_knots(n_ctrl: int, degree: int) -> npt.NDArray[np.float64]:
    """Open uniform knot vector on [0, 1] for ``n_ctrl`` control points of ``degree``."""
    inner = np.linspace(0.0, 1.0, n_ctrl - degree + 1)
    return np.concatenate([np.zeros(degree), inner, np.ones(degree)])
