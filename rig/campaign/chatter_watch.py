"""The chatter suspender of a campaign run: the live force judged window by window
(:mod:`analysis.chatter`), so a run can be held or aborted while it cuts."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from analysis.chatter import ChatterSettings, indicators

#: Revolutions of force the chatter suspender judges (indicators keeps all but one at each end).
CHATTER_WINDOW_REVS = 10


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


class ChatterWatch:
    """The chatter suspender: the last ``revolutions`` of Fx and Fy (N) of the cut, judged after
    every DAQ read by :func:`analysis.chatter.indicators` (a live window, as detect_run judges a
    block); revolutions under ``floor_n`` (air, entry) never count as cutting."""

    def __init__(
        self, channels: tuple[str, ...], rate_hz: float, spindle_rpm: float, floor_n: float,
        settings: ChatterSettings | None = None, revolutions: int = CHATTER_WINDOW_REVS,
    ) -> None:  # fmt: skip
        self.settings = settings
        self.cols = [channels.index(c) for c in ("Fx", "Fy") if c in channels] or [0, 1]
        self.rate_hz, self.spindle_rpm, self.floor_n = rate_hz, spindle_rpm, floor_n
        self.n = int(math.ceil(revolutions * 60.0 * rate_hz / spindle_rpm))
        self.window = np.zeros((0, len(self.cols)))

    def push(self, force_n: np.ndarray) -> str | None:
        """Add a read's forces (n, c) N; a message when the window chatters, else None."""
        self.window = np.vstack([self.window, force_n[:, self.cols]])[-self.n :]
        if len(self.window) < self.n:
            return None
        v = indicators(self.window, self.rate_hz, self.spindle_rpm, self.settings,
                       floor_n=self.floor_n)  # fmt: skip
        if not v.chatter:
            return None
        return (f"chatter at {v.frequency_hz:.0f} Hz (energy {v.energy_ratio:.2f}, opr "
                f"{v.opr_ratio:.2f})")  # fmt: skip
