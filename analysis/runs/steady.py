"""The steady cutting part of a force record, offset removal, per-revolution statistics.

A run is a force record (n, c) at ``rate_hz`` taken while the spindle turns at ``spindle_rpm``:
usually some air before and after the cut, the cutter entering and leaving, and a steady part in
between. Everything here works on whole spindle revolutions:

- ``per_revolution(signal, rate_hz, spindle_rpm) -> (means, peaks)``: statistics of whole
  revolutions (a trailing partial revolution is left out);
- ``steady_window(signal, rate_hz, spindle_rpm) -> slice``: the steady cutting part of a 1-D
  signal (e.g. the resultant force) — the longest stretch of revolutions whose mean stays within
  ``tolerance`` of its median, one revolution trimmed at each end;
- ``find_steady(force_n, rate_hz, spindle_rpm) -> SteadyPart``: the same on a multi-channel record,
  with the dynamometer offset estimated from the air revolutions (linear in time when there is air
  on both sides, so slow charge-amplifier drift goes too) and the refined revolution period;
- ``SyncAverager``: synchronous (per-revolution) averaging into angle bins, fed chunk by chunk
  so a long record streams from HDF5 with memory bounded by the chunk size;
- ``tooth_peaks``: per-tooth peak forces and the runout they show.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from analysis.errors import AnalysisError
from analysis.runs.sync import SyncAverager, ToothPeaks, _indices, refine_period, tooth_peaks

__all__ = [
    "IDENTIFY_TOLERANCE",
    "NoAirError",
    "NoSteadyCutError",
    "RevolutionStats",
    "SteadyPart",
    "SyncAverager",
    "ToothPeaks",
    "engaged_revolutions",
    "find_steady",
    "per_revolution",
    "refine_period",
    "steady_from_stats",
    "steady_window",
    "tooth_peaks",
]


#: Steady window for force identification, as a fraction of the steady level: revolutions whose
#: mean force stays within it of the median count as steady. A face mill enters and leaves a block
#: over tens of revolutions; at 0.05 the last partly engaged ones count too and bias the fit
#: (seed 003 demo: P_R 18.1 instead of 19.6 N/mm, P_A 7.6 instead of 8 N/mm).
IDENTIFY_TOLERANCE = 0.02


class NoSteadyCutError(AnalysisError):
    """The record holds no cutting, or too few steady cutting revolutions: a run to leave out."""


class NoAirError(AnalysisError):
    """The record cuts from start to end: no air revolutions to take the offset from."""


def _samples_per_rev(rate_hz: float, spindle_rpm: float) -> float:
    if not rate_hz > 0:
        raise AnalysisError(f"rate_hz = {rate_hz}: must be > 0 (Hz)")
    if not abs(spindle_rpm) > 0:
        raise AnalysisError(f"spindle_rpm = {spindle_rpm}: the spindle must turn (rpm)")
    spr = rate_hz * 60.0 / abs(spindle_rpm)
    if spr < 8:
        raise AnalysisError(
            f"{spr:.3g} samples per revolution at rate_hz = {rate_hz} and spindle_rpm = "
            f"{spindle_rpm}: too few to resolve a revolution (need >= 8)"
        )
    return spr


def per_revolution(
    signal: ArrayLike, rate_hz: float, spindle_rpm: float
) -> tuple[np.ndarray, np.ndarray]:
    """Mean and peak of each whole revolution.

    ``signal`` shape (n,) or (n, c). Returns (means, peaks), shape (n_rev,) or (n_rev, c); the
    revolution boundaries are at round(k * samples_per_rev) from the first sample.
    """
    x = np.asarray(signal, float)
    spr = _samples_per_rev(rate_hz, spindle_rpm)
    n_rev = int(len(x) // spr)
    if n_rev == 0:
        return np.zeros((0,) + x.shape[1:]), np.zeros((0,) + x.shape[1:])
    edges = np.round(np.arange(n_rev + 1) * spr).astype(np.int64)
    means = np.add.reduceat(x[: edges[-1]], edges[:-1], axis=0) / np.diff(edges).reshape(
        (-1,) + (1,) * (x.ndim - 1)
    )
    peaks = np.maximum.reduceat(x[: edges[-1]], edges[:-1], axis=0)
    return means, peaks


#: Steady revolutions may differ from the median by this many robust standard deviations of
#: their scatter (when that is wider than the tolerance): a real cut's level wanders by a few per
#: cent (spindle-speed wobble, material), and a fixed window would keep only its quietest stretch.
SCATTER_SIGMAS = 4.0
#: Up to this many consecutive revolutions outside the window inside a steady stretch are kept
#: (a noisy revolution does not cut the stretch in two); a longer excursion ends the stretch.
MAX_GAP_REVS = 2


def _steady_stretch(
    level: np.ndarray, cutting: np.ndarray, tolerance: float
) -> tuple[int, int, int]:
    """(start, stop, outliers): the longest stretch of cutting revolutions within the window
    around the steady level, bridging gaps of up to MAX_GAP_REVS cutting revolutions;
    ``outliers`` counts the bridged revolutions."""
    if not cutting.any():
        return 0, 0, 0
    # The steady level is where the revolutions crowd (the mode), not the median of all cutting
    # revolutions: a face mill's entry and exit can take as many revolutions as its steady cut.
    lv = np.sort(level[cutting])
    width = 2 * tolerance * np.abs(lv) + 1e-12
    counts = np.searchsorted(lv, lv + width, side="right") - np.arange(len(lv))
    i = int(np.argmax(counts))
    med = float(np.median(lv[i : i + counts[i]]))
    near = cutting & (np.abs(level - med) <= 0.1 * abs(med))
    sigma = 1.4826 * float(np.median(np.abs(level[near] - med))) if near.any() else 0.0
    ok = cutting & (np.abs(level - med) <= max(tolerance * abs(med), SCATTER_SIGMAS * sigma))
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return 0, 0, 0
    # Split where more than MAX_GAP_REVS revolutions (or any air) separate two steady ones.
    gaps = np.diff(idx) - 1
    air_between = np.array([not cutting[i:j].all() for i, j in zip(idx[:-1], idx[1:])], bool)
    breaks = np.flatnonzero((gaps > MAX_GAP_REVS) | air_between)
    starts = np.concatenate([[0], breaks + 1])
    stops = np.concatenate([breaks, [len(idx) - 1]])
    k = int(np.argmax(idx[stops] - idx[starts]))
    lo, hi = int(idx[starts[k]]), int(idx[stops[k]]) + 1
    return lo, hi, int((hi - lo) - ok[lo:hi].sum())


def steady_window(
    signal: ArrayLike, rate_hz: float, spindle_rpm: float, tolerance: float = 0.05
) -> slice:
    """Sample slice of the steady cutting part of a 1-D signal (e.g. resultant force, N).

    Raises :class:`AnalysisError` when the record holds no cutting or fewer than 3 steady
    revolutions.
    """
    x = np.asarray(signal, float)
    if x.ndim != 1:
        raise AnalysisError(f"signal has shape {x.shape}: expected (n,)")
    try:
        part = find_steady(x[:, None], rate_hz, spindle_rpm, tolerance=tolerance, refine=False)
    except NoAirError:
        # A record that cuts throughout: a level such as the resultant stands out from 0.
        part = find_steady(
            x[:, None], rate_hz, spindle_rpm, tolerance=tolerance, refine=False, offset_n=0.0
        )
    return part.window


@dataclass(frozen=True)
class SteadyPart:
    """Where a run cuts steadily and what to subtract.

    ``window`` sample slice of the steady part (whole revolutions); ``offset_n`` (c,) offset at
    the window's start and ``drift_n_s`` (c,) its change per second (0 without air on both sides);
    ``period_s`` the revolution period (refined from the data when asked); ``cutting_revs`` and
    ``steady_revs`` counts; ``air_revs`` how many revolutions the offset came from;
    ``entry_revs``/``exit_revs`` the cutting revolutions before/after the window (entering,
    leaving, trimmed), ``outlier_revs`` revolutions inside it outside the window's band;
    ``entry_note`` whether the geometry's entry bound set the window ('' without a bound).
    """

    window: slice
    offset_n: np.ndarray
    drift_n_s: np.ndarray
    period_s: float
    cutting_revs: int
    steady_revs: int
    air_revs: int
    entry_revs: int = 0
    exit_revs: int = 0
    outlier_revs: int = 0
    entry_note: str = ""

    @property
    def kept(self) -> str:
        """How many cutting revolutions were kept and why the rest were dropped, one line."""
        why = f"dropped {self.entry_revs} entry, {self.exit_revs} exit"
        if self.outlier_revs:
            why += f"; {self.outlier_revs} kept outside the band (isolated)"
        if not self.air_revs:
            why += "; no air: offset from the record's zero"
        if self.entry_note:
            why += f"; {self.entry_note}"
        return f"kept {self.steady_revs} of {self.cutting_revs} cutting revolutions; {why}"

    def with_period(self, period_s: float, rate_hz: float) -> SteadyPart:
        """The same part with a refined period, cut to whole revolutions of it."""
        # A period a hair longer than nominal must not cost a whole revolution (the window
        # always has the trimmed revolution after it to spare the fraction of a sample).
        n_whole = int((self.window.stop - self.window.start) / (period_s * rate_hz) + 0.01)
        stop = self.window.start + int(round(n_whole * period_s * rate_hz))
        return replace(self, window=slice(self.window.start, stop), period_s=period_s)

    def corrected(self, force_n: np.ndarray, first_sample: int, rate_hz: float) -> np.ndarray:
        """Subtract offset and drift from samples starting at absolute index ``first_sample``."""
        t = (first_sample + np.arange(len(force_n)) - self.window.start) / rate_hz
        return np.asarray(force_n - self.offset_n - t[:, None] * self.drift_n_s)


class RevolutionStats:
    """Per-revolution sums of a record fed in chunks (for streaming a long run from disk).

    Revolution k spans samples [round(k spr), round((k + 1) spr)) from sample 0; ``add(chunk,
    first_sample)`` accumulates sums and sums of squares per revolution and channel.
    """

    def __init__(
        self, rate_hz: float, spindle_rpm: float, n_samples: int, channels: int,
        noise: bool = True,
    ) -> None:  # fmt: skip
        """``noise``: also estimate the noise level (:attr:`hf_noise_n`; the steady-part search
        needs it, a second pass over a known window does not: a third of the work)."""
        self.noise = noise
        self.spr = _samples_per_rev(rate_hz, spindle_rpm)
        self.n_rev = int(n_samples // self.spr)
        self.edges = np.round(np.arange(self.n_rev + 1) * self.spr).astype(np.int64)
        # The first sample of each revolution by add()'s rule (floor((i + 0.5) / spr) = k),
        # which at an exact half sample can differ from the rounded edge by one.
        k = np.arange(self.n_rev + 1)
        first = np.ceil(k * self.spr - 0.5).astype(np.int64)
        first += np.floor((first + 0.5) / self.spr).astype(np.int64) < k
        first -= np.floor((first - 0.5) / self.spr).astype(np.int64) >= k
        self._first = first
        self.sums = np.zeros((self.n_rev, channels))
        self.sumsq = np.zeros((self.n_rev, channels))
        self.counts = np.zeros(self.n_rev)
        self._hf_noise: list[float] = []

    @property
    def hf_noise_n(self) -> float:
        """Noise level (N, norm over channels) from the record's second differences: the median
        absolute value, which a cut's smooth waveform and its few entry jumps hardly move."""
        return float(np.median(self._hf_noise)) if self._hf_noise else 0.0

    def add(self, chunk: ArrayLike, first_sample: int | np.ndarray) -> None:
        """``first_sample``: index of the chunk's first sample, or every sample's index (n,),
        increasing, when the record has holes."""
        x = np.asarray(chunk, float)
        n = len(x)
        each = None if np.ndim(first_sample) == 0 else np.asarray(first_sample)
        if each is None or (n and each[-1] - each[0] == n - 1):
            # Contiguous samples (a record without holes): the revolutions' first samples
            # from the edges, without a revolution number per sample.
            i0 = int(first_sample) if each is None else int(each[0])
            lo = max(int(np.searchsorted(self._first, i0, side="right")) - 1, 0)
            hi = min(int(np.searchsorted(self._first, i0 + n, side="left")), self.n_rev)
            cut = np.clip(self._first[lo : hi + 1] - i0, 0, n)
            keep = cut[1:] > cut[:-1]
            starts, k = cut[:-1][keep], np.arange(lo, hi)[keep]
            x = x[starts[0] : cut[1:][keep][-1]] if k.size else x[:0]
            starts = starts - (starts[0] if k.size else 0)
        else:
            idx = _indices(first_sample, n)
            # Sample i lies in revolution k iff round(k spr) <= i < round((k + 1) spr).
            rev = np.floor((idx + 0.5) / self.spr).astype(np.int64)
            ok = (rev >= 0) & (rev < self.n_rev)
            if not ok.all():
                rev, x = rev[ok], x[ok]
            # rev is non-decreasing: each revolution's run of samples starts where it changes.
            starts = np.flatnonzero(np.diff(rev, prepend=rev[0] - 1)) if len(rev) else rev
            k = rev[starts]
        if len(x) == 0:
            return
        if self.noise and len(x) >= 16:
            # white noise: second differences have std sqrt(6) sigma, median |.| 0.6745 of it;
            # the first 2^16 samples of a chunk estimate it as well as a million would.
            d2 = np.median(np.abs(np.diff(x[: 1 << 16], 2, axis=0)), axis=0) / (0.6745 * np.sqrt(6))
            self._hf_noise.append(float(np.linalg.norm(d2)))
        self.sums[k] += np.add.reduceat(x, starts, axis=0)
        self.sumsq[k] += np.add.reduceat(x * x, starts, axis=0)
        self.counts[k] += np.diff(np.append(starts, len(x)))


