"""Lockstep for the simulated GRBL and the real GRBL streamer on the other end of its pty (the
simulated rig's campaigns only; ``lockstep`` and ``peer`` are set by :class:`rig.sim.session.
SimSession`, never on a real port).

GRBL's stream is a conversation: the streamer sends a line when an ``ok`` frees room in the
receive buffer, polls ``?`` and reacts to the reports. Fanuc's drip feed keeps the line busy and
its gate waits for the next byte; here the host's turnaround (reading an answer, writing the next
line) would pass on the free-running clock, so a busy host moved every line's arrival, and with
it the whole cut (issue: GRBL campaigns not deterministic). So, in lockstep, simulated time
stands still

- at the arrival of the next byte on the wire until the receiver has taken it (an answer or a
  report then goes out at the byte's time, not when this thread got round to it);
- at the moment a waiting line will find room in the planner (its ``ok`` goes out then);
- from :meth:`expect_stream` until the streamer's first byte (opening the port, the handshake);
- from every output (answer, report, message) until the streamer has read it, reacted (written
  what it writes in answer) and is waiting again, and those bytes have been read here
  (:class:`StreamerPeer`).

What the streamer has read is counted from the port's opening against what went out since
:meth:`expect_stream`: so in lockstep the controller sends no power-up banner (before the port is
open; pyserial's open flushes it anyway, but a count must not depend on that).

The streamer's ``?`` poll runs on simulated time too (:class:`rig.dnc.grbl_poll.
StatusPoller`). The reply gate gives way after :data:`LINE_GATE_WALL_S` wall s, the first-byte one
with the line gate (a stalled streamer must not stop simulated time for good: the run's own
timeouts then see it); the byte and room gates are the controller's own work, as its segment's.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from rig.sim._controller_lockstep import LINE_GATE_WALL_S
from rig.sim._grbl_lines import GrblLinesMixin


class GrblLockstepMixin(GrblLinesMixin):
    """The GRBL part of the lockstep (see the module docstring); mixed into SimGrbl."""

    peer: StreamerPeer | None = None
    char_time_s: float
    _outbox: bytearray
    _out_bytes = 0  # every byte put out, in all
    _out0 = 0  # ... when the stream was expected
    _reply_mark: float | None = None  # wall time the reply gate was set (None: not set)

    def expect_stream(self) -> None:
        with self._lock:
            self._out0 = self._out_bytes
        super().expect_stream()  # type: ignore[misc]

    def _conversing(self) -> bool:
        return bool(self.lockstep and self.peer is not None and self._expecting
                    and not self._stream_done)  # fmt: skip

    def _send(self, data: bytes) -> None:
        if self.silent:
            return
        self._out_bytes += len(data)
        if self._conversing() and self._reply_mark is None:
            # held from this instant (the time of the event answered: the gates below put the
            # clock there) until the streamer has taken it and reacted
            self.clock.gate(f"reply-{id(self)}", self.clock.now())
            self._reply_mark = time.monotonic()
        super()._send(data)

    def _update_gates(self) -> None:
        super()._update_gates()
        if not self.lockstep:
            return
        self.clock.gate(f"grbl-{id(self)}", self._grbl_gate_t())
        if self._reply_mark is None:
            return
        if not self._conversing() or self.peer is None:
            done = True
        elif self._outbox:  # not all of it in the pty yet
            done = False
        else:
            done = self.peer.host_done(self._out_bytes - self._out0,
                                       self._bytes_read - self._bytes_read0)  # fmt: skip
        if not done and time.monotonic() - self._reply_mark > LINE_GATE_WALL_S:
            done = True
            why = f"the streamer took no answer for {LINE_GATE_WALL_S:g} wall s: reply gate off"
            self._event("lockstep", why)
        if done:
            self._reply_mark = None
            self.clock.gate(f"reply-{id(self)}", None)

    def _grbl_gate_t(self) -> float | None:
        ts = []
        if self._wire:  # the next character's arrival
            base, k0, _ = self._wire[0]
            ts.append(base + (k0 + 1) * self.char_time_s)
        if self._pending is not None and (t_room := self._room_time()) is not None:
            ts.append(t_room)
        if self._expecting and not self._stream_done and self._bytes_read == self._bytes_read0:
            ts.append(self._expect_t)  # the streamer opens the port: its first byte
        return min(ts) if ts else None

    def _lift_gates(self) -> None:
        super()._lift_gates()  # type: ignore[misc]
        if hasattr(self.clock, "gate"):
            self.clock.gate(f"grbl-{id(self)}", None)
            self.clock.gate(f"reply-{id(self)}", None)
        self._reply_mark = None


class StreamerPeer:
    """The streamer's side of the lockstep, as the session wires it: what the simulated GRBL asks
    of the streamer (:meth:`host_done`) and what the streamer asks of the simulated clock (the
    ``lockstep`` attribute of :class:`rig.dnc.grbl.GrblStreamer`)."""

    def __init__(self, clock: Any, controller: Any, streamer: Any) -> None:
        self.clock = clock  # the SimClock
        self.ctl = controller
        self.streamer = streamer

    def _written(self) -> int:
        link = self.streamer.link
        return 0 if link is None else link.bytes_written + link.realtime_bytes

    # -- asked by the controller (under its lock) -------------------------------------------------
    def host_done(self, out_bytes: int, read_bytes: int) -> bool:
        """The streamer has read the ``out_bytes`` put out since the stream was expected,
        handled every line in them and waits for more, and all it wrote was read here."""
        rx = getattr(self.streamer, "_rx", None)
        if rx is None or self.streamer.link is None:
            return False
        return (rx.bytes_in >= out_bytes and rx.handled_n >= rx.put_n
                and read_bytes >= self._written())  # fmt: skip

    # -- asked by the streamer ------------------------------------------------------------------
    def gate(self, name: str, t_s: float | None) -> None:
        self.clock.gate(f"{name}-{id(self)}", t_s)

    def sleep_until(self, t_s: float, stop: threading.Event) -> bool:
        return bool(self.clock.sleep_until(t_s, stop))

    def settle(self, stop: threading.Event | None = None) -> bool:
        """Wait (wall) until the controller has read every byte the streamer wrote; False if
        ``stop`` was set or :data:`LINE_GATE_WALL_S` passed first."""
        end = time.monotonic() + LINE_GATE_WALL_S
        stop = stop if stop is not None else threading.Event()
        while self.ctl._bytes_read - self.ctl._bytes_read0 < self._written():
            if time.monotonic() > end or stop.wait(0.0005):
                return False
        self.idle()  # its gates now hold what it read
        return True

    def idle(self) -> None:
        """The streamer waits for GRBL's output: the reply gate may lift now."""
        with self.ctl._lock:
            self.ctl._update_gates()
