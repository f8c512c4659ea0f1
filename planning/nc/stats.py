"""Program statistics: machining time, cutting and rapid lengths, bounding box.

Time model: feed moves (lines, arcs) take ``travel / F``, the travel counting the path length and
the rotary axes' degrees together (:func:`segment_travel`; the path length alone without A/B/C);
rapids take the longest single-axis travel at the axis' rapid rate (each axis moves at its rapid
rate independently, as on Fanuc non-interpolated positioning; rotary axes at their
``rapid_deg_min``); dwells take their time. Acceleration is ignored, so these times are
lower bounds; with a machine that gives ``accel_mm_s2``, ``accel_time_s`` adds the look-ahead
planner of :mod:`planning.nc.accel`. Without a machine, rapids use :data:`DEFAULT_RAPID_MM_MIN`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from planning.nc.arcs import ArcGeometry, segment_boxes, segment_length_mm, segment_travel
from planning.nc.motion import DWELL, RAPID, Motion

if TYPE_CHECKING:
    from analysis.config import MachineConfig

DEFAULT_RAPID_MM_MIN = 10_000.0
DEFAULT_ROTARY_RAPID_DEG_MIN = 5_400.0  # without a 5-axis machine config: 15 rpm


@dataclass(frozen=True)
class MotionStats:
    """Summary of a motion.

    segments : number of segments; cutting_length_mm / rapid_length_mm : path lengths, mm;
    time_s : machining time, s (feed + rapid + dwell); feed_time_s, rapid_time_s, dwell_s : the
    parts, s; bbox_min_mm / bbox_max_mm : (3,) exact extent of the whole path including arc
    bulges, mm (NaN without motion); cutting_bbox_min_mm / cutting_bbox_max_mm : extent of feed
    moves only; rapid_mm_min : rapid rate used, mm/min; accel_time_s : machining time with the
    machine's acceleration and corner model, s (None when the machine gives no acceleration);
    rotary_min_deg / rotary_max_deg : (3,) range of A, B, C over the program, deg.
    """

    segments: int
    cutting_length_mm: float
    rapid_length_mm: float
    time_s: float
    feed_time_s: float
    rapid_time_s: float
    dwell_s: float
    bbox_min_mm: tuple[float, float, float]
    bbox_max_mm: tuple[float, float, float]
    cutting_bbox_min_mm: tuple[float, float, float]
    cutting_bbox_max_mm: tuple[float, float, float]
    rapid_mm_min: float
    accel_time_s: float | None = None
    rotary_min_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotary_max_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def _rapid_rate(machine: MachineConfig | None, rapid_mm_min: float | None) -> float:
    if rapid_mm_min is not None:
        if not rapid_mm_min > 0:
            raise ValueError(f"rapid rate must be > 0 mm/min, got {rapid_mm_min}")
        return float(rapid_mm_min)
    return float(machine.rapid_mm_min) if machine is not None else DEFAULT_RAPID_MM_MIN


def _rotary_rates(machine: MachineConfig | None) -> np.ndarray:
    five = machine.five_axis if machine is not None else None
    if five is None:
        return np.full(3, DEFAULT_ROTARY_RAPID_DEG_MIN)
    return np.array([five.a.rapid_deg_min, five.b.rapid_deg_min, five.c.rapid_deg_min])


def segment_time_s(
    motion: Motion, machine: MachineConfig | None = None, *, rapid_mm_min: float | None = None
) -> np.ndarray:
    """Duration of each segment (n,), s, by the time model of this module (vectorised)."""
    rapid = _rapid_rate(machine, rapid_mm_min)
    t = np.zeros(len(motion))
    feed = motion.is_feed
    with np.errstate(invalid="ignore", divide="ignore"):
        t[feed] = segment_travel(motion[feed]) / motion.feed_mm_min[feed] * 60.0
    rap = motion.kind == RAPID
    if rap.any():
        linear = np.abs(motion.end[rap] - motion.start[rap]).max(axis=1) / rapid
        turn = np.abs(motion.rotary_end_deg[rap] - motion.rotary_start_deg[rap])
        t[rap] = np.maximum(linear, (turn / _rotary_rates(machine)).max(axis=1)) * 60.0
    dw = motion.kind == DWELL
    t[dw] = motion.dwell_s[dw]
    return t


def motion_stats(
    motion: Motion, machine: MachineConfig | None = None, *, rapid_mm_min: float | None = None
) -> MotionStats:
    """Lengths, time and bounding box of ``motion`` (vectorised).

    ``rapid_mm_min`` overrides the machine's rapid rate. Sums are exact (correctly rounded), so
    :class:`StreamStats` over any split of the motion into chunks gives the same numbers.
    """
    acc = StreamStats(machine, rapid_mm_min=rapid_mm_min)
    acc.add(motion)
    return acc.result()


def _box(*points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis min and max (3,) of (n, 3) point arrays (NaN where one is NaN). The columns are
    reduced contiguous: numpy reduces axis 0 of an (n, 3) array some 20 times slower."""
    cols = np.ascontiguousarray(np.concatenate(points).T)
    return cols.min(axis=1), cols.max(axis=1)


