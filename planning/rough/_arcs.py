"""Circular arcs (G2/G3) fitted to an XY polyline within a tolerance, for shorter NC programs.

A roughing pass is a shapely polyline (offsets with round joins, contours of Ferguson surfaces), so
curved stretches are many short chords; streamed over RS-232 DNC the control slows down on many
tiny blocks. :func:`fit_arcs` replaces runs of consecutive vertices by one circular arc when the
arc and the run stay within ``tol_mm`` of each other both ways (Hausdorff distance), and runs of
nearly collinear vertices by one line; the rest stay lines.

Hand-written: no maintained library fits tolerance-bounded arcs to polylines for G-code (pypi has
G-code writers and clothoid/biarc Hermite interpolators such as ``clothoids``, none bounding the
distance to a given polyline both ways); the fit is a closed-form least squares per run.

How a run ``i..j`` (at least ``min_chords`` chords) is tested as an arc:

* the circle passes exactly through the run's end vertices (so consecutive elements join at input
  vertices with no gap and the NC start/end radii agree); its centre lies on the perpendicular
  bisector of the chord ``P_i P_j`` at signed offset ``t``; ``t`` minimises the algebraic residual
  ``|P - C|^2 - R^2`` of the inner vertices, which is linear in ``t`` (closed form);
* every vertex lies within ``tol_mm`` of the circle; the vertices turn monotonically about the
  centre (one sense, no chord spanning more than a quarter turn, at most ``max_sweep_rad`` in all,
  default 270 degrees so the chord stays >= 1.41 R and the centre well conditioned);
* every chord stays within ``tol_mm`` of the circle (its point nearest the centre is at most
  ``tol_mm`` inside: the arc-to-chord deviation).

Vertices within ``tol`` radially, monotone in angle, and chords within ``tol`` radially give a
Hausdorff distance <= ``tol`` between the run and the arc: along any ray from the centre the arc
point and the run's point differ only in radius. A line run needs every vertex within ``tol`` of
the chord and vertex projections monotone along it (same argument with parallel rays).

A run is extended greedily from its first vertex by galloping (lengths 3, 6, 12, ... chords until
one fails, then bisection between the last fit and the first failure); each test is vectorised
over the run's vertices. The fit is not monotone in the run length in theory, so the element kept
is always one that was tested. Radii above ``max_radius_mm`` are left to the line test.

A closed polyline (first vertex == last) that is one circle as a whole becomes one full-circle arc
(start = end, which planning.nc writes as ``G2/G3`` with I/J and reads back as a full circle).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from planning.errors import PlanningError
from planning.nc import ARC_CCW, ARC_CW, LINE

TWO_PI = 2.0 * math.pi
MAX_SWEEP_RAD = 1.5 * math.pi
MAX_CHORD_TURN_RAD = 0.5 * math.pi
_TINY_MM = 1e-9


@dataclass(frozen=True, eq=False)
class ArcPath:
    """Lines and arcs replacing a polyline; element ``k`` runs from vertex ``first[k]`` to
    ``last[k]`` of the input (so its start and end are input vertices, consecutive elements share
    a vertex and ``first[0] = 0``, ``last[-1] = n - 1``).

    kind : ndarray (k,), int8 — LINE, ARC_CW or ARC_CCW (seen from +Z, as planning.nc)
    first, last : ndarray (k,), int64 — input vertex indices
    center_mm : ndarray (k, 2), float64 — arc centre, NaN for lines
    radius_mm : ndarray (k,), float64 — arc radius, NaN for lines
    A full circle has ``first = 0``, ``last = n - 1`` and equal start and end points.
    """

    kind: np.ndarray
    first: np.ndarray
    last: np.ndarray
    center_mm: np.ndarray
    radius_mm: np.ndarray

    def __len__(self) -> int:
        return int(self.kind.shape[0])

    @property
    def n_arcs(self) -> int:
        return int(np.count_nonzero(self.kind != LINE))


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles to (-pi, pi]."""
    return np.pi - np.mod(np.pi - a, TWO_PI)


def _chord_inner_dev(p: np.ndarray, c: np.ndarray, r: float) -> float:
    """Largest ``r - distance(centre, chord)`` over the chords of ``p`` (m, 2), mm."""
    a, b = p[:-1] - c, p[1:] - c
    d = b - a
    dd = np.einsum("ij,ij->i", d, d)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.clip(-np.einsum("ij,ij->i", a, d) / dd, 0.0, 1.0)
    s = np.where(dd > 0, s, 0.0)
    near = a + s[:, None] * d
    return float(np.max(r - np.hypot(near[:, 0], near[:, 1])))


