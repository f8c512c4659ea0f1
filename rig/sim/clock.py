"""One simulated clock shared by the simulated controller, machine and DAQ.

The simulated rig's sample clock and block clock are the same object, so every DAQ sample can be
tied to the NC block executing at that instant. Simulated time runs ``speed`` times faster than
wall time (``speed=1`` is real time); it can also be paused (feed hold never rewinds time).

Gates (:meth:`SimClock.gate`) keep simulated time from passing a point until whoever set the gate
has done what is due there (a controller its next event, the line its next byte, a run its
arming): a slow host then makes a simulated run take longer in wall time, never changes what
happens in simulated time. Time stands at the lowest gate and goes on from there, without a jump,
once the gate moves or is lifted.
"""

from __future__ import annotations

import threading
import time


class SimClock:
    """Simulated seconds since start: ``t = speed * (wall time since start, minus pauses)``,
    never past the lowest gate.

    Thread-safe; ``sleep_until`` wakes early when ``stop`` (a ``threading.Event``) is set.
    """

    def __init__(self, speed: float = 1.0, gates: dict[str, float] | None = None) -> None:
        if not speed > 0:
            raise ValueError(f"speed = {speed}: must be > 0 (simulated s per wall s)")
        self.speed = float(speed)
        self._lock = threading.Lock()
        self._wall0 = time.perf_counter()
        self._paused_at: float | None = None
        self._gates: dict[str, float] = dict(gates or {})  # from the start: no time passes
        self._last = 0.0  # the last time handed out: a gate set behind it never rewinds time

    def now(self) -> float:
        """Simulated time, s."""
        with self._lock:
            wall = self._paused_at if self._paused_at is not None else time.perf_counter()
            t = (wall - self._wall0) * self.speed
            if self._gates:
                cap = max(min(self._gates.values()), self._last)
                if t > cap:
                    # stand at the gate: time resumes from here when it is lifted
                    self._wall0 = wall - cap / self.speed
                    t = cap
            self._last = max(self._last, t)
            return t

    def gate(self, name: str, t_s: float | None) -> None:
        """Keep simulated time at or below ``t_s`` until the gate ``name`` moves or is lifted
        (``t_s`` None). A gate behind the present holds time where it is."""
        self.now()  # time up to here ran ungated
        with self._lock:
            if t_s is None:
                self._gates.pop(name, None)
            else:
                self._gates[name] = float(t_s)

    def gated(self) -> bool:
        """True while a gate holds time (it stands at the lowest gate)."""
        with self._lock:
            return bool(self._gates) and self._last >= min(self._gates.values())

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
            if self.gated():
                step = min(step, 0.002)  # a gate may lift any moment: look again soon
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
