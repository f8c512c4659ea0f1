"""Anticipation for the adaptive feed loop: where the cutter is on its pass, and the override the
stock ahead asks for, set before the cutter gets there (the feed-forward commercial adaptive
controls and seed 001's offline feeds use), the measured force correcting what is left.

Position: the pass is one feed block along +X (a campaign's cut), so the cutter's place follows
from one anchor and the overrides since: the anchor is fitted to the first cutting revolution and
the few before it (their measured means against the predicted entry, :meth:`FeedForward.anchor`),
then ``x`` moves at the programmed feed times the override GRBL runs, each change from its byte's
time plus GRBL's byte-to-motion delay (``APPLY_DELAY_S``). All on the run clock: deterministic.

Override: at each DAQ read the loop asks for the override whose predicted force, where the cutter
will be when GRBL runs a byte sent now, is the target divided by ``gain`` (measured over predicted
force on the last steady revolutions, the feedback), and sends it when the override running
would miss the target by more than half the dead band. Within the override's limits and the
slew limits per revolution; where no override reaches the target, the limit nearest it.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from rig.adaptive.predict import X_STEP_MM, LoadProfile
from rig.adaptive.saturation import Limits


class Slew(Limits, Protocol):
    """What the feed-forward reads of the loop's settings (rig.adaptive.AdaptiveSettings)."""

    @property
    def slew_up_pct(self) -> int: ...
    @property
    def slew_down_pct(self) -> int: ...


#: measured / predicted force: how fast the gain follows steady revolutions, and its bounds
GAIN_RATE = 0.5
GAIN_RANGE = (0.67, 1.5)
#: a revolution is steady for the gain when the prediction over it and a revolution either side
#: varies by less than this share
STEADY_SHARE = 0.03
#: revolutions (the anchor's and up to this many before it) fitted to the predicted entry
ANCHOR_REVS = 4


