"""The program as the controller will run it, for the page: the DRO's estimate on a drip feed
(which reports no position) and the toolpath view's segments."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from rig.console.results import PositionEstimate, Segment

if TYPE_CHECKING:
    from analysis.config import MachineConfig


class ProgramPath:
    """The program interpreted with ``planning.nc`` (as the controller will run it): per block
    its segments' start and end (mm), programmed feed (mm/min), spindle (rpm) and duration at
    that feed (s). A drip feed reports no position: the DRO is estimated from the executing
    block's start time and these (no acceleration, no override: marked estimated)."""

    def __init__(self, text: str, machine: MachineConfig | None, name: str = "<program>") -> None:
        from planning.nc import interpret
        from rig.dnc.nc import nc_text, segment_durations_s

        m = interpret(nc_text(text), machine, strict=False, file=name)
        self.rapid_mm_min = float(getattr(machine, "rapid_mm_min", 0) or 10_000.0)
        self.motion = m
        dur = segment_durations_s(m, self.rapid_mm_min) if len(m) else np.zeros(0)
        self.by_block: dict[int, list[int]] = {}
        for i, b in enumerate(m.block.tolist()):
            self.by_block.setdefault(int(b), []).append(i)
        self.dur_s = dur

    def estimate(self, block: int, since_s: float) -> PositionEstimate | None:
        """Position, feed, spindle ``since_s`` after ``block`` started (None: no motion known
        for it, e.g. a block that only sets modes: the caller keeps the last estimate)."""
        idx = self.by_block.get(block)
        if not idx:
            return None
        m, t = self.motion, max(0.0, since_s)
        for i in idx:
            d = float(self.dur_s[i])
            if t <= d or i == idx[-1]:
                f = min(1.0, t / d) if d > 0 else 1.0
                pos = m.start[i] + f * (m.end[i] - m.start[i])  # arcs: along the chord
                feed = float(m.feed_mm_min[i]) if m.kind[i] != 0 else self.rapid_mm_min
                return {"pos_mm": _round(pos), "feed_mm_min": _jsonable(round(feed, 1)),
                        "spindle_rpm": _jsonable(float(m.spindle_rpm[i])),
                        "block_end_mm": _round(m.end[idx[-1]])}  # fmt: skip
            t -= d
        return None

    def toolpath(self, max_points: int = 20_000) -> list[Segment]:
        """[block, kind, x0, y0, x1, y1, z0, z1] per segment (mm; arcs as chords), for the
        page's XY and 3-D views (Z last: the XY view reads the first six); at most
        ``max_points`` segments (a longer program is thinned evenly)."""
        m = self.motion
        n = len(m)
        step = max(1, -(-n // max_points))
        a, b = np.round(m.start[:, :3].astype(float), 3), np.round(m.end[:, :3].astype(float), 3)
        return [[int(m.block[i]), int(m.kind[i]), float(a[i, 0]), float(a[i, 1]), float(b[i, 0]),
                 float(b[i, 1]), float(a[i, 2]), float(b[i, 2])] for i in range(0, n, step)
                if m.kind[i] != 4]  # fmt: skip


def _round(v: Any) -> list[float] | None:
    return None if v is None else [round(float(x), 3) for x in v]


def _jsonable(x: float) -> float | None:
    return float(x) if x is not None and math.isfinite(x) else None
