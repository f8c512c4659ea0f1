"""The GRBL stream's window: the lines sent and not yet answered, and what character counting may
still send (``"char-counting"``: as many lines as GRBL's receive buffer holds, counting the bytes
of every line not yet answered; ``"send-response"``: one line at a time)."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from rig.dnc._stream import Item


@dataclass
class Window:
    """Lines ``items[next:]`` are still to send; ``inflight`` holds, per line sent and not yet
    answered, (position, bytes, send time, the link's bytes written once the line was)."""

    items: list[Item]
    counting: bool
    rx_buffer_bytes: int
    inflight: deque[tuple[int, int, float, int]] = field(default_factory=deque)
    used: int = 0  # bytes of the lines in flight
    next: int = 0

    def more(self) -> bool:
        """Lines to send or answers to wait for."""
        return self.next < len(self.items) or bool(self.inflight)

    def next_data(self) -> bytes | None:
        """The next line's bytes if there is one and it fits now, else None."""
        if self.next >= len(self.items):
            return None
        data = self.items[self.next].text.encode("ascii") + b"\n"
        if self.counting:
            fits = self.used + len(data) <= self.rx_buffer_bytes
        else:
            fits = not self.inflight
        return data if fits else None

    def sent(self, n: int, t: float, written: int) -> Item:
        """The next line went out (``n`` bytes at ``t``, ``written`` bytes on the link since)."""
        self.inflight.append((self.next, n, t, written))
        self.used += n
        self.next += 1
        return self.items[self.next - 1]

    def answered(self) -> tuple[int, int, float]:
        """The oldest line in flight was answered: its (position, bytes, send time)."""
        pos, n, t_send, _ = self.inflight.popleft()
        self.used -= n
        return pos, n, t_send
