"""Arc geometry: centres from I/J/K or R, sweeps, lengths, linearisation within a chord tolerance.

Plane conventions (RS-274): G17 works in (X, Y) about +Z, G18 in (Z, X) about +Y, G19 in (Y, Z)
about +X; :data:`PLANE_AXES` gives the indices ``(a, b, normal)`` so that ``a x b = normal``. CCW is
positive rotation about the normal. R > 0 asks for the arc of at most 180 degrees, R < 0 for the
larger one. An arc whose start and end coincide in the plane (within
:data:`~planning.nc.motion.FULL_CIRCLE_TOL_MM`) is a full circle.

:func:`center_from_ijk` / :func:`center_from_r` are scalar (the interpreter calls them per block);
everything taking a :class:`~planning.nc.Motion` is vectorised over segments.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from planning.nc.motion import ARC_CCW, ARC_CW, DWELL, FULL_CIRCLE_TOL_MM, Motion

PLANE_AXES: dict[int, tuple[int, int, int]] = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
TWO_PI = 2.0 * math.pi

# LinuxCNC's arc tolerances (src/emc/rs274ngc/interp_internal.hh), in program units:
#: I/J/K arcs: start and end radius may differ by this much (CENTER_ARC_RADIUS_TOLERANCE_INCH/MM,
#: the default of the INI settings of the same names) ...
LINUXCNC_CENTER_TOL_INCH = 2 * 0.001 * math.sqrt(2.0)
LINUXCNC_CENTER_TOL_MM = 2 * 0.01 * math.sqrt(2.0)
#: ... or by this fraction of the larger radius (SPIRAL_RELATIVE_TOLERANCE), up to 100 times the
#: absolute tolerance
LINUXCNC_SPIRAL_REL_TOL = 0.001
#: R arcs: the half chord may exceed |R| by this much; also the smallest I/J/K radius
#: (RADIUS_TOLERANCE_INCH, RADIUS_TOLERANCE_MM = the same length)
LINUXCNC_RADIUS_TOL_INCH = 0.00005
LINUXCNC_RADIUS_TOL_MM = LINUXCNC_RADIUS_TOL_INCH * 25.4
#: R arcs: a half chord above (1 - this) |R| is taken as |R| (TINY)
LINUXCNC_TINY = 1e-12


def center_from_r(
    a0: float, b0: float, a1: float, b1: float, r_mm: float, cw: bool, tol_mm: float
) -> tuple[float, float]:
    """In-plane centre of an R-format arc from (a0, b0) to (a1, b1).

    Raises ``ValueError`` with the reason (the interpreter adds the place) when the end points
    coincide (use I/J/K for a full circle) or the chord is longer than ``2|R|`` by more than
    ``tol_mm``.
    """
    da, db = a1 - a0, b1 - b0
    d = math.hypot(da, db)
    if d <= FULL_CIRCLE_TOL_MM:
        raise ValueError(
            "R-format arc with start = end is undefined; program a full circle by I/J/K"
        )
    if r_mm == 0.0:
        raise ValueError("arc radius R must not be 0")
    half = 0.5 * d
    h2 = r_mm * r_mm - half * half
    if h2 < 0.0:
        if half - abs(r_mm) > tol_mm:
            raise ValueError(
                f"arc radius |R| = {abs(r_mm):.6g} mm is smaller than half the chord "
                f"({half:.6g} mm) by more than the tolerance {tol_mm:.6g} mm"
            )
        h2 = 0.0
    h = math.sqrt(h2)
    # centre left of the chord (seen from +normal) for a CCW minor arc; CW or R<0 flips it
    s = h / d if (not cw) == (r_mm > 0.0) else -h / d
    return a0 + 0.5 * da - s * db, b0 + 0.5 * db + s * da


def check_radius(
    a0: float, b0: float, a1: float, b1: float, ca: float, cb: float, tol_mm: float
) -> float:
    """Start radius of an I/J/K arc; ``ValueError`` if the end radius differs by > ``tol_mm``."""
    r0 = math.hypot(a0 - ca, b0 - cb)
    r1 = math.hypot(a1 - ca, b1 - cb)
    if abs(r1 - r0) > tol_mm:
        raise ValueError(
            f"arc end radius {r1:.6g} mm differs from start radius {r0:.6g} mm by "
            f"{abs(r1 - r0):.3g} mm, more than the tolerance {tol_mm:.6g} mm"
        )
    if r0 <= FULL_CIRCLE_TOL_MM:
        raise ValueError("arc centre coincides with the start point (radius 0)")
    return r0


def check_radius_linuxcnc(
    a0: float,
    b0: float,
    a1: float,
    b1: float,
    ca: float,
    cb: float,
    abs_tol_mm: float,
    min_radius_mm: float,
) -> float:
    """Start radius of an I/J/K arc under LinuxCNC's rule (``arc_data_ijk``); ``ValueError`` if
    either radius is below ``min_radius_mm`` or the radii differ by more than ``abs_tol_mm`` and
    by more than :data:`LINUXCNC_SPIRAL_REL_TOL` of the larger one, or by more than 100 times
    ``abs_tol_mm`` in any case. An accepted arc with unequal radii is cut as a spiral from the
    start to the programmed end about the programmed centre."""
    r0 = math.hypot(a0 - ca, b0 - cb)
    r1 = math.hypot(a1 - ca, b1 - cb)
    if r0 < min_radius_mm or r1 < min_radius_mm:
        raise ValueError(
            f"zero-radius arc: start radius {r0:.6g} mm, end radius {r1:.6g} mm (LinuxCNC "
            f"needs at least {min_radius_mm:.6g} mm)"
        )
    err = abs(r0 - r1)
    rel = err / max(r0, r1)
    if err > 100.0 * abs_tol_mm or (rel > LINUXCNC_SPIRAL_REL_TOL and err > abs_tol_mm):
        raise ValueError(
            f"arc end radius {r1:.6g} mm differs from start radius {r0:.6g} mm by {err:.3g} mm "
            f"({100.0 * rel:.3g} %), more than LinuxCNC allows ({abs_tol_mm:.6g} mm, or "
            f"{100.0 * LINUXCNC_SPIRAL_REL_TOL:g} % up to {100.0 * abs_tol_mm:.6g} mm)"
        )
    return r0


def arc_length_mm(
    p0: tuple[float, float, float],
    p1: tuple[float, float, float],
    center: tuple[float, float, float],
    plane: int,
    cw: bool,
) -> float:
    """Path length of one arc (helix included), mm; scalar twin of :func:`segment_length_mm`."""
    ia, ib, ic = PLANE_AXES[plane]
    a0, b0 = p0[ia] - center[ia], p0[ib] - center[ib]
    a1, b1 = p1[ia] - center[ia], p1[ib] - center[ib]
    if math.hypot(a1 - a0, b1 - b0) <= FULL_CIRCLE_TOL_MM:
        sweep = TWO_PI
    else:
        ccw = (math.atan2(b1, a1) - math.atan2(b0, a0)) % TWO_PI
        sweep = (-ccw) % TWO_PI if cw else ccw
    return math.hypot(math.hypot(a0, b0) * sweep, p1[ic] - p0[ic])


def _plane_coords(motion: Motion) -> tuple[np.ndarray, ...]:
    """Per segment in-plane coordinates (a0, b0, a1, b1, ca, cb) and normal start/end (n0, n1)."""
    s, e, c = motion.start, motion.end, motion.center
    plane = motion.plane
    if plane.size and plane[0] == plane[-1] and (plane == plane[0]).all():  # one plane: slices
        ia, ib, ic = PLANE_AXES.get(min(max(int(plane[0]), 0), 19), (0, 1, 2))
        idx = np.broadcast_to(np.array([ia, ib, ic]), (plane.size, 3))
        return s[:, ia], s[:, ib], e[:, ia], e[:, ib], c[:, ia], c[:, ib], s[:, ic], e[:, ic], idx
    axes = np.array([PLANE_AXES.get(int(p), (0, 1, 2)) for p in range(20)])
    idx = axes[np.clip(motion.plane.astype(int), 0, 19)]
    rows = np.arange(len(motion))
    ia, ib, ic = idx[:, 0], idx[:, 1], idx[:, 2]
    s, e, c = motion.start, motion.end, motion.center
    return (
        s[rows, ia],
        s[rows, ib],
        e[rows, ia],
        e[rows, ib],
        c[rows, ia],
        c[rows, ib],
        s[rows, ic],
        e[rows, ic],
        idx,
    )


def arc_radius_mm(motion: Motion) -> np.ndarray:
    """Arc radius (n,), mm; NaN for segments that are not arcs."""
    a0, b0, _, _, ca, cb, *_ = _plane_coords(motion)
    r = np.hypot(a0 - ca, b0 - cb)
    return np.where(motion.is_arc, r, np.nan)


def _angles(
    a0: np.ndarray, b0: np.ndarray, a1: np.ndarray, b1: np.ndarray, ca: np.ndarray,
    cb: np.ndarray, kind: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Start angle and unsigned sweep in (0, 2*pi] of arcs given by in-plane coordinates."""
    with np.errstate(invalid="ignore"):
        t0 = np.arctan2(b0 - cb, a0 - ca)
        t1 = np.arctan2(b1 - cb, a1 - ca)
        ccw = np.mod(t1 - t0, TWO_PI)
        sweep = np.where(kind == ARC_CW, np.mod(-ccw, TWO_PI), ccw)
        full = np.hypot(a1 - a0, b1 - b0) <= FULL_CIRCLE_TOL_MM
    return t0, np.where(full, TWO_PI, sweep)