def _arc_test(
    p: np.ndarray, tol: float, max_radius: float, max_sweep: float
) -> tuple[int, np.ndarray, float] | None:
    """Arc through p[0] and p[-1] within ``tol`` of the polyline p (m, 2), or None.

    Returns (kind ARC_CW/ARC_CCW, centre (2,), radius) when it fits.
    """
    u = p[-1] - p[0]
    c = math.hypot(u[0], u[1])
    if c <= _TINY_MM:
        return None
    h = 0.5 * c
    mid = 0.5 * (p[0] + p[-1])
    n = np.array([-u[1], u[0]]) / c
    q = p[1:-1] - mid
    d = q @ n
    sdd = float(d @ d)
    if sdd <= _TINY_MM**2:
        return None  # collinear: no circle
    a = np.einsum("ij,ij->i", q, q) - h * h
    t = float(a @ d) / (2.0 * sdd)
    r = math.hypot(h, t)
    if r > max_radius:
        return None
    centre = mid + t * n
    v = p - centre
    rad = np.hypot(v[:, 0], v[:, 1])
    if np.max(np.abs(rad - r)) > tol:
        return None
    turning = _one_way_sweep(v)
    if turning is None:
        return None
    sweep, sense = turning
    if abs(sweep) > max_sweep or _chord_inner_dev(p, centre, r) > tol:
        return None
    return (ARC_CCW if sense > 0 else ARC_CW), centre, r


def _one_way_sweep(v: np.ndarray) -> tuple[float, float] | None:
    """(signed sweep rad, sense +-1) of vectors ``v`` (k, 2) from a centre to the vertices, or
    None unless they turn one way in steps of at most MAX_CHORD_TURN_RAD."""
    turn = _wrap(np.diff(np.arctan2(v[:, 1], v[:, 0])))
    sweep = float(turn.sum())
    sense = 1.0 if sweep > 0 else -1.0
    if np.any(turn * sense < 0) or np.any(np.abs(turn) > MAX_CHORD_TURN_RAD):
        return None
    return sweep, sense


def _line_test(p: np.ndarray, tol: float) -> bool:
    """All vertices within ``tol`` of the chord p[0]-p[-1], projections monotone along it."""
    u = p[-1] - p[0]
    c = math.hypot(u[0], u[1])
    if c <= _TINY_MM:
        return False
    e = u / c
    q = p - p[0]
    along = q @ e
    across = q[:, 0] * e[1] - q[:, 1] * e[0]
    return bool(np.all(np.abs(across) <= tol) and np.all(np.diff(along) >= 0))


def _longest(test: Callable[[int, int], bool], i: int, n: int, lo: int) -> int:
    """Largest j in [i + lo, n - 1] with test(i, j) true by galloping then bisection; -1 if
    test(i, i + lo) fails."""
    j = i + lo
    if j > n - 1 or not test(i, j):
        return -1
    good, step = j, lo
    bad = n  # first index known to fail (n: past the end)
    while True:
        j = good + step
        if j >= n:
            j = n - 1
            if j == good:
                return good
            if test(i, j):
                return j
            bad = j
            break
        if test(i, j):
            good, step = j, 2 * step
        else:
            bad = j
            break
    while bad - good > 1:
        j = (good + bad) // 2
        if test(i, j):
            good = j
        else:
            bad = j
    return good


def _full_circle(
    p: np.ndarray, tol: float, max_radius: float
) -> tuple[int, np.ndarray, float] | None:
    """One circle through a closed polyline p (m, 2), p[0] == p[-1], within ``tol``, or None."""
    if p.shape[0] < 5:
        return None
    x, y = p[:-1, 0], p[:-1, 1]
    # Kasa fit: x^2 + y^2 = 2 a x + 2 b y + c, linear least squares; the circle is then taken
    # through p[0] (the NC start point) with the fitted centre.
    A = np.stack([2 * x, 2 * y, np.ones_like(x)], 1)
    sol, *_ = np.linalg.lstsq(A, x * x + y * y, rcond=None)
    centre = sol[:2]
    v = p - centre
    rad = np.hypot(v[:, 0], v[:, 1])
    r = float(rad[0])
    if not r <= max_radius or np.max(np.abs(rad - r)) > tol:
        return None
    turning = _one_way_sweep(v)
    if turning is None:
        return None
    sweep, sense = turning
    if abs(abs(sweep) - TWO_PI) > 1e-6 or _chord_inner_dev(p, centre, r) > tol:
        return None
    return (ARC_CCW if sense > 0 else ARC_CW), centre, r


