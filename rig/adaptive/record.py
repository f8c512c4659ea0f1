"""The adaptive loop's record in memory: each judged revolution and each decision (the run file
gets the same as events), and the figures made of them (the live status, the run's summary, a
note's reported state). See :mod:`rig.adaptive.controller`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.adaptive.results import AdaptiveStatus, AdaptiveSummary
from rig.adaptive.settings import AdaptiveSettings


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


def reported_text(streamer: object, state: str) -> str:
    """The override and feed GRBL last reported (``Ov:``, ``FS:``; ``-`` before a report) and
    the loop's state, for a decision's note."""
    ov = getattr(streamer, "overrides", None) if streamer is not None else None
    last = getattr(streamer, "last_status", None)
    fs = getattr(last, "feed_mm_min", None)
    rpm = getattr(last, "spindle_rpm", None)
    return (f"reported Ov {'/'.join(map(str, ov)) if ov else '-'} FS "
            f"{'-' if fs is None else f'{fs:g}'},{'-' if rpm is None else f'{rpm:g}'}; "
            f"state {state}")  # fmt: skip


def loop_status(
    s: AdaptiveSettings, trace: Sequence[RevRecord], feed_pct: int, spindle_pct: int,
    state: str, hold: str | None,
) -> AdaptiveStatus:  # fmt: skip
    """See :meth:`rig.adaptive.AdaptiveController.live_status`."""
    last = trace[-1] if trace else None
    return {
        "mode": s.mode,
        "target_force_n": s.target_force_n,
        "max_force_n": s.max_force_n,
        "force_n": None if last is None else round(last.force_n, 1),
        "feed_pct": feed_pct,
        "spindle_pct": spindle_pct,
        "reported_pct": None if last is None or last.reported is None else list(last.reported),
        "state": state,
        "hold": hold,
    }


def loop_summary(
    s: AdaptiveSettings, trace: Sequence[RevRecord], rpm: float, *, decisions: int,
    override_bytes: int, hold: str | None, latencies_s: Sequence[float], cpu_s: float,
    feed_forward: bool, chatter_at_s: float | None, chatter_cleared_s: float | None,
) -> AdaptiveSummary:  # fmt: skip
    """See :meth:`rig.adaptive.AdaptiveController.summary`; ``rpm`` the programmed speed."""
    lat = np.asarray(latencies_s, float)
    cut = [r for r in trace if r.state == "cutting"]
    return {
        "mode": s.mode,
        "target_force_n": s.target_force_n,
        "revolutions": len(trace),
        "cutting_revolutions": len(cut),
        "decisions": decisions,
        "override_bytes": override_bytes,
        "hold": hold,
        "latency_p50_ms": float(np.percentile(lat, 50) * 1e3) if lat.size else None,
        "latency_p95_ms": float(np.percentile(lat, 95) * 1e3) if lat.size else None,
        "cpu_s": cpu_s,
        "feed_forward": feed_forward,
        "chatter_at_s": chatter_at_s,
        "chatter_cleared_s": chatter_cleared_s,
        "saturated_revolutions": sum(1 for r in cut if r.saturated),
        "saturated_s": sum(60.0 / (rpm * r.spindle_pct / 100.0) for r in cut if r.saturated),
    }
