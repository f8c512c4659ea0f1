"""Base feed from a synthetic feed sweep (seed 001 4.2 step 2, Table 2 and Fig. 8)."""

from __future__ import annotations

import numpy as np
import pytest
from _rules_sweep import FEEDS, FLUTES, FS, RPM
from _rules_sweep import sweep as _sweep

from analysis.errors import AnalysisError
from analysis.rules.basefeed import BaseFeedSettings, SweepRun, find_base_feed


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
