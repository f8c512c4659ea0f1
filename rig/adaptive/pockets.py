"""The stable pocket the spindle loop moves to: the peak of the nearest run of speeds the tool's
lobes allow, within the spindle override's range."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rig.adaptive.grbl_codes import MAX_PCT, MIN_PCT

if TYPE_CHECKING:
    from analysis.stability import Lobes


def nearest_pocket_rpm(
    lobes: Lobes, rpm: float, depth_mm: float, min_pct: int = MIN_PCT, max_pct: int = MAX_PCT
) -> float | None:
    """The peak of the stable pocket nearest ``rpm`` within ``min_pct..max_pct`` % of it: a
    pocket is a run of speeds whose stability limit (``lobes.depth_limit_mm``) is above
    ``depth_mm`` by 10 %; its peak the speed of its highest limit (the middle of a plateau).
    The peak, not the nearest stable speed: a pocket's edge chatters on a model error of a
    percent (the twin's 0.9 mm slot at 5500 rpm chattered again at the pocket's edge, 5078
    and 5019 rpm). None if there is none."""
    s = np.asarray(lobes.spindle_rpm, float)
    lim = np.asarray(lobes.depth_limit_mm, float)
    ok = lim > 1.1 * depth_mm
    peaks = []
    i = 0
    while i < len(s):
        if not ok[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(s) and ok[j + 1]:
            j += 1
        seg = lim[i : j + 1]
        top = np.flatnonzero(seg >= seg.max() * (1 - 1e-9))
        peak = float(s[i + top[len(top) // 2]])
        if rpm * min_pct / 100 <= peak <= rpm * max_pct / 100:  # a peak within the override
            peaks.append(peak)
        i = j + 1
    if not peaks:
        return None
    return min(peaks, key=lambda p: abs(p - rpm))