class ExactSum:
    """A correctly rounded running sum of float arrays, whatever their split (vectorised: each
    float is cut into two 27-bit integer halves summed per binary exponent, exactly in
    float64; the per-exponent sums are combined in a Python int)."""

    __slots__ = ("_n", "_other")
    _SHIFT = 1126  # 2**-1126 is below the smallest float64 mantissa unit (2**-1074 / 2**52)
    _STEP = 1 << 25  # values per bincount: sums of 27-bit halves stay exact in float64

    def __init__(self) -> None:
        self._n = 0
        self._other = 0.0  # inf / nan

    def add(self, x: np.ndarray) -> None:
        x = np.asarray(x, dtype=np.float64).ravel()
        if not x.size:
            return
        fin = np.isfinite(x)
        if not fin.all():
            self._other += float(x[~fin].sum())
            x = x[fin]
        for k in range(0, x.size, self._STEP):
            part = x[k : k + self._STEP]
            m, e = np.frexp(part)
            big = np.ldexp(m, 53)  # integers, |big| < 2**53
            hi = np.floor(big * (1.0 / 2**27))
            lo = big - hi * 2**27
            emin = int(e.min())
            idx = e - emin
            hs = np.bincount(idx, weights=hi)
            ls = np.bincount(idx, weights=lo)
            n = 0
            for j in np.flatnonzero((hs != 0) | (ls != 0)):
                n += ((int(hs[j]) << 27) + int(ls[j])) << (int(j) + emin - 53 + self._SHIFT)
            self._n += n

    def value(self) -> float:
        v = self._n / (1 << self._SHIFT) if self._n else 0.0
        return v + self._other if self._other else v


