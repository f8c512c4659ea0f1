"""The executed motion of the simulated machine on the SimClock, queried per DAQ sample.

The simulated controller reports each segment as it executes
(``rig.sim._controller_exec.ExecutedSegment``: start and end time on the shared clock, start/end
point, arc centre, feed, spindle speed, NC block). The timeline answers, for a
vector of sample times, where the tool tip is, how fast and in which direction it moves, the
spindle's angle and speed, and which block was executing: the sample clock and the block clock are
one clock.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace

import numpy as np

from planning.nc import ARC_CCW, ARC_CW
from rig.sim._controller_exec import ExecutedSegment  # what the simulated controllers emit


@dataclass(frozen=True)
class TimelineState:
    """Machine state at n sample times (arrays of shape (n,) or (n, 3)).

    position_mm (n,3), velocity_mm_s (n,3), direction (n,3) unit feed direction (the last
    non-zero one while stopped), spindle_angle_rad (n,) (clockwise rotation for M3 decreases it),
    spindle_rpm (n,) signed, block (n,) int (-1 before the first block).
    """

    position_mm: np.ndarray
    velocity_mm_s: np.ndarray
    direction: np.ndarray
    spindle_angle_rad: np.ndarray
    spindle_rpm: np.ndarray
    block: np.ndarray


class MotionTimeline:
    """Append-only record of executed segments; thread-safe (controller writes, DAQ reads)."""

    def __init__(self, home_mm: tuple[float, float, float] = (0.0, 0.0, 1e4)) -> None:
        self._lock = threading.Lock()
        self._segs: list[ExecutedSegment] = []
        self._home = np.asarray(home_mm, dtype=float)
        # Spindle phase breakpoints: at time t_k the spindle was at angle a_k turning at rpm_k.
        self._sp_t = [0.0]
        self._sp_a = [0.0]
        self._sp_rpm = [0.0]
        self._arrays: tuple[np.ndarray, ...] | None = None

    def __len__(self) -> int:
        return len(self._segs)

    @property
    def segments(self) -> list[ExecutedSegment]:
        with self._lock:
            return list(self._segs)

    def add(self, seg: ExecutedSegment) -> None:
        """Record a segment (segments arrive in time order). One that starts before the last
        one's planned end (a feed hold, a GRBL override changing the speed mid-way) ends that one
        where and when it starts: the stock is cut only as far as the tool went."""
        with self._lock:
            last = self._segs[-1] if self._segs else None
            if last is not None and seg.t_start_s < last.t_end_s:
                cut = replace(last, t_end_s=max(seg.t_start_s, last.t_start_s), end_mm=seg.start_mm)
                self._segs[-1] = cut
            self._segs.append(seg)
            self._arrays = None
            if seg.spindle_rpm != self._sp_rpm[-1]:
                t = max(seg.t_start_s, self._sp_t[-1])
                a = self._sp_a[-1] + float(_omega(self._sp_rpm[-1])) * (t - self._sp_t[-1])
                self._sp_t.append(t)
                self._sp_a.append(a)
                self._sp_rpm.append(seg.spindle_rpm)

    def set_spindle(self, t_s: float, rpm: float) -> None:
        """A spindle change outside any motion (M3/M5 blocks, feed hold keeps it)."""
        self.add_spindle_breakpoint(t_s, rpm)

    def add_spindle_breakpoint(self, t_s: float, rpm: float) -> None:
        with self._lock:
            if rpm == self._sp_rpm[-1]:
                return
            t = max(t_s, self._sp_t[-1])
            a = self._sp_a[-1] + float(_omega(self._sp_rpm[-1])) * (t - self._sp_t[-1])
            self._sp_t.append(t)
            self._sp_a.append(a)
            self._sp_rpm.append(rpm)

    def _build(self) -> tuple[np.ndarray, ...]:
        if self._arrays is None:
            s = self._segs
            ts = np.array([g.t_start_s for g in s], dtype=float)
            te = np.array([g.t_end_s for g in s], dtype=float)
            p0 = np.array([g.start_mm for g in s], dtype=float).reshape(-1, 3)
            p1 = np.array([g.end_mm for g in s], dtype=float).reshape(-1, 3)
            kind = np.array([g.kind for g in s], dtype=int)
            cen = np.array(
                [g.center_mm if g.center_mm is not None else (np.nan,) * 3 for g in s], dtype=float
            ).reshape(-1, 3)
            blk = np.array([g.block for g in s], dtype=int)
            self._arrays = (ts, te, p0, p1, kind, cen, blk)
        return self._arrays

    def state(self, t_s: np.ndarray) -> TimelineState:
        """Machine state at sample times ``t_s`` (n,), simulated s."""
        t = np.asarray(t_s, dtype=float)
        n = t.size
        with self._lock:
            ts, te, p0, p1, kind, cen, blk = self._build()
            sp_t = np.asarray(self._sp_t)
            sp_a = np.asarray(self._sp_a)
            sp_rpm = np.asarray(self._sp_rpm)
        pos = np.empty((n, 3))
        vel = np.zeros((n, 3))
        block = np.full(n, -1, dtype=int)
        direction = np.zeros((n, 3))
        direction[:, 0] = 1.0
        if ts.size == 0:
            pos[:] = self._home
        else:
            k = np.searchsorted(ts, t, side="right") - 1
            before = k < 0
            kk = np.clip(k, 0, None)
            dur = np.maximum(te[kk] - ts[kk], 1e-12)
            u = np.clip((t - ts[kk]) / dur, 0.0, 1.0)
            moving = (~before) & (t < te[kk])
            d = p1[kk] - p0[kk]
            pos = p0[kk] + u[:, None] * d
            vel = np.where(moving[:, None], d / dur[:, None], 0.0)
            arc = (kind[kk] == ARC_CW) | (kind[kk] == ARC_CCW)
            if arc.any():
                pos[arc], vel_arc = _arc_points(
                    p0[kk][arc], p1[kk][arc], cen[kk][arc], kind[kk][arc], u[arc], dur[arc]
                )
                vel[arc] = np.where(moving[arc][:, None], vel_arc, 0.0)
            pos[before] = self._home
            block = np.where(before, -1, blk[kk])
            # Feed direction: of the current segment when it moves in XY, else of the latest
            # segment that did (so a feed hold or a plunge keeps the leading side of the cutter).
            dxy = np.hypot(d[:, 0], d[:, 1])
            has_dir = dxy > 1e-12
            seg_dxy = np.hypot(*(p1[:, :2] - p0[:, :2]).T)
            last_dir_idx = _last_true_index(seg_dxy > 1e-12)
            src = np.where(has_dir, kk, last_dir_idx[kk])
            ok = (src >= 0) & ~before
            dd = p1[np.clip(src, 0, None)] - p0[np.clip(src, 0, None)]
            nrm = np.hypot(dd[:, 0], dd[:, 1])
            direction[ok, 0] = dd[ok, 0] / nrm[ok]
            direction[ok, 1] = dd[ok, 1] / nrm[ok]
            direction[ok, 2] = 0.0
            if arc.any():
                tang = vel[arc][:, :2]
                tn = np.hypot(tang[:, 0], tang[:, 1])
                good = tn > 1e-12
                idx = np.flatnonzero(arc)[good]
                direction[idx, :2] = tang[good] / tn[good, None]
        j = np.searchsorted(sp_t, t, side="right") - 1
        j = np.clip(j, 0, None)
        rpm = sp_rpm[j]
        angle = sp_a[j] + _omega(rpm) * (t - sp_t[j])
        return TimelineState(pos, vel, direction, angle, rpm, block)


def _omega(rpm: np.ndarray | float) -> np.ndarray | float:
    """Angular speed of the spindle's angle, rad/s; M3 (rpm > 0) turns clockwise seen from +Z."""
    return -2.0 * np.pi * np.asarray(rpm) / 60.0


