"""Saturation of the adaptive feed loop (issue 29): a revolution cut at an override limit with
the force still outside the dead band on the side the limit keeps it from correcting; the
target is out of reach there (seed 001's 0.1 mm step makes about 74 N at 200 % and at 17 %
alike: its load is the edge's, not the chip's). Each stretch is an event when it starts and
when it ends (with its revolutions and time), so the report can tell reachable cutting time
apart (rig.report.adaptive_figures reads the ``saturation ended`` events)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol


class Limits(Protocol):
    """What saturation reads of the loop's settings (rig.adaptive.AdaptiveSettings)."""

    @property
    def target_force_n(self) -> float: ...
    @property
    def dead_band_pct(self) -> float: ...
    @property
    def min_pct(self) -> int: ...
    @property
    def max_pct(self) -> int: ...


class Saturation:
    """The stretches at a limit; ``note(t_s, text)`` records each start and end."""

    def __init__(self, note: Callable[[float, str], None]) -> None:
        self.note = note
        self.side: str | None = None  # "max" or "min" while saturated
        self.t0_s = 0.0
        self.revs = 0
        self.spans: list[tuple[float, float, int]] = []  # (start s, end s, revs)

    def track(self, t_s: float, force_n: float, pct_ran: int | None, s: Limits,
              rev_s: float) -> bool:  # fmt: skip
        """The revolution ending at ``t_s`` was cut at ``pct_ran`` % (None: the override changed
        within it): saturated (True) when that is a limit and the force is outside the dead
        band on the side the limit blocks."""
        err_pct = (force_n / s.target_force_n - 1.0) * 100.0
        side = None
        if pct_ran is None:
            pass
        elif pct_ran >= s.max_pct and err_pct < -s.dead_band_pct:
            side = "max"
        elif pct_ran <= s.min_pct and err_pct > s.dead_band_pct:
            side = "min"
        if side != self.side:
            self.end(t_s - rev_s)
        if side is None:
            return False
        if self.side is None:
            self.side, self.t0_s, self.revs = side, t_s - rev_s, 0
            lim = s.max_pct if side == "max" else s.min_pct
            self.note(t_s, f"saturated: feed at the {lim} % limit, force {force_n:.0f} N, target "
                      f"{s.target_force_n:.0f} N: out of reach here")  # fmt: skip
        self.revs += 1
        return True

    def end(self, t_end_s: float) -> None:
        if self.side is None:
            return
        t0, n = self.t0_s, self.revs
        self.spans.append((t0, t_end_s, n))
        self.side = None
        self.note(t_end_s, f"saturation ended: {n} revolutions at the limit, {t0:.4f}.."
                  f"{t_end_s:.4f} s")  # fmt: skip
