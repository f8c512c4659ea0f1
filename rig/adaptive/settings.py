"""The adaptive loop's settings: what it holds (the target force, the mode) and where it stops
(the force limit, the override range, the watchdog). See :mod:`rig.adaptive.controller`."""

from __future__ import annotations

from dataclasses import dataclass

from rig.adaptive.grbl_codes import MAX_PCT, MIN_PCT

MODES = ("feed", "spindle", "both")


@dataclass(frozen=True)
class AdaptiveSettings:
    """What the loop holds and where it stops (see :mod:`rig.adaptive.controller`)."""

    mode: str = "feed"
    target_force_n: float = 500.0
    max_force_n: float = 2000.0
    dead_band_pct: float = 5.0
    slew_up_pct: int = 10
    slew_down_pct: int = 50
    settle_revs: int = 1
    air_force_n: float = 30.0
    stall_revs: float = 3.0
    chatter_revs: int = 20
    min_pct: int = MIN_PCT
    max_pct: int = MAX_PCT

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"adaptive mode {self.mode!r}: expected one of {', '.join(MODES)}")
        if not 0 < self.target_force_n < self.max_force_n:
            raise ValueError(
                f"target_force_n = {self.target_force_n} N, max_force_n = {self.max_force_n} N: "
                "expected 0 < target < max"
            )
        if not MIN_PCT <= self.min_pct <= 100 <= self.max_pct <= MAX_PCT:
            raise ValueError(f"override range {self.min_pct}..{self.max_pct} %: expected 10..200")
