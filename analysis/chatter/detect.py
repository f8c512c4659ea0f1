"""Chatter detection from cutting forces: three indicators per stretch of steady cutting.

- Spectrum: the share of the force's (AC) energy up to ``max_hz`` (default 0.3 x the rate)
  away from the spindle's harmonics, so away from every tooth-passing harmonic. A stable cut is
  periodic with the spindle (tooth passing and runout are spindle harmonics), chatter is not: it
  adds a component near a structural mode and its sidebands f_c + k f_tooth. The stretch is
  Hann-windowed (a harmonic's leakage stays within a few bins), the spindle frequency is taken
  from the record (its strongest harmonic's peak within ``speed_tolerance`` of the commanded
  speed), and a band of ``harmonic_band`` x the spindle frequency (at least 3 bins) around each
  harmonic is never chatter: a force level changing within the stretch (entry, exit) spreads a
  harmonic by a few Hz (a stable 3-flute cut at 6000 rpm was once "chatter at 297 Hz", its
  300 Hz tooth frequency). The strongest component off the bands is the chatter frequency.
- Once-per-revolution sampling (Schmitz, Medicus & Dutterer 2002): samples taken at the same
  spindle angle, revolution after revolution, repeat in a stable cut and scatter under chatter.
  The statistic is the variance of those samples (averaged over ``phases`` angles per
  revolution) over the variance of the whole signal: ~0 stable, towards 1 under chatter.
- Growth: the RMS of the part off the harmonic bands over the last third of the stretch over
  its first third. A stable cut's entry transient dies out (below 1); chatter grows, or holds
  once the tool leaves the cut (about 1 and above).

A stretch chatters when all three exceed their thresholds (energy alone is fooled by a force
level that changes within the stretch, the sampling by noise on a light cut, growth by noise).
The defaults (energy 0.1, opr 0.2, growth 0.8, band 0.05) are calibrated on the regenerative
twin (``bench/bench_chatter_detect.py``: 330 calibration and 252 held-out cuts, 2-4 teeth,
slot, half and quarter immersion up and down, 0.5-1.5 x the semi-discretization limit, the
truth from the twin's true force). Blind spot: period-doubling chatter of a cutter with an even
tooth count sits at odd multiples of half the tooth frequency, which are spindle harmonics
(where runout also puts lines), so it is seen only through its sidebands.

Only cutting revolutions are judged: those whose mean resultant lies above ``cut_fraction`` of
the way from the stretch's quietest revolutions (5th percentile: air, if any) to its busiest
(95th), or above ``cut_fraction`` of the busiest, whichever is lower; the longest run of them,
less one at each end (entry and exit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from analysis.errors import AnalysisError

if TYPE_CHECKING:
    from analysis.runs import Run


@dataclass(frozen=True)
class ChatterSettings:
    """Thresholds: ``energy_ratio`` (share of AC energy off the spindle harmonics),
    ``opr_ratio`` (once-per-revolution variance over total variance), ``growth_ratio`` (RMS
    off the harmonics, last third over first third); ``min_revolutions`` a stretch needs to be
    judged; ``cut_fraction`` where a revolution starts to count as cutting (module docstring);
    ``harmonic_band_hz`` half-width kept around each spindle harmonic (default:
    ``harmonic_band`` x the spindle frequency, at least ``band_bins`` FFT bins: the Hann
    window's main lobe is 2; 2 instead of 3 halves the interlock's misses on the twin and more
    than doubles its false alarms); ``speed_tolerance`` how far
    (relative) the spindle may run from the commanded speed; ``max_hz`` the highest frequency
    judged (default 0.3 x the rate: above it a DAQ's aliases fold harmonics off the harmonics);
    ``phases`` per revolution."""

    energy_ratio: float = 0.1
    opr_ratio: float = 0.2
    min_revolutions: int = 6
    cut_fraction: float = 0.5
    harmonic_band_hz: float | None = None
    phases: int = 16
    growth_ratio: float = 0.8
    harmonic_band: float = 0.05
    speed_tolerance: float = 0.01
    max_hz: float | None = None
    band_bins: float = 3.0

    def __post_init__(self) -> None:
        if not self.growth_ratio > 0:
            raise AnalysisError(f"chatter settings: growth_ratio = {self.growth_ratio}: "
                                "expected > 0")  # fmt: skip
        for name in ("energy_ratio", "opr_ratio", "cut_fraction", "harmonic_band",
                     "speed_tolerance"):  # fmt: skip
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
    without one), ``frequency_hz`` the strongest component off the spindle harmonics;
    ``growth`` (last third over first third), ``spindle_rpm_measured`` (from the record) and
    ``band_hz`` (the half-width kept around each harmonic).
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
    growth: float = math.nan
    spindle_rpm_measured: float = math.nan
    band_hz: float = math.nan


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

    def table(self) -> list[dict[str, object]]:
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


def _spindle_hz(p: np.ndarray, f: np.ndarray, f_sp0: float, tol: float) -> float:
    """The spindle frequency from the record: the strongest spindle harmonic's peak within
    ``tol`` of where the commanded speed puts it (parabolic interpolation on the zero-padded
    spectrum ``p`` at frequencies ``f``), divided by its order; the commanded one when no
    harmonic rises clear of its neighbourhood."""
    df = f[1] - f[0]
    best, f_sp = 0.0, f_sp0
    for k in range(1, int(min(f[-1] / f_sp0, 40)) + 1):
        lo, hi = np.searchsorted(f, [k * f_sp0 * (1 - tol), k * f_sp0 * (1 + tol)])
        if hi - lo < 3 or lo < 1 or hi >= len(p) - 1:
            continue
        i = lo + int(np.argmax(p[lo:hi]))
        if p[i] <= best or i in (lo, hi - 1):
            continue
        a, b, c = np.log(p[i - 1 : i + 2] + 1e-300)
        den = a - 2 * b + c
        shift = 0.5 * (a - c) / den if den < 0 else 0.0
        best, f_sp = p[i], (f[i] + shift * df) / k
    return float(f_sp)


def _off_harmonic_mask(f: np.ndarray, f_sp: float, half_hz: float) -> np.ndarray:
    return np.abs(f - np.round(f / f_sp) * f_sp) > half_hz


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
    # Hann-windowed, zero-padded spectrum: a harmonic's leakage stays within a few bins of it,
    # and its peak can be placed between bins (the spindle's true speed).
    n_fft = 1 << int(math.ceil(math.log2(4 * n)))
    p = (np.abs(np.fft.rfft(seg * np.hanning(n)[:, None], n_fft, axis=0)) ** 2).sum(axis=1)
    f = np.fft.rfftfreq(n_fft, 1.0 / rate_hz)
    f_sp = _spindle_hz(p, f, abs(spindle_rpm) / 60.0, st.speed_tolerance)
    # Never chatter near a spindle (so tooth-passing) harmonic: the band holds the window's
    # main lobe (2 bins) and a force level changing within the stretch (entry, exit, a ramp
    # in depth) that spreads each harmonic by a few Hz.
    half = st.harmonic_band_hz
    if half is None:
        half = max(st.harmonic_band * f_sp, st.band_bins * rate_hz / n)
    f_max = st.max_hz or 0.3 * rate_hz
    off = _off_harmonic_mask(f, f_sp, half) & (f <= f_max)
    total = p[1 : np.searchsorted(f, f_max, "right")].sum()
    p_off = np.where(off, p, 0.0)
    energy = float(p_off.sum() / total) if total > 0 else 0.0
    freq = float(f[np.argmax(p_off)]) if p_off.any() else nan
    # Growth: the part off the harmonics (masked in the unwindowed spectrum), its RMS over the
    # last third against the first third of the stretch. A stable cut's entry transient dies
    # out (< 1); chatter grows, or holds once the tool leaves the cut (>= 1).
    spec = np.fft.rfft(seg, axis=0)
    f_n = np.fft.rfftfreq(n, 1.0 / rate_hz)
    spec[~(_off_harmonic_mask(f_n, f_sp, half) & (f_n <= f_max))] = 0.0
    resid = np.fft.irfft(spec, n, axis=0)
    third = n // 3
    early = float(np.sqrt(np.mean(resid[:third] ** 2)))
    late = float(np.sqrt(np.mean(resid[-third:] ** 2)))
    growth = late / early if early > 0 else (math.inf if late > 0 else 0.0)
    # Once per revolution at `phases` angles (linear interpolation between samples).
    spr_true = rate_hz / f_sp
    t_rev = np.arange(int(n // spr_true)) * spr_true
    var_opr = (
        np.mean(
            [
                np.interp(t_rev + ph * spr_true / st.phases, np.arange(n), seg[:, c]).var()
                for ph in range(st.phases)
                for c in range(seg.shape[1])
            ]
        )
        * seg.shape[1]
    )
    var_all = seg.var(axis=0).sum()
    opr = float(var_opr / var_all) if var_all > 0 else 0.0
    chatter = energy > st.energy_ratio and opr > st.opr_ratio and growth > st.growth_ratio
    return StretchChatter(block, t0_s + first / rate_hz, t0_s + (first + n) / rate_hz, revs,
                          True, chatter, freq, energy, opr, st.energy_ratio,
                          st.opr_ratio, "", growth, 60.0 * f_sp, half)  # fmt: skip


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


def detect_run(run: str | Path | Run, settings: ChatterSettings | None = None) -> RunChatter:
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
