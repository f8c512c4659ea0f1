"""The figures of an adaptive run from its run file (the report and the tests use them): the
per-revolution mean feed-plane resultant as the AFC report measures evenness
(:func:`rig.report.afc.cutting_revolutions`: the revolutions from the first to the last that cut,
entry and exit included), the share of that cutting time within +-10 % of the target, and the
cycle time (program start to program end, from the run's events)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from analysis.runs import file as rf


def within_band(lr: Any, target_n: float, band: float = 0.10) -> dict[str, Any]:
    """{within (fraction of the cutting revolutions within +-band of target), revolutions,
    cut_time_s, means (N per cutting revolution)}; within is NaN when nothing cut."""
    from rig.report.afc import cutting_revolutions

    s = cutting_revolutions(lr)
    cut = s["cut"]
    if cut.size < 3:
        return {"within": math.nan, "revolutions": int(cut.size), "cut_time_s": math.nan,
                "means": np.zeros(0)}  # fmt: skip
    means = s["means"][int(cut[0]) : int(cut[-1]) + 1]
    ok = np.abs(means / target_n - 1.0) <= band
    return {"within": float(ok.mean()), "revolutions": int(means.size),
            "cut_time_s": float(s["cut_time_s"]), "means": means}  # fmt: skip


def _events(run: rf.Run) -> list[tuple[str, str, float]]:
    ev = run.events
    return list(zip(ev["kind"], ev["message"], ev["time_s"].astype(float), strict=True))


def cycle_time_s(run: rf.Run) -> float:
    """Run-clock s from the streaming start event to the last executed block's end (NaN when
    the run file does not tell)."""
    t0, t1 = math.nan, -math.inf
    for kind, msg, t in _events(run):
        if kind == rf.EV_START and math.isnan(t0):
            t0 = t
        if kind == rf.EV_NOTE and msg.startswith("executed block "):
            try:
                t1 = max(t1, float(msg.split()[3].split("..")[1].rstrip(":s")))
            except (IndexError, ValueError):
                continue
    return t1 - t0 if math.isfinite(t1) else math.nan


def adaptive_events(run: rf.Run) -> list[tuple[float, str, str]]:
    """(time s, kind, message) of the controller's events (message starts ``adaptive:``)."""
    return [(t, k, m) for k, m, t in _events(run) if m.startswith("adaptive:")]
