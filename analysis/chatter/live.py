"""Chatter judged on a live window of the force, read by read: the campaign's chatter suspender
(:mod:`rig.campaign.chatter_watch`) and the adaptive controller's chatter check.

What a short window can resolve (bench/bench_chatter_live.py, the regenerative twin): the
detector keeps ``band_bins`` FFT bins around every spindle harmonic out of judgement (a Hann
window's main lobe is 2 bins) and judges the stretch less one revolution at each end. A window
of W revolutions has bins f_sp / (W - 2) apart, so 3 bins put 3 / (W - 2) of every spindle
interval on each side of a harmonic out of sight: with W = 10, 0.375 f_sp each side, 75 % of the
spectrum. Chatter within 0.375 f_sp of a spindle harmonic was never chatter: 17 of the 18
held-out cuts the former 10-revolution interlock missed had it 0.01-0.30 f_sp from one. Its
false alarms came from the cutter leaving the block: the force level falls over the cutter's
radius, a harmonic whose amplitude changes within the window is spread off it, and the window
spanned that (every false alarm of the calibration half was there, none in steady cutting).

So the watch judges W = 20 revolutions (bins f_sp / 18; 2 bins, the Hann main lobe, kept around
each harmonic: 0.11 f_sp each side, 78 % of the spectrum judged; the energy threshold half the
detector's), only windows cut at a steady level (the mean resultant of the last third of the
revolutions within ``STEADY_LEVEL`` of the first third's), at most once per ``JUDGE_S`` of
samples, and acts on ``CONFIRM`` chattering verdicts in a row whose power off the harmonics holds
(at least ``growth_ratio`` of the one before: the vibration the entry leaves near the limit dies
out over a few windows, chatter does not). On the bench's held-out half: 0 of 77 stable cuts
stopped, 2 of 74 chattering cuts beyond 1.1 x the limit missed (the former window: 2 and 18).
Latency: 20 revolutions of steady cut plus one more verdict, ``JUDGE_S`` (at 6000 rpm 200 + 100
ms); on the twin, median 36 revolutions (300 ms) from the start of the cut. Blind while the
level changes (entry and exit ramps) and to chatter within 0.11 f_sp of a spindle harmonic.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from analysis.chatter.detect import ChatterSettings, StretchChatter, indicators

#: Revolutions of force each live verdict judges (indicators drops one at each end).
CHATTER_WINDOW_REVS = 20
#: FFT bins around each spindle harmonic the live window keeps out of judgement: a Hann window's
#: main lobe (beyond it a steady harmonic leaks only its side lobes, -31 dB and falling).
LIVE_BAND_BINS = 2.0
#: The live window's energy threshold, of the detector's: the band is 2 bins of 18 revolutions,
#: 0.11 f_sp, twice the whole run's 0.05 f_sp, and a chatter line near it leaves part of its
#: main lobe inside (chosen on the bench's calibration half).
LIVE_ENERGY_SCALE = 0.5
#: Largest change of the mean resultant, last third of the window's revolutions against the
#: first third, over the window's mean, for the window to be judged (entry and exit ramps are not).
STEADY_LEVEL = 0.3
#: s of samples between two verdicts (the rig's DAQ read interval), whatever the DAQ's block size.
JUDGE_S = 0.1
#: Chattering verdicts in a row before the suspender acts.
CONFIRM = 2


def level_change(forces_n: np.ndarray, samples_per_rev: float) -> float:
    """|mean resultant of the last third of the whole revolutions - of the first third| over
    the mean of all (inf with fewer than 3 revolutions or no force)."""
    n_rev = int(len(forces_n) // samples_per_rev)
    if n_rev < 3:
        return math.inf
    edges = np.round(np.arange(n_rev + 1) * samples_per_rev).astype(np.int64)
    res = np.hypot(forces_n[:, 0], forces_n[:, 1]) if forces_n.shape[1] > 1 else forces_n[:, 0]
    means = np.add.reduceat(np.abs(res[: edges[-1]]), edges[:-1]) / np.diff(edges)
    k, mean = n_rev // 3, float(means.mean())
    return abs(float(means[-k:].mean() - means[:k].mean())) / mean if mean > 0 else math.inf


class ChatterWatch:
    """The chatter suspender: the last ``revolutions`` of Fx and Fy (N) of the cut, judged by
    :func:`analysis.chatter.indicators` every ``JUDGE_S`` of samples when the window cuts at a
    steady level (module docstring); revolutions under ``floor_n`` (air) never count as cutting.
    ``last`` is the latest verdict."""

    def __init__(
        self, channels: tuple[str, ...], rate_hz: float, spindle_rpm: float, floor_n: float,
        settings: ChatterSettings | None = None, revolutions: int = CHATTER_WINDOW_REVS,
    ) -> None:  # fmt: skip
        st = settings or ChatterSettings()
        self.settings = dataclasses.replace(
            st, band_bins=LIVE_BAND_BINS, energy_ratio=LIVE_ENERGY_SCALE * st.energy_ratio
        )
        self.cols = [channels.index(c) for c in ("Fx", "Fy") if c in channels] or [0, 1]
        self.rate_hz, self.spindle_rpm, self.floor_n = rate_hz, spindle_rpm, floor_n
        self.revolutions_needed = revolutions
        self.samples_per_rev = 60.0 * rate_hz / spindle_rpm
        self.n = int(math.ceil(revolutions * self.samples_per_rev))
        self.judge_every = max(1, int(round(JUDGE_S * rate_hz)))
        self.window = np.zeros((0, len(self.cols)))
        self.since_verdict = 0
        self.in_a_row = 0
        self.off_power_n2 = 0.0  # N^2 off the harmonics in the latest chattering verdict
        self.last: StretchChatter | None = None

    @staticmethod
    def describe() -> str:
        return f"{CHATTER_WINDOW_REVS} revs, steady, {CONFIRM} holding"

    def push(self, force_n: np.ndarray) -> str | None:
        """Add a read's forces (n, c) N; a message when the cut chatters, else None."""
        self.window = np.vstack([self.window, force_n[:, self.cols]])[-self.n :]
        self.since_verdict += len(force_n)
        if len(self.window) < self.n or self.since_verdict < self.judge_every:
            return None
        self.since_verdict = 0
        if level_change(self.window, self.samples_per_rev) > STEADY_LEVEL:
            self.in_a_row = 0  # entering or leaving the cut: not judged, and no run of verdicts
            self.off_power_n2 = 0.0
            return None
        v = indicators(self.window, self.rate_hz, self.spindle_rpm, self.settings,
                       floor_n=self.floor_n)  # fmt: skip
        self.last = v
        # Power off the harmonics must hold from one chattering verdict to the next (growth, as
        # the detector's within a stretch): the vibration left by the entry into the cut decays
        # over several windows near the limit (the twin's stable 0.6 mm slot at 5500 rpm: 0.11
        # then 0.06 of the power, over 0.2 s), chatter holds or grows.
        off_n2 = v.energy_ratio * float(self.window.var(axis=0).sum()) if v.chatter else 0.0
        holds = off_n2 >= self.settings.growth_ratio * self.off_power_n2
        self.in_a_row = (self.in_a_row + 1 if holds else 1) if v.chatter else 0
        self.off_power_n2 = off_n2
        if self.in_a_row < CONFIRM:
            return None
        return (f"chatter at {v.frequency_hz:.0f} Hz (energy {v.energy_ratio:.2f}, opr "
                f"{v.opr_ratio:.2f})")  # fmt: skip
