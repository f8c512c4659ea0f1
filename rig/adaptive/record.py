"""The adaptive loop's record in memory: each judged revolution and each decision (the run file
gets the same as events). See :mod:`rig.adaptive.controller`."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class RevRecord:
    """One judged revolution: run-clock end time, mean |Fxy| N, state, the override commanded
    after it (feed, spindle %), the last reported override and feed (None: no report yet)."""

    t_s: float
    force_n: float
    state: str
    feed_pct: int
    spindle_pct: int
    reported: tuple[int, ...] | None
    feed_mm_min: float | None
    saturated: bool = False


@dataclass
class Decision:
    t_s: float
    kind: str  # feed, spindle, reset, hold
    reason: str
    wall_latency_s: float | None = None  # from the block's arrival to the last byte written