class FeedForward:
    """See the module docstring. ``profile`` the pass's load table, ``rpm`` the spindle's,
    ``delay_s`` GRBL's byte-to-motion delay."""

    def __init__(self, profile: LoadProfile, target_n: float, air_n: float, delay_s: float):
        self.p = profile
        self.target_n = target_n
        self.air_n = air_n
        self.delay_s = delay_s
        self.rev_s = 60.0 / profile.rpm
        self.anchor_t_s: float | None = None
        self.anchor_x_mm = math.nan
        self.changes: list[tuple[float, int]] = [(-math.inf, 100)]  # (run s GRBL runs it, %)
        self.gain = 1.0
        self.done = False
        self._revs: list[tuple[float, float]] = []  # (end s, mean N) before the anchor
        cutting = profile.force_n[:, np.searchsorted(np.arange(10, 201, 2), 100)] > air_n
        self.x_last_cut_mm = float(profile.x_mm[np.flatnonzero(cutting)[-1]]) if cutting.any() \
            else -math.inf  # fmt: skip

    # -- the cutter's place ----------------------------------------------------------------------
    @property
    def active(self) -> bool:
        return self.anchor_t_s is not None and not self.done

    def pct_at(self, t_s: float) -> int:
        pct = 100
        for t, p in self.changes:
            if t <= t_s:
                pct = p
        return pct

    def commanded(self, t_runs_s: float, pct: int) -> None:
        """GRBL runs ``pct`` % from run-clock ``t_runs_s`` on."""
        self.changes.append((t_runs_s, int(pct)))

    def x_at(self, t_s: float) -> float:
        """Predicted position of the cutter's centre at run-clock ``t_s`` (after the anchor)."""
        if self.anchor_t_s is None:
            return math.nan
        v = self.p.feed_mm_min / 60.0 / 100.0  # mm/s per %
        x, t, pct = self.anchor_x_mm, self.anchor_t_s, self.pct_at(self.anchor_t_s)
        for tc, pc in self.changes:
            if tc <= t:
                continue
            if tc >= t_s:
                break
            x += v * pct * (tc - t)
            t, pct = tc, pc
        return x + v * pct * (t_s - t)

    def ran_over(self, t0_s: float, t1_s: float) -> int | None:
        """The override GRBL ran over all of (t0, t1), None when it changed in between."""
        p0 = self.pct_at(t0_s)
        if any(t0_s < t <= t1_s and p != p0 for t, p in self.changes):
            return None
        return p0

    # -- revolutions -----------------------------------------------------------------------------
    def predicted_rev_n(self, t_end_s: float) -> tuple[float, float]:
        """(predicted mean N over the revolution ending at ``t_end_s``, its spread: the largest
        relative change of the prediction over it and a revolution either side)."""
        ts = t_end_s - self.rev_s * (np.arange(10) + 0.5) / 10
        xs = np.array([self.x_at(t) for t in ts])
        ps = np.array([self.pct_at(t) for t in ts])
        f = self.p.force_at(xs, ps)
        rev_mm = float(xs[0] - xs[-1]) * 10 / 9
        wide = self.p.force_at(np.linspace(xs[-1] - rev_mm, xs[0] + rev_mm, 15), ps.mean())
        mean = float(f.mean())
        spread = float((wide.max() - wide.min()) / mean) if mean > 0 else math.inf
        return mean, spread

    def on_revolution(self, t_end_s: float, force_n: float, cutting: bool) -> str | None:
        """A judged revolution: anchors the pass at the first cutting one (a note's text back),
        then keeps the gain; after the cut ends, done."""
        if self.done:
            return None
        if self.anchor_t_s is None:
            self._revs = (self._revs + [(t_end_s, force_n)])[-ANCHOR_REVS:]
            return self._anchor() if cutting else None
        if not cutting or self.x_at(t_end_s) > self.x_last_cut_mm + self.p.feed_mm_min / self.p.rpm:
            self.done = True
            return f"feed-forward: pass ended at x = {self.x_at(t_end_s):.2f} mm"
        pred, spread = self.predicted_rev_n(t_end_s)
        if pred > 2 * self.air_n and spread < STEADY_SHARE:
            g = self.gain + GAIN_RATE * (force_n / pred - self.gain)
            self.gain = min(max(g, GAIN_RANGE[0]), GAIN_RANGE[1])
        return None

    def _anchor(self) -> str:
        """Fit the cutter's place at the last revolution's end to the revolutions seen: each
        revolution's measured mean against the predicted mean over the span it cut."""
        t_last = self._revs[-1][0]
        v = self.p.feed_mm_min / 60.0 / 100.0
        rev_k = max(1, int(round(v * self.pct_at(t_last) * self.rev_s / X_STEP_MM)))
        xs = self.p.x_mm
        pct = np.full(xs.shape, float(self.pct_at(t_last)))
        inst = self.p.force_at(xs, pct)
        cum = np.concatenate([[0.0], np.cumsum(inst)])
        rev_mean = (cum[rev_k:] - cum[:-rev_k]) / rev_k  # window ending at xs[rev_k - 1:]
        ends = xs[rev_k - 1 :]
        # the first cutting revolution is on the entry: search up to where the prediction first
        # passes three times the air level, and two revolutions on
        up = np.flatnonzero(rev_mean >= 3 * self.air_n)
        stop = min(len(ends), (int(up[0]) if up.size else len(ends)) + 2 * rev_k + 1)
        err = np.zeros(stop)
        for t, m in self._revs:
            back = int(round(v * self.pct_at(t) * (t_last - t) / X_STEP_MM))
            j = np.arange(stop) - back
            pred = np.where(j >= 0, rev_mean[np.clip(j, 0, None)], 0.0)
            err += (pred - m) ** 2
        i = int(np.argmin(err))
        best, best_err = float(ends[i]), float(err[i])
        self.anchor_t_s, self.anchor_x_mm = t_last, float(best)
        rms = math.sqrt(best_err / len(self._revs))
        return (f"feed-forward: anchored at x = {best:.2f} mm at t = {t_last:.4f} s (fit of "
                f"{len(self._revs)} revolutions, rms {rms:.1f} N)")  # fmt: skip

    # -- the override ----------------------------------------------------------------------------
    def next_override(self, t_s: float, pct_now: int, s: Slew, block_s: float
                      ) -> tuple[int, str] | None:  # fmt: skip
        """:meth:`want` within the settings ``s``' limits and slew per revolution (from what
        GRBL runs a revolution before a byte sent now would run)."""
        base = self.pct_at(t_s + self.delay_s - self.rev_s)
        lo = max(s.min_pct, base - s.slew_down_pct)
        hi = min(s.max_pct, base + s.slew_up_pct)
        return self.want(t_s, pct_now, lo, hi, s.dead_band_pct / 2.0, block_s)

    def want(self, t_s: float, pct_now: int, lo: int, hi: int, band_pct: float,
             block_s: float) -> tuple[int, str] | None:  # fmt: skip
        """(the override to send now, why) or None: the one whose predicted force where the
        cutter will be once GRBL runs it (half a DAQ read on) is the target over the gain."""
        if not self.active:
            return None
        t_run = t_s + self.delay_s
        x = self.x_at(t_run) + self.p.feed_mm_min / 60.0 * pct_now / 100.0 * block_s / 2
        if x > self.x_last_cut_mm:
            return None
        goal = self.target_n / self.gain
        now_n = float(self.p.force_at(x, pct_now))
        if abs(now_n / goal - 1.0) * 100.0 <= band_pct and lo <= pct_now <= hi:
            return None
        new, _ = self.p.pct_for(x, goal, lo, hi)
        if new == pct_now:
            return None
        new_n = float(self.p.force_at(x, new)) * self.gain
        return new, (f"feed-forward at x = {x:.2f} mm: predicted {now_n * self.gain:.0f} N at "
                     f"{pct_now} %, {new_n:.0f} N at {new} % (target {self.target_n:.0f} N, gain "
                     f"{self.gain:.3f}): feed {pct_now} -> {new} %")  # fmt: skip
