"""The executed path for the 3-D toolpath view: where the machine was (its reported position, or
the drip feed's estimate from the program, as the DRO shows it), with the feed and the force
there, sampled by the server from the ring (so a page that connects late still gets the whole
run's path; the campaign process does no more work for it).

A point is ``[t_s, x_mm, y_mm, z_mm, feed_mm_min, force_n]`` (run clock; force: the mean
resultant over the last :data:`FORCE_WINDOW_S`), added when the position moved by
:data:`MIN_MOVE_MM` or :data:`MAX_GAP_S` passed. Past :data:`MAX_POINTS` every other point is
dropped (``version`` changes: the pages take the whole path again).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rig.console.forces import force_n
from rig.console.ring import RingReader

SAMPLE_S = 0.08  # the server samples the status this often (the status comes every 0.04 s)
FORCE_WINDOW_S = 0.1
MIN_MOVE_MM = 0.005
MAX_GAP_S = 1.0
MAX_POINTS = 20_000


class Trail:
    """The current run's executed path (see the module docstring)."""

    def __init__(self) -> None:
        self.run: Any = None
        self.version = 0
        self.points: list[list[float | None]] = []
        self._meta: dict[str, Any] = {}
        self._meta_key: tuple[int, int] = (-1, -1)
        self._status_seq = -1

    def sample(self, ring: RingReader | None) -> None:
        """One look at the ring: a new run starts a new path; a new position adds a point."""
        if ring is None or ring.closed:
            return
        key = (ring.generation, ring.seq("meta"))
        if key != self._meta_key:
            self._meta_key = key
            self._meta = ring.get_json("meta")[1] or {}
            if self._meta.get("run") != self.run:
                self.run, self.points = self._meta.get("run"), []
                self.version += 1
        seq = ring.seq("status")
        if seq == self._status_seq:
            return
        self._status_seq, status = ring.get_json("status")
        machine = (status or {}).get("machine") or {}
        pos = machine.get("pos_mm")
        t = (status or {}).get("t_now_s")
        if not pos or len(pos) < 3 or t is None or None in pos[:3]:
            return
        if self.points:
            last = self.points[-1]
            moved = math.dist(pos[:3], last[1:4])  # type: ignore[arg-type]
            if moved < MIN_MOVE_MM and t - float(last[0] or 0.0) < MAX_GAP_S:
                return
        feed = machine.get("feed_mm_min")
        self.points.append([round(float(t), 3), *(round(float(v), 3) for v in pos[:3]),
                            None if feed is None else round(float(feed), 1),
                            self._force(ring)])  # fmt: skip
        if len(self.points) > MAX_POINTS:
            self.points = self.points[::2]
            self.version += 1

    def _force(self, ring: RingReader) -> float | None:
        meta = self._meta
        rate = float(meta.get("rate_hz") or 0.0)
        if rate <= 0 or meta.get("zero_v") is None or not meta.get("volts_to_n"):
            return None  # before the zero: no forces to speak of
        n = max(1, int(FORCE_WINDOW_S * rate))
        g, _, _, rows = ring.rows_since(ring.generation, max(0, ring.rows_written - n))
        if len(rows) == 0 or rows.ndim != 2:
            return None
        f = force_n(meta, rows)
        return round(float(np.sqrt((f * f).sum(axis=1)).mean()), 1)

    def since(self, version: int, n: int) -> tuple[bool, list[list[float | None]]]:
        """(whole path again, the points a page holding ``n`` of ``version`` lacks)."""
        if version != self.version:
            return True, list(self.points)
        return False, self.points[n:]