def fit_arcs(
    xy_mm: np.ndarray,
    tol_mm: float,
    *,
    max_radius_mm: float = 1000.0,
    min_chords: int = 3,
    max_sweep_rad: float = MAX_SWEEP_RAD,
    merge_lines: bool = True,
) -> ArcPath:
    """Lines and arcs within ``tol_mm`` (Hausdorff) of the polyline ``xy_mm`` (n, 2), mm.

    ``tol_mm = 0`` returns the polyline's chords unchanged. A run becomes an arc only if it has at
    least ``min_chords`` chords (>= 3), a radius <= ``max_radius_mm`` and a sweep <=
    ``max_sweep_rad``; with ``merge_lines`` runs of nearly collinear vertices become one line.
    A closed polyline (first == last) that is one circle becomes one full circle.
    """
    p = np.asarray(xy_mm, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 2 or not np.all(np.isfinite(p)):
        raise PlanningError(f"arc fit: need a finite (n >= 2, 2) polyline in mm, got {p.shape}")
    if not (tol_mm >= 0 and min_chords >= 3 and max_radius_mm > 0 and max_sweep_rad > 0):
        raise PlanningError(
            f"arc fit: tol_mm = {tol_mm} (>= 0 mm), min_chords = {min_chords} (>= 3), "
            f"max_radius_mm = {max_radius_mm} (> 0 mm), max_sweep_rad = {max_sweep_rad} (> 0)"
        )
    n = p.shape[0]
    kinds, firsts, lasts, centres, radii = [], [], [], [], []

    def emit(
        kind: int, a: int, b: int, c: npt.ArrayLike = (np.nan, np.nan), r: float = np.nan
    ) -> None:
        kinds.append(kind)
        firsts.append(a)
        lasts.append(b)
        centres.append(c)
        radii.append(r)

    full = None
    if tol_mm > 0 and n - 1 >= min_chords and np.array_equal(p[0], p[-1]):
        full = _full_circle(p, tol_mm, max_radius_mm)
    if full is not None:
        emit(full[0], 0, n - 1, full[1], full[2])
    elif tol_mm == 0:
        for k in range(n - 1):
            emit(LINE, k, k + 1)
    else:
        cache: dict[tuple[int, int], tuple[int, np.ndarray, float] | None] = {}

        def arc_ok(i: int, j: int) -> bool:
            if (i, j) not in cache:
                cache[(i, j)] = _arc_test(p[i : j + 1], tol_mm, max_radius_mm, max_sweep_rad)
            return cache[(i, j)] is not None

        def line_ok(i: int, j: int) -> bool:
            return _line_test(p[i : j + 1], tol_mm)

        i = 0
        while i < n - 1:
            ja = _longest(arc_ok, i, n, min_chords)
            jl = _longest(line_ok, i, n, 1) if merge_lines else -1
            if jl >= ja or ja < 0:
                j = max(jl, i + 1)
                emit(LINE, i, j)
            else:
                j = ja
                hit = cache[(i, j)]
                assert hit is not None  # arc_ok(i, ja) held: the cached fit is an arc
                kind, c, r = hit
                emit(kind, i, j, c, r)
            i = j
    return ArcPath(
        np.asarray(kinds, dtype=np.int8),
        np.asarray(firsts, dtype=np.int64),
        np.asarray(lasts, dtype=np.int64),
        np.asarray(centres, dtype=float).reshape(-1, 2),
        np.asarray(radii, dtype=float),
    )


def sample_path(xy_mm: np.ndarray, path: ArcPath, step_mm: float) -> np.ndarray:
    """Points (m, 2) along the fitted path at most ``step_mm`` apart (arcs along the arc), mm."""
    p = np.asarray(xy_mm, dtype=float)
    out = [p[:1]]
    for k in range(len(path)):
        a, b = p[path.first[k]], p[path.last[k]]
        if path.kind[k] == LINE:
            m = max(1, math.ceil(math.hypot(*(b - a)) / step_mm))
            f = np.arange(1, m + 1) / m
            out.append(a + f[:, None] * (b - a))
            continue
        c, r = path.center_mm[k], path.radius_mm[k]
        t0 = math.atan2(a[1] - c[1], a[0] - c[0])
        t1 = math.atan2(b[1] - c[1], b[0] - c[0])
        ccw = (t1 - t0) % TWO_PI
        if np.array_equal(a, b):
            ccw = TWO_PI
        sweep = ccw if path.kind[k] == ARC_CCW else -((-ccw) % TWO_PI or TWO_PI)
        m = max(1, math.ceil(abs(sweep) * r / step_mm))
        th = t0 + sweep * np.arange(1, m + 1) / m
        out.append(c + r * np.stack([np.cos(th), np.sin(th)], 1))
    return np.concatenate(out)
