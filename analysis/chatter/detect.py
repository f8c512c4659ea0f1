"""Chatter detection from cutting forces: two indicators per stretch of steady cutting.

- Spectrum: the share of the force's (AC) energy away from the spindle's harmonics. A stable
  cut is periodic with the spindle (tooth passing and runout are spindle harmonics), chatter is
  not: it adds a component near a structural mode and its sidebands f_c + k f_tooth. The
  record is cut to whole revolutions and not windowed, so the harmonics fall on FFT bins and do
  not leak. The strongest component away from the harmonics is the chatter frequency reported.
- Once-per-revolution sampling (Schmitz, Medicus & Dutterer 2002): samples taken at the same
  spindle angle, revolution after revolution, repeat in a stable cut and scatter under chatter.
  The statistic is the variance of those samples (averaged over ``phases`` angles per
  revolution) over the variance of the whole signal: ~0 stable, towards 1 under chatter.

A stretch chatters when both exceed their thresholds (either alone is fooled: the spectrum by a
force level that changes within the stretch, the sampling by noise on a light cut). Only
cutting revolutions are judged: those whose mean resultant lies above ``cut_fraction`` of the way
from the stretch's quietest revolutions (5th percentile: air, if any) to its busiest (95th), or
above ``cut_fraction`` of the busiest, whichever is lower; the longest run of them, less one at
each end (entry and exit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.errors import AnalysisError


@dataclass(frozen=True)
class ChatterSettings:
    """Thresholds: ``energy_ratio`` (share of AC energy off the spindle harmonics),
    ``opr_ratio`` (once-per-revolution variance over total variance); ``min_revolutions`` a
    stretch needs to be judged; ``cut_fraction`` where a revolution starts to count as cutting
    (module docstring); ``harmonic_band_hz`` half-width kept around each spindle harmonic
    (default: 2 % of the spindle frequency, at least one FFT bin); ``phases`` per revolution."""

    energy_ratio: float = 0.1
    opr_ratio: float = 0.1
    min_revolutions: int = 6
    cut_fraction: float = 0.5
    harmonic_band_hz: float | None = None
    phases: int = 16

    def __post_init__(self) -> None:
        for name in ("energy_ratio", "opr_ratio", "cut_fraction"):
            v = getattr(self, name)
            if not 0 < v < 1:
                raise AnalysisError(f"chatter settings: {name} = {v}: expected in (0, 1)")
        if self.min_revolutions < 3:
            raise AnalysisError(
                f"chatter settings: min_revolutions = {self.min_revolutions}: expected >= 3"
            )


@dataclass(frozen=True)
class StretchChatter:
    """The verdict on one stretch (an NC block, or a whole run with ``block = -1``).

    ``judged`` False (with ``reason``) when the stretch holds too few cutting revolutions;
    then ``chatter`` is False and the figures NaN. Times in s on the run clock (samples from 0
    without one), ``frequency_hz`` the strongest component off the spindle harmonics.
    """

    block: int
    start_s: float
    stop_s: float
    revolutions: int
    judged: bool
    chatter: bool
    frequency_hz: float
    energy_ratio: float
    opr_ratio: float
    energy_threshold: float
    opr_threshold: float
    reason: str = ""


@dataclass(frozen=True)
class RunChatter:
    """A run's verdict: ``chatter`` if any judged block (or the whole run) chatters;
    ``frequency_hz`` of the stretch with the largest energy ratio; per-block verdicts."""

    name: str
    chatter: bool
    frequency_hz: float
    whole: StretchChatter
    blocks: tuple[StretchChatter, ...]
    settings: ChatterSettings = field(default_factory=ChatterSettings)

    def chattering_blocks(self) -> list[int]:
        return [b.block for b in self.blocks if b.chatter]

    def table(self) -> list[dict[str, Any]]:
        return [vars(b).copy() for b in (self.whole, *self.blocks)]


def _samples_per_rev(rate_hz: float, spindle_rpm: float) -> float:
    if not (rate_hz > 0 and abs(spindle_rpm) > 0):
        raise AnalysisError(
            f"chatter: rate {rate_hz} Hz and spindle speed {spindle_rpm} rpm: both must be > 0"
        )
    return rate_hz * 60.0 / abs(spindle_rpm)


def _revolution_means(x: np.ndarray, spr: float) -> tuple[np.ndarray, np.ndarray]:
    """(edges, mean feed-plane resultant of each whole revolution)."""
    n_rev = int(len(x) // spr)
    edges = np.round(np.arange(n_rev + 1) * spr).astype(np.int64)
    res = np.hypot(x[:, 0], x[:, 1]) if x.shape[1] > 1 else np.abs(x[:, 0])
    if n_rev < 1:
        return edges, np.zeros(0)
    return edges, np.add.reduceat(res[: edges[-1]], edges[:-1]) / np.diff(edges)


def air_floor_n(forces_n: np.ndarray, rate_hz: float, spindle_rpm: float) -> float:
    """A resultant, N, that only cutting exceeds: 5 x the quietest revolutions' (10th
    percentile: air at the start and end of a run) where those are under a tenth of the busiest
    (95th percentile); 0 for a record that cuts throughout."""
    x = np.asarray(forces_n, dtype=float).reshape(len(forces_n), -1)
    _, means = _revolution_means(x, _samples_per_rev(rate_hz, spindle_rpm))
    if means.size == 0:
        return 0.0
    lo, hi = np.percentile(means, [10, 95])
    return float(5.0 * lo) if lo < 0.1 * hi else 0.0


def _cutting_stretch(
    x: np.ndarray, spr: float, cut_fraction: float, floor_n: float
) -> tuple[int, int]:
    """(first sample, revolutions) of the longest run of cutting revolutions, less one at
    each end."""
    edges, means = _revolution_means(x, spr)
    if means.size == 0:
        return 0, 0
    lo, hi = np.percentile(means, [5, 95])
    # Half way up from the air; a record that cuts throughout (lo near hi) keeps all of it.
    cut = (means > min(lo + cut_fraction * (hi - lo), cut_fraction * hi)) & (means > floor_n)
    # Longest run of consecutive cutting revolutions.
    best, start = (0, 0), None
    for i, c in enumerate(np.append(cut, False)):
        if c and start is None:
            start = i
        elif not c and start is not None:
            if i - start > best[1]:
                best = (start, i - start)
            start = None
    run0, count = best
    if count > 2:
        run0, count = run0 + 1, count - 2
    return int(edges[run0]) if count else 0, count


def indicators(
    forces_n: np.ndarray, rate_hz: float, spindle_rpm: float,
    settings: ChatterSettings | None = None, block: int = -1, t0_s: float = 0.0,
    floor_n: float = 0.0,
) -> StretchChatter:  # fmt: skip
    """Judge one stretch of forces (n, c) N (feed-plane channels first): module docstring.
    Revolutions whose mean resultant is at most ``floor_n`` N (the air, see
    :func:`air_floor_n`) never count as cutting."""
    st = settings or ChatterSettings()
    x = np.asarray(forces_n, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or not np.all(np.isfinite(x)):
        raise AnalysisError(f"chatter: forces of shape {x.shape} with NaN/inf: expected (n, c) N")
    spr = _samples_per_rev(rate_hz, spindle_rpm)
    stop_s = t0_s + len(x) / rate_hz
    first, revs = _cutting_stretch(x, spr, st.cut_fraction, floor_n)
    nan = math.nan
    if revs < st.min_revolutions:
        why = f"{revs} cutting revolutions (need {st.min_revolutions})"
        return StretchChatter(block, t0_s, stop_s, revs, False, False, nan, nan, nan,
                              st.energy_ratio, st.opr_ratio, why)  # fmt: skip
    n = int(round(revs * spr))
    seg = x[first : first + n]
    seg = seg - seg.mean(axis=0)
    # Spectrum over whole revolutions: energy per bin, summed over channels.
    p = (np.abs(np.fft.rfft(seg, axis=0)) ** 2).sum(axis=1)
    f = np.fft.rfftfreq(n, 1.0 / rate_hz)
    f_sp = abs(spindle_rpm) / 60.0
    half = st.harmonic_band_hz
    if half is None:
        half = max(0.02 * f_sp, 1.01 * rate_hz / n)
    near = np.abs(f - np.round(f / f_sp) * f_sp) <= half
    total = p[1:].sum()
    off = np.where(near, 0.0, p)
    energy = float(off.sum() / total) if total > 0 else 0.0
    freq = float(f[np.argmax(off)]) if off.any() else nan
    # Once per revolution at `phases` angles (linear interpolation between samples).
    t_rev = np.arange(revs) * spr
    var_opr = np.mean(
        [
            np.interp(t_rev + ph * spr / st.phases, np.arange(n), seg[:, c]).var()
            for ph in range(st.phases)
            for c in range(seg.shape[1])
        ]
    ) * seg.shape[1]
    var_all = seg.var(axis=0).sum()
    opr = float(var_opr / var_all) if var_all > 0 else 0.0
    chatter = energy > st.energy_ratio and opr > st.opr_ratio
    return StretchChatter(block, t0_s + first / rate_hz, t0_s + (first + n) / rate_hz, revs,
                          True, chatter, freq, energy, opr, st.energy_ratio,
                          st.opr_ratio)  # fmt: skip


def detect_chatter(
    forces_n: np.ndarray, rate_hz: float, spindle_rpm: float,
    blocks: np.ndarray | None = None, time_s: np.ndarray | None = None,
    settings: ChatterSettings | None = None, name: str = "",
) -> RunChatter:  # fmt: skip
    """Per-block and whole-record verdicts; ``blocks`` (n,) the NC block of each sample (-1:
    none), ``time_s`` (n,) the sample times (default: from 0 at the rate). The air level of
    the whole record (:func:`air_floor_n`) keeps blocks that do not cut out of judgement."""
    st = settings or ChatterSettings()
    x = np.asarray(forces_n, dtype=float)
    t = np.arange(len(x)) / rate_hz if time_s is None else np.asarray(time_s, dtype=float)
    floor = air_floor_n(x, rate_hz, spindle_rpm)
    whole = indicators(x, rate_hz, spindle_rpm, st, -1, float(t[0]) if len(t) else 0.0, floor)
    verdicts = []
    if blocks is not None:
        b = np.asarray(blocks)
        if b.shape != (len(x),):
            raise AnalysisError(f"chatter: blocks of shape {b.shape}, forces {x.shape}")
        change = np.flatnonzero(np.diff(b)) + 1
        for lo, hi in zip(np.r_[0, change], np.r_[change, len(b)]):
            if b[lo] >= 0:
                verdicts.append(indicators(x[lo:hi], rate_hz, spindle_rpm, st, int(b[lo]),
                                           float(t[lo]), floor))  # fmt: skip
    judged = [v for v in (whole, *verdicts) if v.judged]
    worst = max(judged, key=lambda v: v.energy_ratio, default=whole)
    return RunChatter(name, any(v.chatter for v in judged), worst.frequency_hz, whole,
                      tuple(verdicts), st)  # fmt: skip


def detect_run(run: Any, settings: ChatterSettings | None = None) -> RunChatter:
    """Verdicts for a run file (path or ``analysis.runs.Run``), per executed NC block."""
    from analysis.runs import load_run

    r = load_run(run) if isinstance(run, str | Path) else run
    rpm = r.conditions.get("spindle_rpm")
    if not isinstance(rpm, int | float) or not rpm:
        raise AnalysisError(f"{r.path}: conditions.spindle_rpm = {rpm!r}: expected rpm > 0")
    if r.force_n is None:
        raise AnalysisError(f"{r.path}: the run has no calibration, so no forces in N")
    names = list(r.channel_names)
    cols = [names.index(c) for c in ("Fx", "Fy") if c in names] or list(range(min(2, len(names))))
    return detect_chatter(r.force_n[:, cols], r.rate_hz, float(rpm), r.executing_block(),
                          r.time_s, settings, Path(r.path).name)  # fmt: skip
