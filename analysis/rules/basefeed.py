"""Base feed from a feed sweep (seed 001 4.2, step 2).

Runs at increasing feed with everything else fixed (seed 001 Table 2: GM241, phi 30 ball end mill,
2000 rpm, 0.3 mm deep slot, 400..2200 mm/min in 10 steps). For each run: the resultant of the feed
and cross-feed forces per spindle revolution (mean and peak), and a vibration indicator, the RMS of
the force content away from the spindle and tooth-passing harmonics (chatter shows up there, runout
and the cutting itself do not). The base feed is the highest feed before

- the force-vs-feed slope rises sharply: the slope of interval i exceeds ``slope_ratio`` times the
  median slope of the intervals below it (at least ``min_reference_intervals`` of them), or
- the vibration jumps: the indicator at the interval's upper feed exceeds ``vibration_ratio`` times
  the median indicator of all lower feeds,

combined as configured (``criterion``: "any", "both", "slope" or "vibration"). The result states
the slopes, ratios and indicators per interval and which test fired, and a sweep with no such
change says so (``found=False``) instead of inventing a base feed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from analysis.errors import AnalysisError
from analysis.runs import per_revolution

#: how the slope and vibration indicators combine into a flag
Criterion = Literal["any", "both", "slope", "vibration"]


@dataclass(frozen=True)
class SweepRun:
    """One run of a feed sweep, steady cutting only.

    forces_n : ndarray, shape (n_samples, 2 or 3), N — feed (X), cross-feed (Y)[, axial (Z)].
    """

    feed_mm_min: float
    forces_n: NDArray[np.float64]
    rate_hz: float
    spindle_rpm: float
    flutes: int
    name: str = ""


@dataclass(frozen=True)
class BaseFeedSettings:
    slope_ratio: float = 1.6
    vibration_ratio: float = 2.0
    min_reference_intervals: int = 2
    criterion: Criterion = "any"
    harmonic_band_hz: float | None = (
        None  # half-width around each spindle harmonic; default 2 % of f_spindle
    )

    def __post_init__(self) -> None:
        if not self.slope_ratio > 1:
            raise AnalysisError(f"slope_ratio = {self.slope_ratio}: expected > 1")
        if not self.vibration_ratio > 1:
            raise AnalysisError(f"vibration_ratio = {self.vibration_ratio}: expected > 1")
        if self.min_reference_intervals < 1:
            raise AnalysisError(
                f"min_reference_intervals = {self.min_reference_intervals}: expected >= 1"
            )
        if self.criterion not in ("any", "both", "slope", "vibration"):
            raise AnalysisError(
                f"criterion = {self.criterion!r}: expected any, both, slope or vibration"
            )


@dataclass(frozen=True)
class RunSummary:
    feed_mm_min: float
    revolutions: int
    mean_resultant_n: float  # mean over revolutions of the per-revolution mean resultant
    peak_resultant_n: float  # mean over revolutions of the per-revolution peak resultant
    vibration_rms_n: float  # RMS of the content away from spindle harmonics
    name: str = ""


@dataclass(frozen=True)
class Interval:
    feed_lo_mm_min: float
    feed_hi_mm_min: float
    slope_n_per_mm_min: float
    reference_slope: float  # NaN where too few intervals below
    slope_ratio: float  # NaN where no reference
    vibration_ratio: float  # indicator at feed_hi / median indicator of lower feeds
    slope_jump: bool
    vibration_jump: bool
    flagged: bool


@dataclass(frozen=True)
class BaseFeedResult:
    found: bool
    base_feed_mm_min: float | None
    message: str
    runs: tuple[RunSummary, ...]
    intervals: tuple[Interval, ...]
    settings: BaseFeedSettings = field(default_factory=BaseFeedSettings)

    def table(self) -> list[dict[str, float | bool]]:
        return [vars(iv).copy() for iv in self.intervals]


def vibration_rms(
    signal: NDArray[np.float64],
    rate_hz: float,
    spindle_rpm: float,
    band_hz: float | None = None,
) -> float:
    """RMS (same unit as ``signal``) of the spectrum away from DC and spindle-frequency harmonics.

    Tooth-passing harmonics are spindle harmonics too, so cutting and runout are both excluded; what
    remains is noise plus vibration at other frequencies (chatter). The record is cut to a whole
    number of revolutions and not windowed, so the (large) harmonics fall on FFT bins instead of
    leaking into their neighbours, which would make the indicator grow with the force itself.
    """
    spr = rate_hz * 60.0 / spindle_rpm
    n_rev = int(len(signal) // spr)
    n = int(round(n_rev * spr)) if n_rev >= 1 else len(signal)
    x = np.asarray(signal[:n], float)
    x = x - x.mean()
    spec = np.fft.rfft(x)
    # Mean square per one-sided bin (Parseval): the sum over all bins is the mean square of x.
    p = np.abs(spec) ** 2 / n**2
    p[1 : (n + 1) // 2] *= 2
    f = np.fft.rfftfreq(n, 1.0 / rate_hz)
    f_sp = spindle_rpm / 60.0
    half = band_hz if band_hz is not None else max(0.02 * f_sp, 1.01 * rate_hz / n)
    k = np.round(f / f_sp)
    near = np.abs(f - k * f_sp) <= half  # includes DC (k = 0)
    return float(np.sqrt(np.sum(p[~near])))


def summarise_run(run: SweepRun, band_hz: float | None = None) -> RunSummary:
    f = np.asarray(run.forces_n, float)
    if f.ndim != 2 or f.shape[1] < 2:
        raise AnalysisError(
            f"run {run.name or run.feed_mm_min}: forces_n has shape {f.shape}; expected "
            "(n_samples, 2 or 3) N with feed and cross-feed columns"
        )
    if not np.all(np.isfinite(f[:, :2])):
        raise AnalysisError(f"run {run.name or run.feed_mm_min}: forces contain NaN or inf")
    resultant = np.hypot(f[:, 0], f[:, 1])
    means, peaks = per_revolution(resultant, run.rate_hz, run.spindle_rpm)
    if means.mean() < 1e-9:
        raise AnalysisError(
            f"run {run.name or run.feed_mm_min}: no cutting force in it (mean resultant "
            f"{means.mean():.3g} N)"
        )
    vib = vibration_rms(resultant, run.rate_hz, run.spindle_rpm, band_hz)
    return RunSummary(
        run.feed_mm_min, len(means), float(means.mean()), float(peaks.mean()), vib, run.name
    )


def find_base_feed(
    runs: Sequence[SweepRun], settings: BaseFeedSettings | None = None
) -> BaseFeedResult:
    """Seed 001 step 2: the highest feed before the force slope or the vibration jumps."""
    st = settings or BaseFeedSettings()
    need = st.min_reference_intervals + 2
    if len(runs) < need:
        raise AnalysisError(
            f"{len(runs)} sweep runs: need at least {need} (min_reference_intervals "
            f"{st.min_reference_intervals} + 2) to judge a slope change"
        )
    runs = sorted(runs, key=lambda r: r.feed_mm_min)
    feeds = np.array([r.feed_mm_min for r in runs])
    dup = np.flatnonzero(np.diff(feeds) <= 0)
    if dup.size:
        raise AnalysisError(
            f"two sweep runs at feed {feeds[dup[0]]} mm/min: each feed once (merge or drop one)"
        )
    summ = tuple(summarise_run(r, st.harmonic_band_hz) for r in runs)
    force = np.array([s.mean_resultant_n for s in summ])
    vib = np.array([s.vibration_rms_n for s in summ])
    slopes = np.diff(force) / np.diff(feeds)
    intervals = []
    first = None
    for i, s in enumerate(slopes):
        if i >= st.min_reference_intervals:
            ref = float(np.median(slopes[:i]))
            ratio = s / ref if ref > 0 else math.inf
            slope_jump = bool(ratio > st.slope_ratio)
        else:
            ref, ratio, slope_jump = math.nan, math.nan, False
        vref = float(np.median(vib[: i + 1]))
        vratio = vib[i + 1] / vref if vref > 0 else math.inf
        vib_jump = bool(vratio > st.vibration_ratio) and i + 1 >= st.min_reference_intervals
        flagged = {
            "any": slope_jump or vib_jump,
            "both": slope_jump and vib_jump,
            "slope": slope_jump,
            "vibration": vib_jump,
        }[st.criterion]
        intervals.append(
            Interval(
                float(feeds[i]),
                float(feeds[i + 1]),
                float(s),
                ref,
                float(ratio),
                float(vratio),
                slope_jump,
                vib_jump,
                flagged,
            )
        )
        if flagged and first is None:
            first = i
    if first is None:
        max_sr = np.nanmax([iv.slope_ratio for iv in intervals]) if intervals else math.nan
        max_vr = max(iv.vibration_ratio for iv in intervals)
        msg = (
            f"no sharp change over {feeds[0]:g}..{feeds[-1]:g} mm/min: largest slope ratio "
            f"{max_sr:.2f} (threshold {st.slope_ratio}), largest vibration ratio {max_vr:.2f} "
            f"(threshold {st.vibration_ratio}); no base feed chosen — extend the sweep upward "
            "or set the base feed by hand"
        )
        return BaseFeedResult(False, None, msg, summ, tuple(intervals), st)
    iv = intervals[first]
    why = []
    if iv.slope_jump:
        why.append(f"force slope x{iv.slope_ratio:.2f} the median below (> {st.slope_ratio})")
    if iv.vibration_jump:
        why.append(f"vibration x{iv.vibration_ratio:.2f} the median below (> {st.vibration_ratio})")
    msg = (
        f"base feed {iv.feed_lo_mm_min:g} mm/min: between {iv.feed_lo_mm_min:g} and "
        f"{iv.feed_hi_mm_min:g} mm/min the " + " and ".join(why)
    )
    return BaseFeedResult(True, iv.feed_lo_mm_min, msg, summ, tuple(intervals), st)


@dataclass(frozen=True)
class Sweep:
    """Feed-sweep runs read from run files, and the load of their (common) test cut."""

    runs: tuple[SweepRun, ...]
    reference_load_pct: float | None  # seed 001 load of the sweep's slot, None if not derivable
    tool: str | None = None  # the tool every run names (configs/tools.toml), None if they differ


def sweep_runs_from_files(paths: Sequence[str | Path]) -> Sweep:
    """Read feed-sweep runs (``analysis.runs.file``) into :class:`SweepRun` s, steady part only.

    Each run's conditions must give ``feed_mm_min`` and ``spindle_rpm``, and ``flutes`` or a
    ``tool`` name from the tool library. The force channels used are Fx and Fy (else the first two).
    The reference load is the seed 001 load of a full slot at the runs' ``depth_mm`` with their
    tool, when every run names the same tool and depth.
    """
    from analysis.config import get_tool
    from analysis.forces.models import ENDMILL
    from analysis.rules.load import slot_load_percent
    from analysis.runs import load_run, steady_window

    runs, cuts, tools = [], set(), set()
    for path in paths:
        run = load_run(path)
        c = run.conditions
        where = f"{path}: conditions"
        for k in ("feed_mm_min", "spindle_rpm"):
            if not isinstance(c.get(k), int | float) or not c[k] > 0:
                raise AnalysisError(f"{where}.{k} = {c.get(k)!r}: expected a number > 0")
        tool = get_tool(c["tool"]) if isinstance(c.get("tool"), str) else None
        tools.add(c.get("tool") if isinstance(c.get("tool"), str) else None)
        flutes = c.get("flutes") or (getattr(tool, "flutes", None) if tool else None)
        if not isinstance(flutes, int) or flutes < 1:
            raise AnalysisError(f"{where}: neither flutes nor a known end-mill tool name given")
        if run.force_n is None:
            raise AnalysisError(f"{path}: the run has no calibration, so no forces in N")
        names = list(run.channel_names)
        cols = [names.index(n) for n in ("Fx", "Fy")] if {"Fx", "Fy"} <= set(names) else [0, 1]
        forces = run.force_n[:, cols]
        sl = steady_window(
            np.hypot(forces[:, 0], forces[:, 1]), run.rate_hz, float(c["spindle_rpm"])
        )
        runs.append(
            SweepRun(
                float(c["feed_mm_min"]),
                forces[sl],
                run.rate_hz,
                float(c["spindle_rpm"]),
                int(flutes),
                Path(path).name,
            )
        )
        if ENDMILL.describes(tool) and isinstance(c.get("depth_mm"), int | float):
            cuts.add(
                (
                    tool.kind,
                    tool.diameter_mm,
                    tool.corner_radius_mm,
                    tool.flute_length_mm,
                    float(c["depth_mm"]),
                )
            )
    ref = None
    if len(cuts) == 1:
        kind, dia, rc, flute, depth = cuts.pop()
        ref = slot_load_percent(kind, dia, depth, flute, rc)
    name = tools.pop() if len(tools) == 1 else None
    return Sweep(tuple(runs), ref, name)
