"""Synchronous averaging of a force record over spindle revolutions: the revolution period
refined from the signal (``refine_period``), the force averaged into angle bins chunk by chunk
(``SyncAverager``: a long record streams from HDF5 with memory bounded by the chunk size), and
per-tooth peak forces with the runout they show (``tooth_peaks``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from analysis.errors import AnalysisError


def _indices(first_sample: int | np.ndarray, n: int) -> np.ndarray:
    if np.ndim(first_sample) == 0:
        return int(first_sample) + np.arange(n)
    idx = np.asarray(first_sample)
    if len(idx) != n:
        raise AnalysisError(f"{len(idx)} sample indices for {n} samples")
    return idx


def refine_period(
    signal: ArrayLike, rate_hz: float, nominal_period_s: float, tolerance: float = 0.02
) -> float:
    """Revolution period (s) from the autocorrelation of a 1-D signal, near the nominal one.

    First the autocorrelation peak at one revolution (within ``tolerance``) over the first few
    revolutions (FFT), then the peaks at 2, 4, 8, ... revolutions (up to half the record),
    each searched by direct products over the few lags the previous estimate leaves open, with
    parabolic interpolation; the error shrinks like 1/k. Returns the nominal period if the record
    is shorter than two revolutions.
    """
    x = np.asarray(signal, float)
    x = x - x.mean()
    spr = nominal_period_s * rate_hz
    if len(x) < 2 * spr + 2:
        return nominal_period_s
    head = x[: int(min(len(x), 8 * spr))]
    nfft = 1 << int(np.ceil(np.log2(2 * len(head))))
    spec = np.fft.rfft(head, nfft)
    ac = np.fft.irfft(spec * np.conj(spec), nfft)[: len(head)]
    lo = max(1, int(np.floor(spr * (1 - tolerance))))
    hi = min(len(head) - 2, int(np.ceil(spr * (1 + tolerance))))
    if hi <= lo:
        return nominal_period_s
    lags = np.arange(lo, hi + 1)
    lag = _parabolic_peak(lags, ac[lo : hi + 1] / (len(head) - lags))
    # Double the number of revolutions spanned each step: the last estimate predicts the peak to
    # a fraction of a sample times k, so a few lags around it are enough.
    k = 1
    while 2 * k * lag <= len(x) / 2:
        k *= 2
        centre = k * lag
        half = int(np.ceil(0.05 * k)) + 3
        lags = np.arange(max(1, int(centre) - half), min(len(x) - 1, int(centre) + half + 1))
        vals = np.array([x[: len(x) - L] @ x[L:] / (len(x) - L) for L in lags])
        lag = _parabolic_peak(lags, vals) / k
    return float(lag / rate_hz)


def _parabolic_peak(lags: np.ndarray, vals: np.ndarray) -> float:
    i = int(np.argmax(vals))
    j = float(lags[i])
    if 0 < i < len(vals) - 1:
        y0, y1, y2 = vals[i - 1], vals[i], vals[i + 1]
        den = y0 - 2 * y1 + y2
        if den != 0:
            j += 0.5 * (y0 - y2) / den
    return j


class SyncAverager:
    """Synchronous average over revolutions into ``n_bins`` angle bins, fed in chunks.

    ``add(chunk, first_sample)`` takes samples (m, c) whose first has index ``first_sample``
    counted from the window start (angle 0); memory is O(n_bins x c) plus the chunk.
    """

    def __init__(self, rate_hz: float, period_s: float, n_bins: int, channels: int = 3) -> None:
        self.rate_hz, self.period_s, self.n_bins = float(rate_hz), float(period_s), int(n_bins)
        self.sums = np.zeros((self.n_bins, channels))
        self.counts = np.zeros(self.n_bins)
        self.samples = 0

    def add(self, chunk: ArrayLike, first_sample: int | np.ndarray) -> None:
        x = np.asarray(chunk, float)
        idx = _indices(first_sample, len(x))
        # Bin k covers [k - h, k + 1 - h) * 2 pi / n_bins, h half a sample: with a whole number
        # of samples per bin they sit half a sample inside its edges, where neither rounding nor
        # a refined period's slow drift over the record moves them to a neighbour.
        spr = self.rate_hz * self.period_s
        frac = (idx / spr) % 1.0
        h = 0.5 * self.n_bins / spr
        b = np.floor(frac * self.n_bins + h).astype(np.int64) % self.n_bins
        for c in range(x.shape[1]):
            self.sums[:, c] += np.bincount(b, weights=x[:, c], minlength=self.n_bins)
        self.counts += np.bincount(b, minlength=self.n_bins)
        self.samples += len(x)

    def mean(self) -> np.ndarray:
        """Averaged waveform (n_bins, c); bin k covers angles [k - h, k + 1 - h) * 2 pi / n_bins
        with h half a sample (so a sample at angle 2 pi k / n_bins lands in bin k)."""
        if np.any(self.counts == 0):
            raise AnalysisError(
                f"{int((self.counts == 0).sum())} of {self.n_bins} angle bins are empty: use fewer "
                f"bins (at most about {int(self.rate_hz * self.period_s)} samples per revolution)"
            )
        return self.sums / self.counts[:, None]


@dataclass(frozen=True)
class ToothPeaks:
    """Per-tooth peak resultant force: ``peaks_n`` (n_rev, teeth) N, their mean per tooth
    ``mean_peak_n`` (teeth,), and ``runout_ratio`` = (max - min) / mean of the per-tooth means."""

    peaks_n: np.ndarray
    mean_peak_n: np.ndarray
    runout_ratio: float


def tooth_peaks(
    force_n: ArrayLike, rate_hz: float, period_s: float, teeth: int, phase_rad: float = 0.0
) -> ToothPeaks:
    """Peak resultant force of each tooth in each whole revolution of a steady record (n, c).

    Revolution k spans samples [k, k + 1) * period; tooth j owns the angle sector
    [j, j + 1) * 2 pi / teeth shifted by ``phase_rad`` (put the sector edges between teeth: pass
    the angle where the averaged force is lowest).
    """
    x = np.linalg.norm(np.asarray(force_n, float), axis=1)
    spr = rate_hz * period_s
    n_rev = int(len(x) // spr)
    if n_rev < 1 or teeth < 1:
        raise AnalysisError(f"tooth peaks need >= 1 revolution and tooth (got {n_rev}, {teeth})")
    idx = np.arange(int(n_rev * spr))
    ang = (idx / spr * 2 * np.pi - phase_rad) % (2 * np.pi)
    sector = np.minimum((ang / (2 * np.pi) * teeth).astype(np.int64), teeth - 1)
    rev = np.minimum((idx / spr).astype(np.int64), n_rev - 1)
    peaks = np.full((n_rev, teeth), -np.inf)
    np.maximum.at(peaks, (rev, sector), x[idx])
    mean_peak = peaks.mean(axis=0)
    ratio = float((mean_peak.max() - mean_peak.min()) / mean_peak.mean()) if teeth > 1 else 0.0
    return ToothPeaks(peaks, mean_peak, ratio)
