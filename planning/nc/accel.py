"""Machining time with acceleration: a look-ahead planner with trapezoidal velocity profiles.

:mod:`planning.nc.stats` times every move at its programmed feed, a lower bound. Programs of many
short blocks (dies, post-processed programs) never reach their feed, so a control's look-ahead
planner is modelled here, the way GRBL and most CNC controls plan:

- every segment accelerates and decelerates at ``accel_mm_s2`` along the path (one path
  acceleration, not per axis);
- the speed through the junction of two feed moves is limited by the junction deviation
  ``delta`` (GRBL's corner model): v^2 = a delta sin(theta/2) / (1 - sin(theta/2)), theta the
  angle between the two directions (0 for a full reversal, pi for a straight continuation), and
  by both segments' feeds;
- an arc's feed is limited by its centripetal acceleration, v^2 <= a R;
- the path stops before and after rapids and dwells, and at the ends of the program; rapids run
  at the speed that gives their stats.py time (the slowest axis at the rapid rate), with the same
  acceleration;
- zero-length moves take no time and do not stop the path;
- a move of the rotary axes counts its degrees with the millimetres (the feed's convention, see
  :mod:`planning.nc.motion`), for lengths and for corners (directions in X Y Z A B C);
- the path also stops where the tool, the spindle speed or the coolant changes between two moves
  (M0/M1 program stops are not in :class:`~planning.nc.Motion`, so they do not stop it here).

Two passes (backward: every junction reachable to a stop; forward: reachable from the start) give
each segment's entry and exit speed; the time of a segment is then a closed-form trapezoid (or
triangle). The passes are sequential, so they run compiled with numba (a million segments: 0.79 s
as a Python loop, 7.5 ms compiled; bench_nc times the whole estimate).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from planning.nc.arcs import (
    _plane_coords,
    arc_radius_mm,
    arc_sweep_rad,
    segment_length_mm,
    segment_travel,
)
from planning.nc.motion import ARC_CW, DWELL, RAPID, Motion

__all__ = ["accel_segment_time_s", "junction_speed_mm_s", "segment_tangents"]


def segment_tangents(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Unit direction of travel at the start and end of every segment, (n, 3) each (0 for
    dwells and zero-length moves)."""
    a0, b0, a1, b1, ca, cb, n0, n1, idx = _plane_coords(motion)
    d = motion.end - motion.start
    t0 = d.copy()
    t1 = d.copy()
    arc = motion.is_arc
    if arc.any():
        r = arc_radius_mm(motion)[arc]
        axial = (n1 - n0)[arc] / np.maximum(arc_sweep_rad(motion)[arc] * r, 1e-300)
        sign = np.where(motion.kind[arc] == ARC_CW, -1.0, 1.0)
        rows = np.flatnonzero(arc)
        for t, pa, pb in ((t0, a0, b0), (t1, a1, b1)):
            ra, rb = (pa - ca)[arc] / r, (pb - cb)[arc] / r
            v = np.zeros((rows.size, 3))
            # CCW about the plane normal: (a, b) -> (-b, a); CW the opposite.
            v[np.arange(rows.size), idx[arc, 0]] = -sign * rb
            v[np.arange(rows.size), idx[arc, 1]] = sign * ra
            v[np.arange(rows.size), idx[arc, 2]] = axial
            t[rows] = v
    for t in (t0, t1):
        norm = np.linalg.norm(t, axis=1)
        t /= np.where(norm > 0, norm, 1.0)[:, None]
        t[motion.kind == DWELL] = 0.0
    return t0, t1


