"""The figures of an adaptive run from its run file (the report and the tests use them): the
per-revolution mean feed-plane resultant as the AFC report measures evenness
(:func:`rig.report.afc.cutting_revolutions`: the revolutions from the first to the last that cut,
entry and exit included), the share of that cutting time within +-10 % of the target, and the
cycle time (program start to program end, from the run's events). The controller's saturation
events (``adaptive: saturated ...`` / ``saturation ended: N revolutions at the limit, a..b s``)
mark where the target was out of reach of the override: :func:`within_band` counts the share over
all the cutting time and, apart, over the reachable time (the cutting revolutions outside those
spans), never the one as the other."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from analysis.runs import file as rf


def within_band(lr: Any, target_n: float, band: float = 0.10) -> dict[str, Any]:
    """{within (fraction of the cutting revolutions within +-band of target), revolutions,
    cut_time_s, means (N per cutting revolution), and over the reachable revolutions (those
    not inside a saturation span of the controller): within_reachable, reachable_revolutions,
    saturated_revolutions, saturated_s}; within is NaN when nothing cut."""
    from rig.report.afc import cutting_revolutions

    s = cutting_revolutions(lr)
    cut = s["cut"]
    if cut.size < 3:
        return {"within": math.nan, "revolutions": int(cut.size), "cut_time_s": math.nan,
                "means": np.zeros(0), "within_reachable": math.nan, "reachable_revolutions": 0,
                "saturated_revolutions": 0, "saturated_s": 0.0}  # fmt: skip
    first, last = int(cut[0]), int(cut[-1])
    means = s["means"][first : last + 1]
    ok = np.abs(means / target_n - 1.0) <= band
    # revolution k of per_revolution spans time_s[0] + [k, k + 1) periods: judged by its middle
    period = float(s["period_s"])
    mid = float(lr.run.time_s[0]) + (np.arange(first, last + 1) + 0.5) * period
    sat = np.zeros(means.size, bool)
    for t0, t1 in saturated_spans(lr.run):
        sat |= (mid >= t0) & (mid <= t1)
    reach = ~sat
    return {"within": float(ok.mean()), "revolutions": int(means.size),
            "cut_time_s": float(s["cut_time_s"]), "means": means,
            "within_reachable": float(ok[reach].mean()) if reach.any() else math.nan,
            "reachable_revolutions": int(reach.sum()), "saturated_revolutions": int(sat.sum()),
            "saturated_s": float(sat.sum() * period)}  # fmt: skip


def saturated_spans(run: rf.Run) -> list[tuple[float, float]]:
    """(start, end) run-clock s of each stretch the controller reported at an override limit
    with the target out of reach (its ``saturation ended`` events)."""
    import re

    out = []
    for kind, msg, _ in _events(run):
        m = re.search(r"saturation ended: \d+ revolutions at the limit, ([0-9.]+)\.\.([0-9.]+) s",
                      msg) if kind == rf.EV_NOTE else None  # fmt: skip
        if m:
            out.append((float(m.group(1)), float(m.group(2))))
    return out


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
