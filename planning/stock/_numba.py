"""Compiled Z-map kernel (numba), used by :meth:`planning.stock.zmap.ZMap.cut_pieces` when
available.

Why: the numpy kernel evaluates each move on its footprint patch with ~10-20 whole-array
operations; for the short blocks of real roughing programs (a patch of ~2,000 points) the per-call
overhead of numpy dominates and ``bench/bench_zmap.py`` measured about 15,000-30,000 moves/s, below
the 20,000 blocks/s target for simulation plus post-processing. This kernel runs the same geometry
(:mod:`planning.stock._kernels`: flat interval ends, Choi's ball formula, torus bisection) point by
point in compiled loops, with no temporaries. numba is optional: without it (or with
``CUTLAB_NO_NUMBA=1``) the numpy kernel runs, and the tests check both give the same stock.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from typing import TypeVar

import numpy as np
import numpy.typing as npt

try:  # optional dependency
    if os.environ.get("CUTLAB_NO_NUMBA"):
        raise ImportError("disabled by CUTLAB_NO_NUMBA")
    from numba import njit

    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised when numba is absent
    AVAILABLE = False

    _Fn = TypeVar("_Fn", bound=Callable[..., object])

    # no-redef: the stand-in for numba's njit when numba is absent
    def njit(*args: object, **kwargs: object) -> Callable[[_Fn], _Fn]:  # type: ignore[no-redef]
        def wrap(f: _Fn) -> _Fn:
            return f

        return wrap


_BISECT = 48
_F = npt.NDArray[np.float64]


@njit(cache=True, fastmath=False)
def _profile(kind: int, r: float, rc: float, rho2: float) -> float:
    if rho2 > r * r:
        return math.inf
    if kind == 0:
        return 0.0
    if kind == 1:
        return r - math.sqrt(max(r * r - rho2, 0.0))
    e = max(math.sqrt(rho2) - (r - rc), 0.0)
    return rc - math.sqrt(max(rc * rc - e * e, 0.0))


@njit(cache=True, fastmath=False)
def _bull_g(
    t: float, tp: float, w2: float, l2: float, za: float, dz: float, a: float, rc: float
) -> float:
    rho = math.sqrt(w2 + l2 * (t - tp) * (t - tp))
    e = max(rho - a, 0.0)
    return za + t * dz + rc - math.sqrt(max(rc * rc - e * e, 0.0))


@njit(cache=True, fastmath=False)
def _envelope_point(
    kind: int, r: float, rc: float, qx: float, qy: float, dx: float, dy: float, dz: float,
    za: float, l2: float,
) -> float:  # fmt: skip
    """Lowest cutter height over one grid point (offset qx, qy from the start), inf if none."""
    r2 = r * r
    if l2 <= 1e-18:
        return min(za, za + dz) + _profile(kind, r, rc, qx * qx + qy * qy)
    inv = 1.0 / l2
    tp = (qx * dx + qy * dy) * inv
    cross = qx * dy - qy * dx
    w2 = cross * cross * inv
    k2 = r2 - w2
    if k2 < -1e-12 * r2:
        return math.inf
    k2 = max(k2, 0.0)
    hw = math.sqrt(k2 * inv)
    lo = max(tp - hw, 0.0)
    hi = min(tp + hw, 1.0)
    if lo > hi + 1e-12:
        return math.inf
    hi = max(hi, lo)
    if kind == 0:
        return za + (lo if dz >= 0 else hi) * dz
    if kind == 1:
        d_p = math.sqrt(l2)
        phi = math.atan2(dz, d_p)
        t_ = math.sqrt(k2)
        c = min(max(tp * d_p - t_ * math.sin(phi), 0.0), d_p)
        off = c - tp * d_p
        return za + r + c * (dz / d_p) - math.sqrt(max(k2 - off * off, 0.0))
    a = r - rc
    if dz == 0.0:
        return _bull_g(min(max(tp, lo), hi), tp, w2, l2, za, dz, a, rc)
    for _ in range(_BISECT):
        mid = 0.5 * (lo + hi)
        s = mid - tp
        rho = math.sqrt(w2 + l2 * s * s)
        e = max(rho - a, 0.0)
        root = math.sqrt(max(rc * rc - e * e, 1e-300))
        slope = dz
        if rho > 0:
            slope += (e / root) * (l2 * s / rho)
        if slope > 0:
            hi = mid
        else:
            lo = mid
    return _bull_g(0.5 * (lo + hi), tp, w2, l2, za, dz, a, rc)


N_ARC = 90  # samples of the leading half-circle (2 deg each)
MAX_ARCS = 10  # engaged arcs kept per move; more are joined to the last
ARC_TOL_MM = 0.02  # stock this little above the tip is floor residue: not a cut
ARC_SPLIT = 0.25  # a new arc where the engaged height differs this much (relative) from its start


@njit(cache=True, fastmath=False)
def leading_arc(
    h: _F, x0g: float, y0g: float, s: float, xa: float, ya: float, za: float,
    xb: float, yb: float, zb: float, r: float, rc: float, out: npt.NDArray[np.float32],
) -> None:  # fmt: skip
    """The engaged arcs of the cutter's periphery at the middle of the move a -> b, before it
    cuts: ``out`` (MAX_ARCS * 3,) = (entry rad, exit rad, engaged height mm) per arc, NaN where
    there is none (all NaN without XY motion).

    Angles as the force model's: 0 on the left of the feed direction, pi on its right, the
    cutter turning clockwise (M3) from entry to exit over the leading half. The stock is read on
    the circle of radius ``r`` at the grid point under each sample, engaged above the tip plus
    the corner radius ``rc`` (where the flank begins). An arc ends where the stock does or where
    its height above the tip differs by ARC_SPLIT from the arc's first sample (a ramp, a step);
    an arc's height is its samples' mean weighted by sin(angle), as the chip (and the force)
    is. Arcs beyond MAX_ARCS are joined to the last (more force where a gap was: the safe side).
    """
    out[:] = np.nan
    fx, fy = xb - xa, yb - ya
    norm = math.sqrt(fx * fx + fy * fy)
    if norm < 1e-9:
        return
    fx /= norm
    fy /= norm
    xm, ym = 0.5 * (xa + xb), 0.5 * (ya + yb)
    zt = 0.5 * (za + zb) + rc
    ny, nx = h.shape
    step = math.pi / N_ARC
    d = np.zeros(N_ARC)  # stock height above the flank's foot per sample
    for a in range(N_ARC):
        th = (a + 0.5) * step
        # the direction at immersion th: (pi/2 - th) counter-clockwise from the feed
        c, sn = math.sin(th), math.cos(th)
        i = int(math.floor((xm + r * (c * fx - sn * fy) - x0g) / s))
        j = int(math.floor((ym + r * (c * fy + sn * fx) - y0g) / s))
        if 0 <= i < nx and 0 <= j < ny:
            d[a] = h[j, i] - zt
    # one sample missing between two engaged ones is a grid point the previous cut just
    # reached (a ramp's floor, a wall at the radius): not a gap in the cut
    for a in range(1, N_ARC - 1):
        if d[a] <= ARC_TOL_MM < min(d[a - 1], d[a + 1]):
            d[a] = 0.5 * (d[a - 1] + d[a + 1])
    n = 0  # arcs begun
    first = 0.0  # engaged height at the current arc's first sample
    total = 0.0
    count = 0.0
    inside = False
    for a in range(N_ARC):
        w = math.sin((a + 0.5) * step)
        engaged = d[a] > ARC_TOL_MM
        if engaged and (not inside or abs(d[a] - first) > ARC_SPLIT * first):
            if n < MAX_ARCS:  # an arc begins
                if n > 0 and inside:
                    out[3 * n - 1] = total / count
                out[3 * n] = a * step
                total, count = 0.0, 0.0
                n += 1
            first = d[a]
        elif not engaged and inside:
            out[3 * n - 1] = total / count
        if engaged:
            out[3 * n - 2] = (a + 1) * step
            total += d[a] * w
            count += w
        inside = engaged
    if inside:
        out[3 * n - 1] = total / count


@njit(cache=True, fastmath=False)
def cut_pieces(
    h: _F, x0g: float, y0g: float, s: float, bottom: float, kind: int, r: float, rc: float,
    pts: _F, removed: _F, depth: _F, arcs: npt.NDArray[np.float32],
) -> None:  # fmt: skip
    """Cut the moves ``pts`` (k, 6: x0 y0 z0 x1 y1 z1) in order into ``h`` (ny, nx) in place.

    Fills ``removed`` (k,) with mm^3 and ``depth`` (k,) with the deepest height drop, mm; and,
    if ``arcs`` has k rows, each move's engaged arcs (:func:`leading_arc`) before it cuts.
    """
    ny, nx = h.shape
    cx = x0g + 0.5 * s
    cy = y0g + 0.5 * s
    area = s * s
    for k in range(pts.shape[0]):
        xa, ya, za, xb, yb, zb = pts[k, 0], pts[k, 1], pts[k, 2], pts[k, 3], pts[k, 4], pts[k, 5]
        if arcs.shape[0] > 0:
            leading_arc(h, x0g, y0g, s, xa, ya, za, xb, yb, zb, r, rc, arcs[k])
        i0 = max(0, int(math.ceil((min(xa, xb) - r - cx) / s - 1e-9)))
        i1 = min(nx, int(math.floor((max(xa, xb) + r - cx) / s + 1e-9)) + 1)
        j0 = max(0, int(math.ceil((min(ya, yb) - r - cy) / s - 1e-9)))
        j1 = min(ny, int(math.floor((max(ya, yb) + r - cy) / s + 1e-9)) + 1)
        dx, dy, dz = xb - xa, yb - ya, zb - za
        l2 = dx * dx + dy * dy
        zlow = max(min(za, zb), bottom)
        total = 0.0
        drop = 0.0
        for j in range(j0, j1):
            qy = cy + j * s - ya
            for i in range(i0, i1):
                hv = h[j, i]
                if hv <= zlow:
                    continue
                qx = cx + i * s - xa
                if kind == 0 and dz == 0.0:
                    # level flat cut: inside the stadium or not
                    if l2 > 0.0:
                        t = min(max((qx * dx + qy * dy) / l2, 0.0), 1.0)
                        ex = qx - t * dx
                        ey = qy - t * dy
                    else:
                        ex, ey = qx, qy
                    if ex * ex + ey * ey > r * r:
                        continue
                    env = zlow
                else:
                    env = _envelope_point(kind, r, rc, qx, qy, dx, dy, dz, za, l2)
                    if env < bottom:
                        env = bottom
                if hv > env:
                    d = hv - env
                    total += d
                    if d > drop:
                        drop = d
                    h[j, i] = env
        removed[k] = total * area
        depth[k] = drop


def warm_up() -> None:
    """Compile (or load from cache) the kernel for float64 inputs."""
    if AVAILABLE:
        h = np.zeros((4, 4))
        one = np.zeros(1)
        cut_pieces(h, 0.0, 0.0, 1.0, -1.0, 0, 1.0, 0.0, np.zeros((1, 6)), one, one,
                   np.zeros((1, 3 * MAX_ARCS), np.float32))  # fmt: skip
