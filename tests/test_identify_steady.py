"""Steady part, offset and drift, per-revolution statistics, period refinement, tooth peaks."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.errors import AnalysisError
from analysis.runs.steady import (
    SyncAverager,
    find_steady,
    per_revolution,
    refine_period,
    steady_window,
    tooth_peaks,
)

RATE, RPM = 2000.0, 600.0  # 200 samples per revolution


def _record(n_rev=60, air_rev=8, rpm_true=RPM, offset=(5.0, -3.0, 1.0), drift=(0.0, 0.0, 0.0),
            noise=0.5, seed=0):  # fmt: skip
    rng = np.random.default_rng(seed)
    n = int((n_rev + 2 * air_rev) * RATE * 60 / RPM)
    t = np.arange(n) / RATE
    ang = 2 * np.pi * rpm_true / 60 * t
    f = np.zeros((n, 3))
    cut = (t >= air_rev * 0.1) & (t < (air_rev + n_rev) * 0.1)
    burst = np.clip(np.sin(ang), 0, None) ** 2  # one tooth, cutting half a turn
    f[cut, 0] = 100 * burst[cut]
    f[cut, 1] = -60 * burst[cut] + 20
    f[cut, 2] = 10 * burst[cut]
    f += np.asarray(offset) + t[:, None] * np.asarray(drift)
    return f + rng.normal(0, noise, f.shape), cut


def test_per_revolution_means_and_peaks():
    x = np.arange(1000.0)
    means, peaks = per_revolution(x, RATE, RPM)
    assert len(means) == 5  # 1000 samples = 5 whole revolutions of 200
    np.testing.assert_allclose(means, [99.5, 299.5, 499.5, 699.5, 899.5])
    np.testing.assert_allclose(peaks, [199, 399, 599, 799, 999])
    m2, _ = per_revolution(np.column_stack([x, -x]), RATE, RPM)
    assert m2.shape == (5, 2)


def test_steady_part_offset_and_drift():
    f, cut = _record(drift=(0.2, -0.1, 0.05))
    part = find_steady(f, RATE, RPM)
    first, last = np.flatnonzero(cut)[[0, -1]]
    assert first < part.window.start <= first + 400  # one revolution trimmed
    assert last - 400 <= part.window.stop <= last + 1
    t0 = part.window.start / RATE
    expected = np.array([5, -3, 1]) + t0 * np.array([0.2, -0.1, 0.05])
    np.testing.assert_allclose(part.offset_n, expected, atol=0.05)
    np.testing.assert_allclose(part.drift_n_s, [0.2, -0.1, 0.05], atol=0.01)
    assert part.air_revs >= 12


def test_steady_window_of_a_level_and_no_cutting():
    f, cut = _record()
    w = steady_window(np.linalg.norm(f - [5, -3, 1], axis=1), RATE, RPM)
    assert cut[w].all()
    with pytest.raises(AnalysisError, match="no cutting found"):
        steady_window(np.abs(np.random.default_rng(1).normal(0, 1, 20_000)), RATE, RPM)
    with pytest.raises(AnalysisError, match="at least 3"):
        find_steady(f[:500], RATE, RPM)
    with pytest.raises(AnalysisError, match="too few"):
        per_revolution(f, 10.0, RPM)


def test_spindle_off_its_commanded_speed_is_found():
    """The spindle turns 0.4 % fast: the period comes from the data, and the synchronous
    average stays sharp."""
    f, _ = _record(n_rev=80, rpm_true=602.4, noise=0.2)
    part = find_steady(f, RATE, RPM)
    assert part.period_s == pytest.approx(60 / 602.4, rel=2e-5)
    seg = part.corrected(f[part.window], part.window.start, RATE)
    avg = SyncAverager(RATE, part.period_s, 200)
    avg.add(seg, 0)
    assert avg.mean()[:, 0].max() == pytest.approx(100.0, rel=0.01)
    nominal = SyncAverager(RATE, 0.1, 200)
    nominal.add(seg, 0)
    assert nominal.mean()[:, 0].max() < 90  # smeared without the refinement
    assert refine_period(np.sin(2 * np.pi * np.arange(50_000) / 201.3), 1.0, 200.0) == (
        pytest.approx(201.3, rel=1e-5)
    )


def test_tooth_peaks_and_runout():
    spr = 200
    ang = 2 * np.pi * np.arange(20 * spr) / spr
    heights = np.array([100.0, 100.0, 80.0, 100.0])  # tooth 2 cuts less (runout)
    tooth = (np.floor(ang / (np.pi / 2)) % 4).astype(int)
    f = np.zeros((len(ang), 3))
    f[:, 0] = heights[tooth] * np.sin(2 * (ang % (np.pi / 2))) ** 2
    tp = tooth_peaks(f, RATE, 0.1, 4)
    np.testing.assert_allclose(tp.mean_peak_n, heights, rtol=1e-3)
    assert tp.runout_ratio == pytest.approx(20 / 95, rel=1e-2)
    assert tp.peaks_n.shape == (20, 4)


def test_a_record_without_air_cuts_throughout():
    """The air trimmed off: every revolution cuts. Not 'no cutting found' but NoAirError (no
    offset to take), and with the record's zero as the offset all revolutions count."""
    from analysis.runs.steady import NoAirError

    f, cut = _record(n_rev=40, offset=(0.0, 0.0, 0.0))
    f = f[cut]
    with pytest.raises(NoAirError):
        find_steady(f, RATE, RPM)
    part = find_steady(f, RATE, RPM, offset_n=np.zeros(3))
    assert part.steady_revs >= 36 and part.air_revs == 0
    assert part.kept.startswith(f"kept {part.steady_revs} of {part.cutting_revs}")