def _combined_tangents(
    motion: Motion, rows: np.ndarray, travel: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents (m, 6) at the start and end of the moving segments ``rows`` in the combined
    X Y Z A B C space the feed is counted in (mm and degrees alike): the X/Y/Z direction scaled
    by the path's share of the travel, the rotary axes' share constant along the segment."""

    t0, t1 = segment_tangents(motion[rows])
    share = (segment_length_mm(motion[rows]) / travel)[:, None]
    rot = (motion.rotary_end_deg[rows] - motion.rotary_start_deg[rows]) / travel[:, None]
    return np.hstack([t0 * share, rot]), np.hstack([t1 * share, rot])


def junction_speed_mm_s(
    exit_dir: np.ndarray, entry_dir: np.ndarray, accel_mm_s2: float, deviation_mm: float
) -> np.ndarray:
    """Largest speed through a corner from ``exit_dir`` into ``entry_dir`` (unit, (..., k)),
    mm/s, by the junction-deviation model (module doc); inf for a straight continuation."""
    cos_theta = -np.sum(exit_dir * entry_dir, axis=-1)
    sin_half = np.sqrt(np.clip(0.5 * (1.0 - cos_theta), 0.0, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        v2 = accel_mm_s2 * deviation_mm * sin_half / (1.0 - sin_half)
    return np.where(sin_half >= 1.0 - 1e-12, np.inf, np.sqrt(v2))


@njit(cache=True)
def _passes(junction: np.ndarray, length: np.ndarray, accel: float) -> None:
    n = length.size
    for i in range(n - 1, -1, -1):
        reach = np.sqrt(junction[i + 1] ** 2 + 2.0 * accel * length[i])
        if junction[i] > reach:
            junction[i] = reach
    for i in range(n):
        reach = np.sqrt(junction[i] ** 2 + 2.0 * accel * length[i])
        if junction[i + 1] > reach:
            junction[i + 1] = reach


def _trapezoid_time_s(
    length: np.ndarray, v_in: np.ndarray, v_out: np.ndarray, v_max: np.ndarray, accel: float
) -> np.ndarray:
    """Time over ``length`` from ``v_in`` to ``v_out`` cruising at most at ``v_max`` (mm, mm/s)."""
    d_up = (v_max**2 - v_in**2) / (2 * accel)
    d_down = (v_max**2 - v_out**2) / (2 * accel)
    cruise = length - d_up - d_down
    peak = np.sqrt(np.maximum((2 * accel * length + v_in**2 + v_out**2) / 2, 0.0))
    top = np.where(cruise >= 0, v_max, np.minimum(peak, v_max))
    t = (top - v_in) / accel + (top - v_out) / accel
    with np.errstate(divide="ignore", invalid="ignore"):
        t = t + np.where(cruise > 0, cruise / v_max, 0.0)
    out: np.ndarray = t
    return out


def accel_segment_time_s(
    motion: Motion, accel_mm_s2: float, junction_deviation_mm: float, rapid_time_s: np.ndarray
) -> np.ndarray:
    """Duration of each segment (n,), s, with acceleration (module doc).

    ``rapid_time_s`` (n,) is the constant-speed time of each segment from stats.py (used for the
    rapids' speed and the dwells' time).
    """
    if not accel_mm_s2 > 0 or not junction_deviation_mm > 0:
        raise ValueError(
            f"accel {accel_mm_s2} mm/s^2 and junction deviation {junction_deviation_mm} mm "
            "must be > 0"
        )

    length = segment_travel(motion)  # mm and degrees together, as the feed counts them
    kind = motion.kind
    moving = (length > 0) & (kind != DWELL)
    rows = np.flatnonzero(moving)
    seg_len = length[rows]
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(
            kind[rows] == RAPID,
            seg_len / rapid_time_s[rows],
            motion.feed_mm_min[rows] / 60.0,
        )
    arc = motion.is_arc[rows]
    if arc.any():
        v[arc] = np.minimum(v[arc], np.sqrt(accel_mm_s2 * arc_radius_mm(motion)[rows][arc]))
    t0, t1 = _combined_tangents(motion, rows, seg_len)
    junction = np.zeros(rows.size + 1)
    if rows.size > 1:
        corner = junction_speed_mm_s(t1[:-1], t0[1:], accel_mm_s2, junction_deviation_mm)
        corner = np.minimum(corner, np.minimum(v[:-1], v[1:]))
        # Stop around rapids, where the tool, spindle or coolant changes between two moves (the
        # control finishes the motion before an M-code), and wherever a dwell sits between them.
        a, b = rows[:-1], rows[1:]
        stop = (kind[a] == RAPID) | (kind[b] == RAPID)
        stop |= (motion.tool[a] != motion.tool[b]) | (motion.coolant[a] != motion.coolant[b])
        stop |= motion.spindle_rpm[a] != motion.spindle_rpm[b]
        dwell_between = np.zeros(rows.size - 1, dtype=bool)
        dwells = np.flatnonzero(kind == DWELL)
        if dwells.size:
            k = np.searchsorted(rows, dwells)  # junction k sits between moves k-1 and k
            inner = (k > 0) & (k < rows.size)
            dwell_between[k[inner] - 1] = True
        junction[1:-1] = np.where(stop | dwell_between, 0.0, corner)
    _passes(junction, seg_len, float(accel_mm_s2))
    t = np.zeros(len(motion))
    t[rows] = _trapezoid_time_s(seg_len, junction[:-1], junction[1:], v, accel_mm_s2)
    t[kind == DWELL] = motion.dwell_s[kind == DWELL]
    return t