def find_steady(
    force_n: ArrayLike, rate_hz: float, spindle_rpm: float, tolerance: float = 0.05,
    refine: bool = True, offset_n: ArrayLike | None = None, engaged_after_s: float = 0.0,
) -> SteadyPart:  # fmt: skip
    """Locate the steady cutting part of a record (n, c) and estimate its offset.

    Air revolutions are those whose mean and spread match the quietest revolution's; the offset
    is their mean (a straight line in time if there is air before and after the cut). Give
    ``offset_n`` to skip the estimate (a record with no air in it). ``engaged_after_s``: see
    :func:`engaged_revolutions`.
    """
    x = np.asarray(force_n, float)
    if x.ndim != 2 or len(x) == 0:
        raise AnalysisError(f"force record has shape {x.shape}: expected (n, channels) N")
    stats = RevolutionStats(rate_hz, spindle_rpm, len(x), x.shape[1])
    stats.add(x, 0)
    part = steady_from_stats(stats, rate_hz, spindle_rpm, tolerance, offset_n, engaged_after_s)
    if refine:
        seg = x[part.window]
        period = refine_period(
            np.linalg.norm(seg - seg.mean(axis=0), axis=1), rate_hz, part.period_s
        )
        part = part.with_period(period, rate_hz)
    return part


