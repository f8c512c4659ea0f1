"""Base feed from a synthetic feed sweep (seed 001 4.2 step 2, Table 2 and Fig. 8)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.basefeed import BaseFeedSettings, SweepRun, find_base_feed, per_revolution
from analysis.errors import AnalysisError

RPM, FLUTES, FS = 2000.0, 2, 10_000.0
FEEDS = np.arange(400, 2201, 200.0)  # seed 001 Table 2: 400..2200 mm/min in 10 steps


def _slot_forces(fz_mm: float, seconds: float, rng: np.random.Generator) -> np.ndarray:
    """Feed and cross-feed force of a 2-flute slot (linear edge-force model, no helix)."""
    kt, kr, kte, kre, a = 1100.0, 420.0, 22.0, 28.0, 2.0  # N/mm^2, N/mm, mm (effective width)
    t = np.arange(int(seconds * FS)) / FS
    phi0 = 2 * np.pi * RPM / 60 * t
    fx = np.zeros_like(t)
    fy = np.zeros_like(t)
    for j in range(FLUTES):
        phi = np.mod(phi0 + 2 * np.pi * j / FLUTES, 2 * np.pi)
        eng = phi < np.pi  # slotting: engaged over half a revolution
        h = fz_mm * np.sin(phi)
        ft = (kt * a * h + kte * a) * eng
        fr = (kr * a * h + kre * a) * eng
        fx += -ft * np.cos(phi) - fr * np.sin(phi)
        fy += ft * np.sin(phi) - fr * np.cos(phi)
    return np.column_stack([fx, fy]) + rng.normal(0, 1.0, (len(t), 2))


def _sweep(
    change_at: float | None, vib_jump: bool = True, slope_jump: bool = True, seed: int = 1
) -> list[SweepRun]:
    rng = np.random.default_rng(seed)
    runs = []
    t = np.arange(int(1.0 * FS)) / FS
    for f in FEEDS:
        fz = f / (RPM * FLUTES)
        if change_at is not None and slope_jump and f > change_at:
            fz_c = change_at / (RPM * FLUTES)
            fz = fz_c + 2.5 * (fz - fz_c)  # force rises faster past the change (Fig. 8)
        forces = _slot_forces(fz, 1.0, rng)
        chatter = 15.0 if (change_at is not None and vib_jump and f > change_at) else 2.0
        forces[:, 0] += chatter * np.sin(2 * np.pi * 1250.0 * t)  # 1250 Hz: no spindle harmonic
        runs.append(SweepRun(float(f), forces, FS, RPM, FLUTES, name=f"F{int(f)}"))
    return runs


def test_base_feed_is_1000_when_slope_and_vibration_change_between_1000_and_1200() -> None:
    res = find_base_feed(_sweep(1000.0))
    assert res.found and res.base_feed_mm_min == 1000.0
    flagged = [iv for iv in res.intervals if iv.flagged]
    assert (flagged[0].feed_lo_mm_min, flagged[0].feed_hi_mm_min) == (1000.0, 1200.0)
    assert flagged[0].slope_jump and flagged[0].vibration_jump
    assert "1000" in res.message and "slope" in res.message and "vibration" in res.message
    # Intervals below the change are not flagged, and their slope ratios are near 1.
    below = [iv for iv in res.intervals if iv.feed_hi_mm_min <= 1000]
    assert not any(iv.flagged for iv in below)
    assert all(abs(iv.slope_ratio - 1) < 0.3 for iv in below if not np.isnan(iv.slope_ratio))


@pytest.mark.parametrize("change", [800.0, 1400.0, 1800.0])
def test_moving_the_change_moves_the_answer(change: float) -> None:
    assert find_base_feed(_sweep(change)).base_feed_mm_min == change


def test_each_indicator_alone_is_found_by_its_criterion() -> None:
    only_slope = _sweep(1200.0, vib_jump=False)
    assert find_base_feed(only_slope, BaseFeedSettings(criterion="slope")).base_feed_mm_min == 1200
    assert not find_base_feed(only_slope, BaseFeedSettings(criterion="vibration")).found
    assert not find_base_feed(only_slope, BaseFeedSettings(criterion="both")).found
    only_vib = _sweep(1200.0, slope_jump=False)
    assert (
        find_base_feed(only_vib, BaseFeedSettings(criterion="vibration")).base_feed_mm_min == 1200
    )
    assert not find_base_feed(only_vib, BaseFeedSettings(criterion="slope")).found


def test_a_sweep_with_no_change_says_so() -> None:
    res = find_base_feed(_sweep(None))
    assert not res.found and res.base_feed_mm_min is None
    assert "no sharp change" in res.message and "400..2200" in res.message
    assert len(res.intervals) == len(FEEDS) - 1


def test_per_revolution_mean_and_peak_against_closed_form() -> None:
    fs, rpm = 1000.0, 600.0  # 100 samples per revolution
    t = np.arange(1050) / fs  # 10.5 revolutions: the partial one is left out
    x = 5 + 2 * np.sin(2 * np.pi * rpm / 60 * t)
    means, peaks = per_revolution(x, fs, rpm)
    assert len(means) == 10
    np.testing.assert_allclose(means, 5, atol=1e-9)
    np.testing.assert_allclose(peaks, 7, atol=1e-3)


def test_bad_sweeps_give_clear_errors() -> None:
    runs = _sweep(1000.0)
    with pytest.raises(AnalysisError, match="need at least 4"):
        find_base_feed(runs[:3])
    dead = [SweepRun(r.feed_mm_min, r.forces_n * 0, FS, RPM, FLUTES, r.name) for r in runs]
    with pytest.raises(AnalysisError, match="no cutting force"):
        find_base_feed(dead)
    with pytest.raises(AnalysisError, match="two sweep runs at feed 400"):
        find_base_feed([runs[0], *runs])
    with pytest.raises(AnalysisError, match=r"shape \(10000,\)"):
        find_base_feed([SweepRun(400, runs[0].forces_n[:, 0], FS, RPM, 2), *runs[1:]])
    with pytest.raises(AnalysisError, match="slope_ratio"):
        BaseFeedSettings(slope_ratio=0.5)
