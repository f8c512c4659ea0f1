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
from typing import TYPE_CHECKING

import numpy as np

from analysis.runs import file as rf
from rig.report.results import BandFigures, ChatterDecay

if TYPE_CHECKING:
    from rig.report.base import LoadedRun


def within_band(lr: LoadedRun, target_n: float, band: float = 0.10) -> BandFigures:
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


#: The post-move stretch ends where the cut leaves the block: the first revolution whose mean
#: resultant falls below this share of the steady level (the median of the first 20 after the move).
EXIT_LEVEL = 0.9
#: Revolutions kept off the stretch's end: the whole-stretch spectrum's edge puts the cut-off
#: ends' mismatch into the part off the harmonics (0.02 -> 0.08 over the last 3 on the twin).
EDGE_REVS = 2
#: Gone: below the threshold for this many revolutions in a row (the live watch's window), or to
#: the stretch's end. The exit spreads the harmonics before the level falls (0.03 -> 0.26 over
#: the last 4 revolutions on the twin), so "to the end of the cut" would count the exit.
HOLD_REVS = 20


def chatter_decay(
    run: rf.Run, t_move_s: float, rpm: float, threshold: float = 0.1
) -> ChatterDecay:  # fmt: skip
    """The chatter component per revolution after a spindle move at run-clock ``t_move_s`` to
    ``rpm``: the force's part off the spindle harmonics (the detector's energy indicator: the
    post-move steady stretch's spectrum with a band of max(0.05 f_sp, 3 bins) kept out around
    each harmonic, back to time), its energy over each revolution's AC energy. ``cleared_revs``:
    the revolutions from the move to the first one from which the share stays below
    ``threshold`` (the detector's ``energy_ratio``) for ``HOLD_REVS`` revolutions (or to the
    end of the steady cut); None when it never does. Also ``shares`` and the residual's RMS N
    per revolution."""
    out: ChatterDecay = {"cleared_revs": None, "shares": [], "rms_n": [], "revolutions": 0}
    if run.force_n is None:  # no calibration: no force to judge
        return out
    x = np.asarray(run.force_n[:, :2], float)
    rate = float(run.rate_hz)
    spr = rate * 60.0 / abs(rpm)
    i0 = int(np.searchsorted(run.time_s, t_move_s))
    n_rev = int((len(x) - i0) // spr)
    if n_rev < 3 + EDGE_REVS:
        return out
    edges = i0 + np.round(np.arange(n_rev + 1) * spr).astype(np.int64)
    res = np.hypot(x[:, 0], x[:, 1])
    means = np.add.reduceat(res[edges[0] : edges[-1]], edges[:-1] - edges[0]) / np.diff(edges)
    low = means < EXIT_LEVEL * float(np.median(means[:20]))
    end = (int(np.argmax(low)) if low.any() else n_rev) - EDGE_REVS
    if end < 3:
        return out
    seg = x[edges[0] : edges[end]] - x[edges[0] : edges[end]].mean(axis=0)
    n = len(seg)
    spec = np.fft.rfft(seg, axis=0)
    f = np.fft.rfftfreq(n, 1.0 / rate)
    f_sp = abs(rpm) / 60.0
    half = max(0.05 * f_sp, 3.0 * rate / n)
    on = (np.abs(f - np.round(f / f_sp) * f_sp) <= half) | (f > 0.3 * rate)
    spec[on] = 0.0
    resid = np.fft.irfft(spec, n, axis=0)
    starts = edges[:end] - edges[0]
    e_res = np.add.reduceat((resid**2).sum(axis=1), starts)
    e_all = np.add.reduceat((seg**2).sum(axis=1), starts)
    shares = e_res / np.where(e_all > 0, e_all, np.inf)
    below = shares < threshold
    hold = min(HOLD_REVS, int(end))
    cleared = next((k for k in range(int(end) - hold + 1) if below[k : k + hold].all()), None)
    rms_n = np.sqrt(e_res / np.diff(edges[: end + 1]))
    return ChatterDecay(
        cleared_revs=cleared, shares=shares.tolist(), rms_n=rms_n.tolist(), revolutions=int(end)
    )