def steady_from_stats(
    stats: RevolutionStats, rate_hz: float, spindle_rpm: float, tolerance: float = 0.05,
    offset_n: ArrayLike | None = None, engaged_after_s: float = 0.0,
) -> SteadyPart:  # fmt: skip
    """:func:`find_steady` from per-revolution statistics (the period is the nominal one)."""
    if not 0.0 < tolerance < 1.0:
        raise AnalysisError(
            f"steady tolerance = {tolerance!r}: expected a fraction of the steady level, "
            "0 < tolerance < 1 (e.g. 0.02)"
        )
    n_rev, spr, edges = stats.n_rev, stats.spr, stats.edges
    if n_rev < 3:
        raise AnalysisError(
            f"record of {int(stats.edges[-1])} samples holds {n_rev} whole revolutions at "
            f"{spindle_rpm} rpm: need at least 3"
        )
    cnt = np.maximum(stats.counts, 1)[:, None]
    means = stats.sums / cnt
    spread = np.sqrt(np.maximum(stats.sumsq / cnt - means**2, 0.0))  # per-revolution std
    channels = means.shape[1]
    quiet = int(np.argmin(spread.sum(axis=1)))
    noise = np.linalg.norm(spread[quiet]) + 1e-12
    # Even the quietest revolution carries a periodic force far above the sample noise and
    # comparable to the others': the record cuts throughout (the operator trimmed the air).
    spread_n = np.linalg.norm(spread, axis=1)
    cuts_throughout = noise > max(3 * stats.hf_noise_n, 0.2 * float(spread_n.max()))
    dist = np.linalg.norm(means - means[quiet], axis=1) + np.linalg.norm(
        spread - spread[quiet], axis=1
    )
    # A revolution cuts when it differs from the quietest one by far more than the noise can.
    floor = 8 * noise / np.sqrt(spr) + 0.5 * noise
    if offset_n is not None:
        # Offset known: a revolution cuts when its mean force stands out from it (works for
        # records that cut from start to end).
        dist = np.linalg.norm(means - np.asarray(offset_n, float), axis=1)
        floor = 8 * noise / np.sqrt(spr)
    elif cuts_throughout:
        raise NoAirError(
            f"no air revolutions to take the dynamometer offset from (all {n_rev} revolutions "
            "cut: the quietest varies by "
            f"{noise:.3g} N against {stats.hf_noise_n:.3g} N of noise); record some air before "
            "the cut or give offset_n"
        )
    if dist.max() <= floor and not (offset_n is not None and cuts_throughout):
        raise NoSteadyCutError(
            f"no cutting found: all {n_rev} revolutions look alike (spread {noise:.3g} N, "
            f"largest change {dist.max():.3g} N); is this an air run?"
        )
    cutting = dist > max(floor, 0.2 * dist.max())
    if offset_n is not None and cuts_throughout:
        cutting = dist > min(floor, 0.2 * dist.max())
    t_rev = 0.5 * (edges[:-1] + edges[1:]) / rate_hz
    if offset_n is not None:
        off_at0 = np.broadcast_to(np.asarray(offset_n, float), (channels,)).copy()
        drift = np.zeros(channels)
        n_air = 0
    else:
        off_at0, drift, air = _air_line(means, cutting, t_rev, floor)
        n_air = int(air.sum())
        cutting = ~air
    level = np.linalg.norm(means - off_at0 - t_rev[:, None] * drift, axis=1)
    lo, hi, outliers = _steady_stretch(level, cutting, tolerance)
    engaged = engaged_revolutions(cutting, engaged_after_s, 60.0 / abs(spindle_rpm), lo)
    if engaged is not cutting:
        lo, hi, outliers = _steady_stretch(level, engaged, tolerance)
    lo, hi = lo + 1, hi - 1  # the first and last steady revolutions may hold the transition
    if hi - lo < 3:
        why = "" if engaged is cutting else f" after the geometry's {engaged_after_s:.3g} s entry"
        raise NoSteadyCutError(
            f"only {max(hi - lo, 0)} steady cutting revolutions (of {int(cutting.sum())} cutting)"
            f"{why}: need at least 3 whose mean stays within {tolerance:.0%} of the median"
        )
    start, stop = int(edges[lo]), int(edges[hi])
    off0 = off_at0 + drift * start / rate_hz
    return SteadyPart(
        slice(start, stop), np.asarray(off0, float), np.asarray(drift, float),
        60.0 / abs(spindle_rpm), int(cutting.sum()), hi - lo, n_air,
        int(cutting[:lo].sum()), int(cutting[hi:].sum()),
        int(outliers), _entry_note(cutting, engaged, engaged_after_s),
    )  # fmt: skip