def test_a_noisy_revolution_does_not_halve_the_steady_part():
    """One revolution 5 % high in the middle of the cut: kept (bridged), not a split."""
    f, cut = _record(n_rev=60)
    k = 8 + 30  # a revolution in the middle of the cut
    rev = slice(k * 200, (k + 1) * 200)
    f[rev] += 0.05 * (f[rev] - [5, -3, 1])
    part = find_steady(f, RATE, RPM, tolerance=0.02)
    assert part.steady_revs >= 56 and part.outlier_revs == 1
    assert "1 kept outside the band" in part.kept


def test_slow_entry_and_exit_tails_do_not_count_as_air():
    """A cut ramping in and out over 15 revolutions: the revolutions cutting little beside the
    cut are not air, so the offset (5, -3, 1) N is not pulled towards them."""
    f, cut = _record(n_rev=60, noise=0.2)
    t = np.arange(len(f)) / RATE
    first, last = t[cut][[0, -1]]
    ramp = np.clip(np.minimum(t - first, last - t) / 1.5, 0, 1)
    f = (f - [5, -3, 1]) * ramp[:, None] + [5, -3, 1]
    part = find_steady(f, RATE, RPM)
    np.testing.assert_allclose(part.offset_n, [5, -3, 1], atol=0.05)
    assert part.entry_revs >= 14 and part.exit_revs >= 14


@pytest.mark.parametrize("rate_hz,rpm", [(10_000.0, 600.0), (12_345.0, 777.7), (10_000.0, 48_000.0),
                                         (20_010.0, 1200.0)])  # fmt: skip
def test_revolution_sums_of_contiguous_chunks_equal_a_per_sample_count(rate_hz, rpm) -> None:
    """Chunks without holes find their revolutions from the edges; the sums and counts are those
    of sample i counted in revolution floor((i + 0.5) / spr), written out here per sample
    (12.5 and 1000.5 samples per revolution put samples exactly half way)."""
    from analysis.runs.steady import RevolutionStats

    rng = np.random.default_rng(7)
    n = 20_000
    x = rng.normal(size=(n, 3))
    stats = RevolutionStats(rate_hz, rpm, n, 3)
    cuts = np.sort(rng.choice(np.arange(1, n), 6, replace=False))
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, n]):
        stats.add(x[lo:hi], lo if lo % 2 else np.arange(lo, hi))
    rev = np.floor((np.arange(n) + 0.5) / stats.spr).astype(int)
    ok = rev < stats.n_rev
    assert np.array_equal(stats.counts, np.bincount(rev[ok], minlength=stats.n_rev))
    want = np.stack([np.bincount(rev[ok], x[ok, c], stats.n_rev) for c in range(3)], axis=1)
    np.testing.assert_allclose(stats.sums, want, rtol=1e-12, atol=1e-9)
