"""The chatter suspender of a campaign run: the live force judged window by window
(:class:`analysis.chatter.live.ChatterWatch`, whose docstring says what a window resolves), so a
run can be held or aborted while it cuts. The watch is re-exported here for the campaign's
modules.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from analysis.chatter import ChatterSettings
from analysis.chatter.live import (
    CHATTER_WINDOW_REVS,
    CONFIRM,
    JUDGE_S,
    LIVE_BAND_BINS,
    LIVE_ENERGY_SCALE,
    STEADY_LEVEL,
    ChatterWatch,
    level_change,
)

__all__ = [
    "CHATTER_WINDOW_REVS",
    "CONFIRM",
    "JUDGE_S",
    "LIVE_BAND_BINS",
    "LIVE_ENERGY_SCALE",
    "STEADY_LEVEL",
    "ChatterWatch",
    "ChatterWatchConfig",
    "level_change",
]


@dataclass(frozen=True)
class ChatterWatchConfig:
    """The campaign's chatter suspender for one run: ``on_chatter`` ``none`` (off), ``hold``
    (feed hold, abort after the hold timeout) or ``abort``; the commanded ``spindle_rpm`` (0:
    off); ``floor_n`` the mean resultant, N, a revolution needs to count as cutting;
    ``settings`` the detector's thresholds (None: its defaults)."""

    on_chatter: Literal["none", "hold", "abort"] = "none"
    spindle_rpm: float = 0.0
    floor_n: float = 10.0
    settings: ChatterSettings | None = None