def _entry_note(cutting: np.ndarray, engaged: np.ndarray, entry_s: float) -> str:
    """Whether the geometry's entry bound (:func:`engaged_revolutions`) set the window, and why
    not: said in the run's steady line ('' without a bound, e.g. an end mill)."""
    if not entry_s > 0:
        return ""
    if engaged is not cutting:
        return f"window after the geometry's {entry_s:.3g} s entry from the first touch"
    why = ("starts in the cut" if cutting[0] else
           "is steady within a quarter of it from the first touch (no entry in it)")  # fmt: skip
    return f"the geometry's {entry_s:.3g} s entry bound not applied: the record {why}"


def engaged_revolutions(
    cutting: np.ndarray, engaged_after_s: float, period_s: float, level_start: int
) -> np.ndarray:
    """The cutting revolutions at least ``engaged_after_s`` after the first one, the cutter's
    first touch, when the record shows that entry; else ``cutting`` itself. The geometry gives
    the time (a face mill fed into a block: until its arc is wholly over it); the force level
    cannot: an offset cut's force grows by under 2 % over the entry's last seconds, and those
    revolutions would count as steady. The record shows the entry when it has air before the
    first cutting revolution and the level's steady stretch (from revolution ``level_start``)
    begins at least a quarter of that time after it; a cut that is steady at once (a plunge, a
    record made without an entry) keeps its level-based window."""
    if not engaged_after_s > 0 or not cutting.any() or cutting[0]:
        return cutting
    first = int(np.argmax(cutting))
    if (level_start - first) * period_s < 0.25 * engaged_after_s:
        return cutting
    out = cutting.copy()
    out[: first + int(np.ceil(engaged_after_s / period_s))] = False
    return out


