"""Swept-envelope kernels of the Z-map: the lowest cutter point over grid points for one move.

Private to :mod:`planning.stock.zmap`. Every function works on one move from tool tip ``A`` to tool
tip ``B`` and on a rectangular patch of grid points given as broadcastable offsets from ``A``:
``qx`` shape (1, m) and ``qy`` shape (n, 1), mm. They return the envelope, shape (n, m), mm, the
lowest height any point of the cutter reaches above each grid point during the move, ``+inf`` where
the cutter never passes over the point.

Geometry. The cutter is axisymmetric about a vertical axis, with tip at the programmed point. Its
lower surface at horizontal distance ``rho`` from the axis is ``f(rho)`` above the tip: flat
``0``; ball ``R - sqrt(R^2 - rho^2)``; bull (torus, corner radius ``rc``, flat radius
``a = R - rc``) ``0`` for ``rho <= a`` and ``rc - sqrt(rc^2 - (rho - a)^2)`` beyond; outside ``R``
the cutter is not over the point. Along the move the tip is ``A + t (B - A)``, ``t`` in [0, 1].
With ``tp`` the projection parameter of a grid point on the horizontal path and ``w`` its
perpendicular distance, ``rho(t)^2 = w^2 + L^2 (t - tp)^2``, so the height of the cutter over the
point, ``g(t) = z_A + t dz + f(rho(t))``, is convex in ``t`` (a convex increasing profile of a
convex distance plus a linear term). Its minimum over the interval where ``rho <= R`` is therefore:

- flat: at an end of that interval (``g`` is linear there);
- ball: Choi's closed form (seed 001 Fig. 3), the contact station ``c = l - t sin(phi)`` clamped to
  the move, which also covers the spherical end caps;
- bull: horizontal moves at ``t = clip(tp)``; ramps by bisection on the sign of ``g'`` (the
  torus sweep has no closed form the cost of which beats 40 vectorised halvings).

Vertical moves (plunges, retracts) leave the cutter's own shape at the lower end point.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FLAT, BALL, BULL = 0, 1, 2
_BISECT_ITERATIONS = 48  # interval shrinks 2^-48: far below any grid spacing


def profile_mm(
    kind: int, r_mm: float, rc_mm: float, rho2: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Height of the cutter's lower surface above its tip at squared radius ``rho2`` (mm^2), mm.

    ``+inf`` outside the cutter radius. Shape of ``rho2``.
    """
    out = np.full(np.shape(rho2), np.inf)
    inside = rho2 <= r_mm * r_mm
    if kind == FLAT:
        out[inside] = 0.0
    elif kind == BALL:
        out[inside] = r_mm - np.sqrt(r_mm * r_mm - rho2[inside])
    else:
        a = r_mm - rc_mm
        rho = np.sqrt(rho2[inside])
        e = np.maximum(rho - a, 0.0)
        out[inside] = rc_mm - np.sqrt(np.maximum(rc_mm * rc_mm - e * e, 0.0))
    return out


def envelope(
    kind: int,
    r_mm: float,
    rc_mm: float,
    qx: NDArray[np.float64],
    qy: NDArray[np.float64],
    dx: float,
    dy: float,
    dz: float,
    za: float,
) -> NDArray[np.float64]:
    """Lowest cutter height over each grid point for the move A -> A + (dx, dy, dz), mm.

    Parameters
    ----------
    kind : FLAT, BALL or BULL
    r_mm, rc_mm : cutter radius and corner radius, mm
    qx, qy : arrays broadcasting to (n, m), mm, grid point offsets from the start tip A
    dx, dy, dz : move vector, mm
    za : tip height at the start, mm

    Returns
    -------
    env : ndarray, shape (n, m), mm (``+inf`` where the cutter never passes over a point)
    """
    l2 = dx * dx + dy * dy
    r2 = r_mm * r_mm
    if l2 <= 1e-18:  # plunge or retract: the cutter's own shape at the lower end
        return min(za, za + dz) + profile_mm(kind, r_mm, rc_mm, qx * qx + qy * qy)
    inv_l2 = 1.0 / l2
    # Projection parameter on the horizontal path and the cross product giving the distance to
    # it; axis-parallel moves keep them 1-D (broadcasting does the rest), a large saving.
    if dy == 0.0:
        tp, cross = qx * (dx * inv_l2), qy * -dx
    elif dx == 0.0:
        tp, cross = qy * (dy * inv_l2), qx * dy
    else:
        tp = qx * (dx * inv_l2) + qy * (dy * inv_l2)
        cross = qx * dy - qy * dx
    w2 = cross * cross * inv_l2  # squared perpendicular distance to the path line
    k2 = r2 - w2
    reach = k2 >= -1e-12 * r2  # points exactly on the rim count, despite rounding
    k2 = np.maximum(k2, 0.0)
    hw = np.sqrt(k2 * inv_l2)  # half-width in t of the interval where rho <= R
    lo = np.maximum(tp - hw, 0.0)
    hi = np.minimum(tp + hw, 1.0)
    valid = reach & (lo <= hi + 1e-12)
    hi = np.maximum(hi, lo)
    if kind == FLAT:
        t = lo if dz >= 0 else hi
        env = za + t * dz
    elif kind == BALL:
        env = _choi_ball(r_mm, tp, w2, k2, l2, dz, za)
    else:
        env = _bull(r_mm, rc_mm, tp, w2, lo, hi, l2, dz, za)
    return np.where(valid, env, np.inf)


