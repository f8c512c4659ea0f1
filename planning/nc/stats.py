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

from planning.nc.arcs import bounding_box, segment_boxes, segment_length_mm, segment_travel
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

    def to_dict(self) -> dict:
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

    ``rapid_mm_min`` overrides the machine's rapid rate.
    """
    rapid = _rapid_rate(machine, rapid_mm_min)
    length = segment_length_mm(motion)
    feed = motion.is_feed
    rap = motion.kind == RAPID
    t = segment_time_s(motion, machine, rapid_mm_min=rapid)
    feed_time = float(t[feed].sum())
    rapid_time = float(t[rap].sum())
    dwell = float(t[motion.kind == DWELL].sum())
    accel_time = None
    if machine is not None and machine.accel_mm_s2 is not None:
        # lazy: accel compiles with numba, which a machine without accel_mm_s2 never needs
        from planning.nc.accel import accel_segment_time_s

        accel_time = float(
            accel_segment_time_s(
                motion, machine.accel_mm_s2, machine.junction_deviation_mm, t
            ).sum()
        )
    lo, hi = bounding_box(motion)
    clo, chi = bounding_box(motion[motion.is_feed])
    return MotionStats(
        segments=len(motion),
        cutting_length_mm=float(length[feed].sum()),
        rapid_length_mm=float(length[rap].sum()),
        time_s=feed_time + rapid_time + dwell,
        feed_time_s=feed_time,
        rapid_time_s=rapid_time,
        dwell_s=dwell,
        bbox_min_mm=tuple(map(float, lo)),
        bbox_max_mm=tuple(map(float, hi)),
        cutting_bbox_min_mm=tuple(map(float, clo)),
        cutting_bbox_max_mm=tuple(map(float, chi)),
        rapid_mm_min=float(rapid),
        accel_time_s=accel_time,
        **_rotary_range(motion),
    )


def _rotary_range(motion: Motion) -> dict[str, tuple[float, float, float]]:
    if not len(motion):
        return {}
    both = np.concatenate([motion.rotary_start_deg, motion.rotary_end_deg])
    lo, hi = both.min(axis=0), both.max(axis=0)
    return {"rotary_min_deg": tuple(map(float, lo)), "rotary_max_deg": tuple(map(float, hi))}


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
