"""The GRBL streamer's status poll: a ``?`` ``status_hz`` times a second while it streams.

On a real port the period is the wall clock's. Under the simulated rig's lockstep (the streamer's
``lockstep``) it is the simulated clock's: each ``?`` is written while the simulated clock stands
at its time (a gate) and read by the controller before it moves on, so the reports come at the
same simulated times however busy the host.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Protocol

from rig.dnc.grbl_halt import STATUS
from rig.dnc.link import LinkLost, LinkTimeout, SerialLink


class Polled(Protocol):
    """What the poll needs of the streamer (rig.dnc.grbl.GrblStreamer)."""

    status_hz: float
    lockstep: Any  # rig.sim's StreamerPeer, or None on a real port
    link: SerialLink | None
    clock: Callable[[], float]

    def _write_rt(self, link: SerialLink, cmd: bytes) -> None: ...


class StatusPoller:
    """Started with the stream (:meth:`start`), stopped at its end (:meth:`stop`)."""

    def __init__(self, streamer: Polled) -> None:
        self.s = streamer
        self.stopped = threading.Event()
        self.thread: threading.Thread | None = None

    def start(self) -> StatusPoller:
        s = self.s
        target, args = self._wall, ()
        if s.lockstep is not None:  # the first poll's gate before the clock can pass it
            t_first = s.clock() + 1.0 / s.status_hz
            s.lockstep.gate("poll", t_first)
            target, args = self._simulated, (t_first,)  # type: ignore[assignment]
        self.thread = threading.Thread(target=target, args=args, name="grbl-status", daemon=True)
        self.thread.start()
        return self

    def stop(self) -> None:
        self.stopped.set()
        if self.thread is not None:
            self.thread.join(timeout=2.0)

    def _poll(self) -> bool:
        try:
            self.s._write_rt(self.s.link, STATUS)  # type: ignore[arg-type]
        except (LinkLost, LinkTimeout, OSError):
            return False
        return True

    def _wall(self) -> None:
        period = 1.0 / self.s.status_hz
        while not self.stopped.wait(period):
            if not self._poll():
                return

    def _simulated(self, t_first: float) -> None:
        lk, period = self.s.lockstep, 1.0 / self.s.status_hz
        k = 0
        try:
            while lk.sleep_until(t_first + k * period, self.stopped):
                if not self._poll() or not lk.settle(self.stopped):
                    return
                k += 1
                lk.gate("poll", t_first + k * period)
        finally:
            lk.gate("poll", None)