def _choi_ball(
    r_mm: float,
    tp: NDArray[np.float64],
    w2: NDArray[np.float64],
    k2: NDArray[np.float64],
    l2: float,
    dz: float,
    za: float,
) -> NDArray[np.float64]:
    """Choi's swept-sphere formula (seed 001 Fig. 3), in tip coordinates, with the end caps.

    Choi's names: ``d_p`` horizontal length, ``l`` station of the grid point along the path, ``w``
    its distance from the path, ``phi = atan(dz / d_p)``, ``t = r sin(theta) = sqrt(r^2 - w^2)``,
    ``h = t sin(phi)``, contact station ``c = l - h`` and ``z_n = z_i + c tan(phi) - t cos(phi)``
    (``z_i`` the ball centre). A contact station outside [0, d_p] means the lowest point lies on an
    end sphere; clamping ``c`` there and evaluating the sphere gives it, since the height over the
    point is convex along the move.
    """
    d_p = math.sqrt(l2)
    phi = math.atan2(dz, d_p)
    t_ = np.sqrt(k2)
    c = tp * d_p - t_ * math.sin(phi)
    c = np.clip(c, 0.0, d_p)
    off = c - tp * d_p  # station offset from the foot of the perpendicular, mm
    zc = za + r_mm + c * (dz / d_p)  # ball centre height at the contact station
    return zc - np.sqrt(np.maximum(k2 - off * off, 0.0))


def _bull(
    r_mm: float,
    rc_mm: float,
    tp: NDArray[np.float64],
    w2: NDArray[np.float64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    l2: float,
    dz: float,
    za: float,
) -> NDArray[np.float64]:
    """Torus sweep: minimise the convex g(t) on [lo, hi] (closed form when the move is level)."""
    a = r_mm - rc_mm

    def g(t: NDArray[np.float64]) -> NDArray[np.float64]:
        rho = np.sqrt(w2 + l2 * (t - tp) ** 2)
        e = np.maximum(rho - a, 0.0)
        return za + t * dz + rc_mm - np.sqrt(np.maximum(rc_mm * rc_mm - e * e, 0.0))

    if dz == 0.0:
        return g(np.clip(tp, lo, hi))
    lo = lo.copy()
    hi = hi.copy()
    for _ in range(_BISECT_ITERATIONS):
        mid = 0.5 * (lo + hi)
        s = mid - tp
        rho = np.sqrt(w2 + l2 * s * s)
        e = np.maximum(rho - a, 0.0)
        root = np.sqrt(np.maximum(rc_mm * rc_mm - e * e, 1e-300))
        slope = dz + np.where(rho > 0, (e / root) * (l2 * s / np.maximum(rho, 1e-300)), 0.0)
        up = slope > 0  # minimum lies left of mid
        hi = np.where(up, mid, hi)
        lo = np.where(up, lo, mid)
    return g(0.5 * (lo + hi))


def envelope_sampled(
    kind: int,
    r_mm: float,
    rc_mm: float,
    qx: NDArray[np.float64],
    qy: NDArray[np.float64],
    dx: float,
    dy: float,
    dz: float,
    za: float,
    samples: int,
) -> NDArray[np.float64]:
    """Reference envelope by placing the cutter at ``samples`` positions along the move.

    Converges to :func:`envelope` from above as ``samples`` grows; used by tests as an independent
    check (it shares only the cutter profile).
    """
    env = np.full(np.broadcast_shapes(np.shape(qx), np.shape(qy)), np.inf)
    for t in np.linspace(0.0, 1.0, samples):
        ex, ey = qx - t * dx, qy - t * dy
        env = np.minimum(env, za + t * dz + profile_mm(kind, r_mm, rc_mm, ex * ex + ey * ey))
    return env