def _air_line(
    means: np.ndarray, core: np.ndarray, t_rev: np.ndarray, floor: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(offset at t = 0, drift per s, air mask): the dynamometer offset from the air revolutions.

    ``core`` marks the clearly cutting revolutions; the rest are air candidates, but a face
    mill's slow entry and exit leave revolutions that cut a little (below the core's threshold)
    beside the cut: a robust line (medians of the air before and after) finds them, as
    revolutions off it by more than ``floor``, so they count as cutting, not as offset.
    """
    channels = means.shape[1]
    n_rev = len(means)
    if core.all():
        raise NoAirError(
            "no air revolutions to take the dynamometer offset from (the record cuts from "
            "start to end); record some air before the cut or give offset_n"
        )
    first_cut, last_cut = np.flatnonzero(core)[[0, -1]] if core.any() else (n_rev, -1)
    before = ~core & (np.arange(n_rev) < first_cut)
    after = ~core & (np.arange(n_rev) > last_cut)
    air = ~core
    for _ in range(3):
        if (air & before).any() and (air & after).any():
            # Air on both sides: a straight line through them removes slow amplifier drift.
            b, a = air & before, air & after
            tb, ta = np.median(t_rev[b]), np.median(t_rev[a])
            mb, ma = np.median(means[b], axis=0), np.median(means[a], axis=0)
            drift = (ma - mb) / (ta - tb)
            off_at0 = mb - drift * tb
        else:
            off_at0, drift = np.median(means[air], axis=0), np.zeros(channels)
        off = np.linalg.norm(means - off_at0 - t_rev[:, None] * drift, axis=1)
        new_air = ~core & (off <= floor)
        if not new_air.any() or (new_air == air).all():
            break
        air = new_air
    b, a = air & before, air & after
    if b.any() and a.any():
        tt = t_rev[air]
        A = np.column_stack([np.ones_like(tt), tt])
        coef, *_ = np.linalg.lstsq(A, means[air], rcond=None)
        return coef[0], coef[1], air
    return means[air].mean(axis=0), np.zeros(channels), air
