"""Progress display of a stream on stderr: blocks, bytes/s, ETA and (GRBL) the block
acknowledged beside the block executing (tqdm)."""

from __future__ import annotations

import sys
import time

from tqdm import tqdm


class Progress:
    """A tqdm bar counting blocks, showing bytes/s; disabled when ``enabled`` is False."""

    def __init__(self, total_blocks: int, enabled: bool = True, desc: str = "dnc") -> None:
        self._bar = tqdm(
            total=total_blocks,
            unit="block",
            desc=desc,
            file=sys.stderr,
            disable=not enabled,
            mininterval=0.5,
            dynamic_ncols=True,
        )
        self._t0 = time.perf_counter()
        self._last = self._t0  # first rate after half a second, not from one block

    def update(self, n_blocks: int, bytes_sent: int, extra: str = "") -> None:
        """``n_blocks`` more recorded, ``bytes_sent`` so far; ``extra`` shown after the rate
        (GRBL: the block acknowledged and the block executing)."""
        self._bar.update(n_blocks)
        now = time.perf_counter()
        if now - self._last > 0.5:
            self._last = now
            rate = bytes_sent / max(now - self._t0, 1e-9)
            tail = f", {extra}" if extra else ""
            self._bar.set_postfix_str(f"{rate:,.0f} B/s{tail}", refresh=False)

    def close(self) -> None:
        self._bar.close()
