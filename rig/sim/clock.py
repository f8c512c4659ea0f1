"""One simulated clock shared by the simulated controller, machine and DAQ.

The simulated rig's sample clock and block clock are the same object, so every DAQ sample can be
tied to the NC block executing at that instant. Simulated time runs ``speed`` times faster than
wall time (``speed=1`` is real time); it can also be paused (feed hold never rewinds time).
"""

from __future__ import annotations

import threading
import time


class SimClock:
    """Simulated seconds since start: ``t = speed * (wall time since start, minus pauses)``.

    Thread-safe; ``sleep_until`` wakes early when ``stop`` (a ``threading.Event``) is set.
    """

    def __init__(self, speed: float = 1.0) -> None:
        if not speed > 0:
            raise ValueError(f"speed = {speed}: must be > 0 (simulated s per wall s)")
        self.speed = float(speed)
        self._lock = threading.Lock()
        self._wall0 = time.perf_counter()
        self._paused_at: float | None = None

    def now(self) -> float:
        """Simulated time, s."""
        with self._lock:
            wall = self._paused_at if self._paused_at is not None else time.perf_counter()
            return (wall - self._wall0) * self.speed

    def wall_delay(self, t_sim: float) -> float:
        """Wall seconds until simulated time ``t_sim`` (0 if already past)."""
        return max(0.0, (t_sim - self.now()) / self.speed)

    def sleep_until(self, t_sim: float, stop: threading.Event | None = None) -> bool:
        """Block until simulated time reaches ``t_sim``; False if ``stop`` was set first."""
        while True:
            delay = self.wall_delay(t_sim)
            if delay <= 0 and self._paused_at is None:
                return True
            step = min(delay, 0.05) if delay > 0 else 0.01
            if stop is not None:
                if stop.wait(step):
                    return False
            else:
                time.sleep(step)

    def pause(self) -> None:
        with self._lock:
            if self._paused_at is None:
                self._paused_at = time.perf_counter()

    def resume(self) -> None:
        with self._lock:
            if self._paused_at is not None:
                self._wall0 += time.perf_counter() - self._paused_at
                self._paused_at = None

    @property
    def paused(self) -> bool:
        return self._paused_at is not None