class StreamStats:
    """:func:`motion_stats` accumulated chunk by chunk: ``add`` each Motion chunk of a program in
    order, then ``result()`` gives the MotionStats of the whole (the same numbers as
    ``motion_stats`` of the concatenation). Memory: a few chunks at most (the acceleration
    estimate keeps neighbouring chunks as look-ahead, only for a machine with ``accel_mm_s2``).
    """

    def __init__(
        self, machine: MachineConfig | None = None, *, rapid_mm_min: float | None = None
    ) -> None:
        self.machine = machine
        self.rapid = _rapid_rate(machine, rapid_mm_min)
        self.segments = 0
        self._cut, self._rap = ExactSum(), ExactSum()
        self._tfeed, self._trap, self._tdwell = ExactSum(), ExactSum(), ExactSum()
        nan = np.full(3, np.nan)
        self._lo, self._hi, self._clo, self._chi = nan, nan, nan, nan
        self._rlo: np.ndarray | None = None
        self._rhi: np.ndarray | None = None
        self._accel: _AccelWindow | None = None
        if machine is not None and machine.accel_mm_s2 is not None:
            self._accel = _AccelWindow(machine, self.rapid)

    def add(self, motion: Motion) -> None:
        n = len(motion)
        if not n:
            return
        self.segments += n
        arcs = ArcGeometry.of(motion)  # sweeps once, for lengths and the box
        length = segment_length_mm(motion, arcs)
        feed = motion.is_feed
        rap = motion.kind == RAPID
        dw = motion.kind == DWELL
        # segment_time_s, with the lengths computed once (every figure is per segment, so the
        # same numbers as segment_time_s gives)
        t = np.zeros(n)
        if feed.any():
            travel = length[feed]
            r0, r1 = motion.rotary_start_deg[feed], motion.rotary_end_deg[feed]
            if not np.array_equal(r0, r1):
                travel = np.hypot(travel, np.linalg.norm(r1 - r0, axis=1))
            with np.errstate(invalid="ignore", divide="ignore"):
                t[feed] = travel / motion.feed_mm_min[feed] * 60.0
        if rap.any():
            linear = np.abs(motion.end[rap] - motion.start[rap]).max(axis=1) / self.rapid
            turn = np.abs(motion.rotary_end_deg[rap] - motion.rotary_start_deg[rap])
            rates = _rotary_rates(self.machine)
            t[rap] = np.maximum(linear, (turn / rates).max(axis=1)) * 60.0
        t[dw] = motion.dwell_s[dw]
        self._cut.add(length[feed])
        self._rap.add(length[rap])
        self._tfeed.add(t[feed])
        self._trap.add(t[rap])
        self._tdwell.add(t[dw])
        # the boxes of the whole and of the feed moves: the end points, widened by the few arcs
        # whose quadrant points can reach out (all arcs are feed moves)
        lo, hi = _box(motion.start, motion.end)
        clo = chi = None
        if feed.all():
            clo, chi = lo, hi
        elif feed.any():
            clo, chi = _box(motion.start[feed], motion.end[feed])
        if arcs is not None and clo is not None and chi is not None:  # (arcs are feed moves)
            wide_lo, wide_hi = arcs.extend_box(clo, chi)
            clo, chi = wide_lo, wide_hi
            lo, hi = np.minimum(lo, wide_lo), np.maximum(hi, wide_hi)
        self._lo, self._hi = np.fmin(self._lo, lo), np.fmax(self._hi, hi)
        if clo is not None and chi is not None:
            self._clo, self._chi = np.fmin(self._clo, clo), np.fmax(self._chi, chi)
        both_lo, both_hi = _box(motion.rotary_start_deg, motion.rotary_end_deg)
        if self._rlo is None or self._rhi is None:
            self._rlo, self._rhi = both_lo, both_hi
        else:
            self._rlo, self._rhi = np.minimum(self._rlo, both_lo), np.maximum(self._rhi, both_hi)
        if self._accel is not None:
            self._accel.add(motion, t)

    def result(self) -> MotionStats:
        feed_time, rapid_time, dwell = self._tfeed.value(), self._trap.value(), self._tdwell.value()
        rot: dict[str, tuple[float, float, float]] = {}
        if self._rlo is not None and self._rhi is not None:
            rot = {
                "rotary_min_deg": _vec3(self._rlo),
                "rotary_max_deg": _vec3(self._rhi),
            }
        return MotionStats(
            segments=self.segments,
            cutting_length_mm=self._cut.value(),
            rapid_length_mm=self._rap.value(),
            time_s=feed_time + rapid_time + dwell,
            feed_time_s=feed_time,
            rapid_time_s=rapid_time,
            dwell_s=dwell,
            bbox_min_mm=_vec3(self._lo),
            bbox_max_mm=_vec3(self._hi),
            cutting_bbox_min_mm=_vec3(self._clo),
            cutting_bbox_max_mm=_vec3(self._chi),
            rapid_mm_min=float(self.rapid),
            accel_time_s=None if self._accel is None else self._accel.finish(),
            **rot,
        )


def _vec3(v: np.ndarray) -> tuple[float, float, float]:
    """A (3,) array as a tuple of Python floats."""
    return (float(v[0]), float(v[1]), float(v[2]))


