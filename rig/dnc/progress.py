"""Progress display of a stream on stderr: blocks, bytes/s, ETA and (GRBL) the block
acknowledged beside the block executing (tqdm on a terminal; otherwise a plain line every few
seconds, for a log file, CI or a service)."""

from __future__ import annotations

import sys
import time

from tqdm import tqdm

#: seconds between the plain lines when stderr is not a terminal
PLAIN_INTERVAL_S = 5.0


class Progress:
    """A tqdm bar counting blocks, showing bytes/s; disabled when ``enabled`` is False; plain
    lines (``dnc fanuc: 120/400 block (30 %), 2,400 B/s, 8 s``) when stderr is no terminal."""

    def __init__(self, total_blocks: int, enabled: bool = True, desc: str = "dnc") -> None:
        try:
            tty = sys.stderr.isatty()
        except (AttributeError, ValueError):
            tty = False
        self._plain = enabled and not tty
        self._bar = tqdm(
            total=total_blocks,
            unit="block",
            desc=desc,
            file=sys.stderr,
            disable=not enabled or self._plain,
            mininterval=0.5,
            dynamic_ncols=True,
        )
        self._desc, self._total, self._n, self._postfix = desc, total_blocks, 0, ""
        self._t0 = time.perf_counter()
        self._last = self._t0  # first rate after half a second, not from one block
        self._printed = self._t0

    def update(self, n_blocks: int, bytes_sent: int, extra: str = "") -> None:
        """``n_blocks`` more recorded, ``bytes_sent`` so far; ``extra`` shown after the rate
        (GRBL: the block acknowledged and the block executing)."""
        self._bar.update(n_blocks)
        self._n += n_blocks
        now = time.perf_counter()
        if now - self._last > 0.5:
            self._last = now
            rate = bytes_sent / max(now - self._t0, 1e-9)
            tail = f", {extra}" if extra else ""
            self._postfix = f"{rate:,.0f} B/s{tail}"
            self._bar.set_postfix_str(self._postfix, refresh=False)
        if self._plain and now - self._printed >= PLAIN_INTERVAL_S:
            self._printed = now
            pct = 100 * self._n / self._total if self._total else 100.0
            tail = f", {self._postfix}" if self._postfix else ""
            print(f"{self._desc}: {self._n}/{self._total} block ({pct:.0f} %){tail}, "
                  f"{now - self._t0:.0f} s", file=sys.stderr, flush=True)  # fmt: skip

    def close(self) -> None:
        self._bar.close()
