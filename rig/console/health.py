"""The logger's health on the page: the sample rate achieved against the configured one, and the
fraction of the samples received that the run writer has written, flagged beyond
:data:`TOLERANCE_PCT`.

- Achieved rate: the samples the DAQ delivered (holes of an overflow or a lost block are not
  delivered) over the run clock from the DAQ's start to the newest block's arrival (timed at
  arrival, so the publisher's beat does not bias it).
- Written: the writer's committed samples against those received :data:`LAG_S` of run clock
  earlier (the writer's queue holds the newest blocks for a moment; a writer that falls further
  behind, or drops blocks, shows here). The writer's own dropped and missing samples are shown.
- Nothing is judged before :data:`JUDGE_AFTER_S` of run clock (one block late is 5 % at 0.2 s).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any, cast

from rig.console.results import LoggerStatus, WriterCounts

TOLERANCE_PCT = 5.0
LAG_S = 0.5
JUDGE_AFTER_S = 2.0


class LoggerHealth:
    """Counts kept from the acquisition thread (cheap: two adds and a clock read a block)."""

    def __init__(self, rate_hz: float, t0_s: float) -> None:
        self.rate_hz, self.t0_s = float(rate_hz), float(t0_s)
        self.received = 0
        self.arrived_s = math.nan  # run clock s of the newest block's arrival
        self._history: deque[tuple[float, int]] = deque(maxlen=256)  # (arrival s, received)

    def on_block(self, n: int, now_s: float) -> None:
        self.received += int(n)
        self.arrived_s = float(now_s)

    def status(self, writer_stats: WriterCounts | None, now_s: float) -> LoggerStatus:
        """JSON for the page (``writer_stats``: :class:`rig.log.WriterStats` or None before the
        program starts)."""
        if self.received and (not self._history or self._history[-1][1] != self.received):
            self._history.append((self.arrived_s, self.received))  # one entry per arrival
        span = self.arrived_s - self.t0_s
        out: dict[str, Any] = {"configured_hz": self.rate_hz, "received": self.received,
                               "tolerance_pct": TOLERANCE_PCT}  # fmt: skip
        achieved = self.received / span if span > 0 else math.nan
        out["achieved_hz"] = round(achieved, 1) if math.isfinite(achieved) else None
        rate_dev = 100.0 * (achieved / self.rate_hz - 1.0) if self.rate_hz > 0 else math.nan
        out["rate_dev_pct"] = round(rate_dev, 2) if math.isfinite(rate_dev) else None
        written_pct = math.nan
        if writer_stats is not None:
            then = self._received_before(now_s - LAG_S)
            written = int(writer_stats.samples_written)
            out |= {"written": written, "lost": int(writer_stats.samples_dropped)
                    + int(writer_stats.samples_missing)}  # fmt: skip
            if then > 0:
                written_pct = 100.0 * min(1.0, written / then)
        out["written_pct"] = round(written_pct, 2) if math.isfinite(written_pct) else None
        judged = span >= JUDGE_AFTER_S and math.isfinite(rate_dev)
        out["judged"] = judged
        bad = []
        if judged and abs(rate_dev) > TOLERANCE_PCT:
            bad.append(f"sample rate {rate_dev:+.1f} % from the configured {self.rate_hz:g} Hz")
        if judged and math.isfinite(written_pct) and written_pct < 100.0 - TOLERANCE_PCT:
            bad.append(f"{written_pct:.1f} % of the samples written")
        out["flag"] = bool(bad)
        out["why"] = "; ".join(bad) if bad else ("" if judged else
                                                 f"judged after {JUDGE_AFTER_S:g} s")  # fmt: skip
        return cast(LoggerStatus, out)  # built key by key above: LoggerStatus's keys

    def _received_before(self, t_s: float) -> int:
        """Samples received by the newest arrival at or before ``t_s`` (0: none that old)."""
        best = 0
        for t, n in self._history:
            if t <= t_s:
                best = n
            else:
                break
        return best