class _AccelWindow:
    """The look-ahead planner of :mod:`planning.nc.accel` over a stream of chunks, exactly: a
    chunk is planned inside a window of its neighbours long enough (path travel at least
    v_max^2 / 2a on each side, v_max the chunk's fastest segment) that the window's ends, where
    the planner stops, cannot limit any of the chunk's junction speeds."""

    def __init__(self, machine: MachineConfig, rapid: float) -> None:
        if machine.accel_mm_s2 is None:  # (StreamStats makes one only for a machine with it)
            raise ValueError("the acceleration estimate needs the machine's accel_mm_s2")
        self.a = float(machine.accel_mm_s2)
        self.dev = float(machine.junction_deviation_mm)
        self.total = ExactSum()
        self.buf: list[tuple[Motion, np.ndarray, float, float]] = []  # motion, t, travel, vmax
        self.done = 0  # chunks of buf already planned (the left context)

    def add(self, motion: Motion, t: np.ndarray) -> None:
        travel = segment_travel(motion)
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.where(motion.kind == RAPID, travel / t, motion.feed_mm_min / 60.0)
        v = v[(travel > 0) & (motion.kind != DWELL) & np.isfinite(v)]
        vmax = float(v.max()) if v.size else 0.0
        self.buf.append((motion, t, float(travel.sum()), vmax))
        self._plan(final=False)

    def finish(self) -> float:
        self._plan(final=True)
        return self.total.value()

    def _reach(self, k: int) -> float:
        return self.buf[k][3] ** 2 / (2.0 * self.a) * 1.01 + 1e-9

    def _plan(self, final: bool) -> None:
        from planning.nc.accel import accel_segment_time_s

        while self.done < len(self.buf):
            k = self.done
            need = self._reach(k)
            right, got = k + 1, 0.0
            while right < len(self.buf) and got < need:
                got += self.buf[right][2]
                right += 1
            if got < need and not final:
                return
            left, got = k, 0.0
            while left > 0 and got < need:
                left -= 1
                got += self.buf[left][2]
            parts = self.buf[left:right]
            m = Motion.concatenate([p[0] for p in parts]) if len(parts) > 1 else parts[0][0]
            t = np.concatenate([p[1] for p in parts]) if len(parts) > 1 else parts[0][1]
            ta = accel_segment_time_s(m, self.a, self.dev, t)
            off = sum(len(p[0]) for p in self.buf[left:k])
            self.total.add(ta[off : off + len(self.buf[k][0])])
            self.done += 1
            # drop chunks no later window can need (kept: travel >= the largest reach seen)
            keep = max(self._reach(j) for j in range(len(self.buf)))
            got, j = 0.0, self.done
            while j > 0 and got < keep:
                j -= 1
                got += self.buf[j][2]
            if j > 0:
                del self.buf[:j]
                self.done -= j


def _rotary_range(motion: Motion) -> dict[str, tuple[float, float, float]]:
    if not len(motion):
        return {}
    both = np.concatenate([motion.rotary_start_deg, motion.rotary_end_deg])
    lo, hi = both.min(axis=0), both.max(axis=0)
    return {"rotary_min_deg": _vec3(lo), "rotary_max_deg": _vec3(hi)}


def axis_limit_problems(motion: Motion, machine: MachineConfig | None) -> list[str]:
    """One line per axis the program takes outside the machine's X/Y/Z travel (work offsets as
    given to the interpreter, zero by default) or its 5-axis A/B/C limits, naming the first
    source line that does; empty without a machine."""
    if machine is None or not len(motion):
        return []
    out = []
    lo, hi = segment_boxes(motion)
    for i, name in enumerate("xyz"):
        trav = getattr(machine, name)
        bad = (lo[:, i] < trav.min_mm - 1e-9) | (hi[:, i] > trav.max_mm + 1e-9)
        if bad.any():
            k = int(np.argmax(bad))
            v = lo[k, i] if lo[k, i] < trav.min_mm - 1e-9 else hi[k, i]
            out.append(
                f"line {int(motion.line[k])}: {name.upper()} goes to {float(v):g} mm, outside "
                f"machine '{machine.name}' travel {trav.min_mm:g}..{trav.max_mm:g} mm"
            )
    five = machine.five_axis
    for i, name in enumerate("abc" if five is not None else ""):
        lim = getattr(five, name)
        ends = np.stack([motion.rotary_start_deg[:, i], motion.rotary_end_deg[:, i]], axis=1)
        outside = (ends < lim.min_deg - 1e-9) | (ends > lim.max_deg + 1e-9)
        bad = outside.any(axis=1)
        if bad.any():
            k = int(np.argmax(bad))
            v = float(ends[k][np.argmax(outside[k])])  # the end that is outside
            out.append(
                f"line {int(motion.line[k])}: {name.upper()} goes to {v:g} deg, outside machine "
                f"'{machine.name}' {name.upper()} limits {lim.min_deg:g}..{lim.max_deg:g} deg"
            )
    return out