@dataclass(frozen=True)
class ArcGeometry:
    """The arcs of a motion, computed once for lengths and boxes: their segment indices ``rows``,
    in-plane start (a0, b0) and centre (ca, cb), normal start/end (n0, n1), plane axes ``idx``
    (k, 3), radius ``r``, start angle ``t0``, unsigned sweep (rad) and the CCW mask."""

    rows: np.ndarray
    a0: np.ndarray
    b0: np.ndarray
    ca: np.ndarray
    cb: np.ndarray
    n0: np.ndarray
    n1: np.ndarray
    idx: np.ndarray
    r: np.ndarray
    t0: np.ndarray
    sweep: np.ndarray
    ccw: np.ndarray

    @staticmethod
    def of(motion: Motion) -> ArcGeometry | None:
        """The arcs of ``motion`` (None when it has none)."""
        rows = np.flatnonzero(motion.is_arc)
        if not rows.size:
            return None
        a0, b0, a1, b1, ca, cb, n0, n1, idx = _plane_coords(motion)
        a0, b0, a1, b1, ca, cb, n0, n1 = (v[rows] for v in (a0, b0, a1, b1, ca, cb, n0, n1))
        kind = motion.kind[rows]
        t0, sweep = _angles(a0, b0, a1, b1, ca, cb, kind)
        r = np.hypot(a0 - ca, b0 - cb)
        return ArcGeometry(rows, a0, b0, ca, cb, n0, n1, idx[rows], r, t0, sweep, kind == ARC_CCW)

    def quadrant_points(
        self, k: np.ndarray | None = None, quadrants: Iterable[int] = range(4)
    ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """For the arcs ``k`` (indices into ``rows``; all if None) the points at 0, 90, 180 and
        270 degrees (``quadrants`` 0..3) in their plane that lie inside their sweep: ``(j, p)``
        per quadrant, ``j`` indices into ``rows`` and ``p`` (len(j), 3) the points (the normal
        axis at its start value: it peaks at the ends)."""
        k = np.arange(self.rows.size) if k is None else k
        t0, sweep, ccw = self.t0[k], self.sweep[k], self.ccw[k]
        for q in quadrants:
            ang = q * 0.5 * math.pi
            delta = np.where(ccw, np.mod(ang - t0, TWO_PI), np.mod(t0 - ang, TWO_PI))
            j = k[delta <= sweep]
            if not j.size:
                continue
            p = np.empty((j.size, 3))
            at = np.arange(j.size)
            p[at, self.idx[j, 0]] = self.ca[j] + self.r[j] * math.cos(ang)
            p[at, self.idx[j, 1]] = self.cb[j] + self.r[j] * math.sin(ang)
            p[at, self.idx[j, 2]] = self.n0[j]
            yield j, p

    def extend_box(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``lo``, ``hi`` (3,), a box holding every arc's start, widened by the quadrant points
        inside the sweeps, looking at the sweep only where the point lies outside the box (or
        is NaN): the same box as :func:`segment_boxes` gives, for a fraction of the work."""
        ia, ib = self.idx[:, 0], self.idx[:, 1]
        lo_a, hi_a, lo_b, hi_b = lo[ia], hi[ia], lo[ib], hi[ib]
        for q in range(4):
            ang = q * 0.5 * math.pi
            pa = self.ca + self.r * math.cos(ang)  # as quadrant_points computes them
            pb = self.cb + self.r * math.sin(ang)
            k = np.flatnonzero(~((pa >= lo_a) & (pa <= hi_a) & (pb >= lo_b) & (pb <= hi_b)))
            for _, p in self.quadrant_points(k, (q,)) if k.size else ():
                lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
        return lo, hi


def arc_sweep_rad(motion: Motion) -> np.ndarray:
    """Unsigned swept angle (n,) of each arc in (0, 2*pi], radians; 0 for non-arcs."""
    a0, b0, a1, b1, ca, cb, *_ = _plane_coords(motion)
    _, sweep = _angles(a0, b0, a1, b1, ca, cb, motion.kind)
    out: np.ndarray = np.where(motion.is_arc, sweep, 0.0)
    return out


def segment_length_mm(motion: Motion, arcs: ArcGeometry | None = None) -> np.ndarray:
    """Path length (n,) of each segment, mm (helical arcs included; 0 for dwells); ``arcs``:
    ``ArcGeometry.of(motion)`` when the caller has it."""
    d = motion.end - motion.start
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    # np.linalg.norm's sum, ~5x faster on (n, 3)
    length: np.ndarray = np.sqrt((x * x + y * y) + z * z)
    length[motion.kind == DWELL] = 0.0
    arcs = ArcGeometry.of(motion) if arcs is None else arcs
    if arcs is not None:
        length[arcs.rows] = np.hypot(arcs.r * arcs.sweep, arcs.n1 - arcs.n0)
    return length


def segment_travel(motion: Motion) -> np.ndarray:
    """Combined travel (n,) of each segment: hypot(path length mm, rotary travel deg)."""
    rot = np.linalg.norm(motion.rotary_end_deg - motion.rotary_start_deg, axis=1)
    out: np.ndarray = np.hypot(segment_length_mm(motion), rot)
    return out


def segment_boxes(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Exact axis-aligned box of every segment, ``(lo (n, 3), hi (n, 3))``, mm.

    Arcs contribute their end points and the quadrant points (0, 90, 180, 270 degrees in their
    plane) that lie inside their sweep; vectorised, no linearisation.
    """
    lo = np.minimum(motion.start, motion.end)
    hi = np.maximum(motion.start, motion.end)
    arcs = ArcGeometry.of(motion)
    for j, p in arcs.quadrant_points() if arcs is not None else ():
        assert arcs is not None  # (no points without arcs)
        rows = arcs.rows[j]
        lo[rows] = np.minimum(lo[rows], p)
        hi[rows] = np.maximum(hi[rows], p)
    return lo, hi


def bounding_box(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Exact axis-aligned bounding box ``(lo (3,), hi (3,))`` of the path, mm (NaN if empty);
    see :func:`segment_boxes`."""
    if len(motion) == 0:
        nan = np.full(3, np.nan)
        return nan, nan.copy()
    lo, hi = segment_boxes(motion)
    return lo.min(axis=0), hi.max(axis=0)


@dataclass(frozen=True)
class Linearized:
    """Straight pieces approximating a motion.

    start, end : ndarray, shape (k, 3), mm
    source : ndarray, shape (k,), int64 — index of the motion segment each piece comes from
        (non-decreasing; every segment has at least one piece, a dwell a zero-length one)
    kind : ndarray, shape (k,), int8 — the source segment's kind
    """

    start: np.ndarray
    end: np.ndarray
    source: np.ndarray
    kind: np.ndarray

    def __len__(self) -> int:
        return int(self.source.shape[0])


def pieces_per_segment(motion: Motion, chord_tol_mm: float) -> np.ndarray:
    """How many straight pieces each segment needs so the chord error stays <= ``chord_tol_mm``."""
    if not chord_tol_mm > 0:
        raise ValueError(f"chord tolerance must be > 0 mm, got {chord_tol_mm}")
    r = arc_radius_mm(motion)
    sweep = arc_sweep_rad(motion)
    with np.errstate(invalid="ignore", divide="ignore"):
        # sagitta r (1 - cos(d/2)) <= tol  <=>  d <= 2 acos(1 - tol/r); at most 120 deg per piece
        dmax = np.where(r > chord_tol_mm, 2.0 * np.arccos(1.0 - chord_tol_mm / r), math.pi)
        dmax = np.minimum(dmax, TWO_PI / 3.0)
        m = np.ceil(sweep / dmax - 1e-12)
    return np.where(motion.is_arc, np.maximum(m, 1), 1).astype(np.int64)


def linearize(motion: Motion, chord_tol_mm: float = 0.001) -> Linearized:
    """Replace every arc by chords whose deviation from the arc is at most ``chord_tol_mm``.

    Lines, rapids and dwells map to one piece each. Helical arcs interpolate the normal axis
    linearly in angle. Vectorised: no Python loop over segments.
    """
    m = pieces_per_segment(motion, chord_tol_mm)
    source = np.repeat(np.arange(len(motion)), m)
    first = np.cumsum(m) - m
    j = np.arange(source.size) - first[source]  # piece index within its segment
    mm = m[source]
    f0, f1 = j / mm, (j + 1) / mm
    start = motion.start[source] + f0[:, None] * (motion.end - motion.start)[source]
    end = motion.start[source] + f1[:, None] * (motion.end - motion.start)[source]
    arcs = motion.is_arc[source]
    if arcs.any():
        a0, b0, _, _, ca, cb, n0, n1, idx = _plane_coords(motion)
        r = np.hypot(a0 - ca, b0 - cb)
        t0 = np.arctan2(b0 - cb, a0 - ca)
        sgn = np.where(motion.kind == ARC_CCW, 1.0, -1.0)
        sweep = arc_sweep_rad(motion) * sgn
        k = np.nonzero(arcs)[0]
        s = source[k]
        for frac, out in ((f0[k], start), (f1[k], end)):
            th = t0[s] + frac * sweep[s]
            pa = ca[s] + r[s] * np.cos(th)
            pb = cb[s] + r[s] * np.sin(th)
            pn = n0[s] + frac * (n1[s] - n0[s])
            out[k, idx[s, 0]] = pa
            out[k, idx[s, 1]] = pb
            out[k, idx[s, 2]] = pn
        # exact end points where the source has them (no rounding drift at joints)
        last = k[f1[k] == 1.0]
        end[last] = motion.end[source[last]]
        firsts = k[f0[k] == 0.0]
        start[firsts] = motion.start[source[firsts]]
    return Linearized(start=start, end=end, source=source, kind=motion.kind[source])


__all__ = [
    "PLANE_AXES",
    "ArcGeometry",
    "Linearized",
    "arc_length_mm",
    "arc_radius_mm",
    "arc_sweep_rad",
    "bounding_box",
    "center_from_r",
    "check_radius",
    "check_radius_linuxcnc",
    "linearize",
    "pieces_per_segment",
    "segment_length_mm",
]