def _last_true_index(mask: np.ndarray) -> np.ndarray:
    """For each i, the largest j <= i with mask[j], else -1."""
    idx = np.where(mask, np.arange(mask.size), -1)
    return np.maximum.accumulate(idx) if idx.size else idx


def _arc_points(p0, p1, c, kind, u, dur):
    """Points and velocities on arcs in the XY plane (helical Z interpolated linearly)."""
    a0 = np.arctan2(p0[:, 1] - c[:, 1], p0[:, 0] - c[:, 0])
    a1 = np.arctan2(p1[:, 1] - c[:, 1], p1[:, 0] - c[:, 0])
    r = np.hypot(p0[:, 0] - c[:, 0], p0[:, 1] - c[:, 1])
    ccw = kind == ARC_CCW
    sweep = np.where(ccw, np.mod(a1 - a0, 2 * np.pi), -np.mod(a0 - a1, 2 * np.pi))
    sweep = np.where(np.abs(sweep) < 1e-12, np.where(ccw, 2 * np.pi, -2 * np.pi), sweep)
    a = a0 + u * sweep
    pos = np.stack(
        [c[:, 0] + r * np.cos(a), c[:, 1] + r * np.sin(a), p0[:, 2] + u * (p1[:, 2] - p0[:, 2])],
        axis=1,
    )
    w = sweep / dur
    vel = np.stack([-r * np.sin(a) * w, r * np.cos(a) * w, (p1[:, 2] - p0[:, 2]) / dur], axis=1)
    return pos, vel
