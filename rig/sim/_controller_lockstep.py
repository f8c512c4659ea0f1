"""Lockstep for the simulated controllers (:class:`rig.sim._controller.SimControllerBase`):
the gates that hold the shared simulated clock while the controller moves (its next segment's
end, a feed hold's stop) and while a streamer is sending (the line never idles because the host
was slow)."""

from __future__ import annotations

import select
import time

from rig.sim._controller_exec import ControllerState

#: wall s the line gate waits for the streamer's next byte before it gives up (a stalled streamer
#: must not stop simulated time for good: the run's own timeouts then see it)
LINE_GATE_WALL_S = 10.0


class LockstepMixin(ControllerState):
    """The lockstep part of SimControllerBase (its state is set by SimControllerBase)."""

    def expect_stream(self) -> None:
        """A streamer is about to send a program (lockstep only): until it has sent it, the
        clock waits at the arrival of the last byte for the next (the line never idles because
        the host was slow), at most :data:`LINE_GATE_WALL_S` wall s per byte."""
        with self._lock:
            self._expecting, self._stream_done = True, False
            self._stream_bytes = None
            self._bytes_read0 = self._bytes_read
            self._expect_t = self.clock.now()
            self._line_mark = time.monotonic()
            self._update_gates()

    def end_stream(self, bytes_written: int | None = None) -> None:
        """The streamer has written all it will (``bytes_written`` since :meth:`expect_stream`,
        if it knows): the line gate lifts once that much has been read. A write returns before
        the pty shows its bytes to the reader (the kernel's flip buffer), so "nothing pending"
        alone let the clock run past the last chunk now and then (issue 31, item 10)."""
        with self._lock:
            self._stream_done = True
            self._stream_bytes = bytes_written
            self._update_gates()

    def _stream_read(self) -> bool:
        """All the streamer wrote has been read (nothing left in the pty)."""
        got = self._bytes_read - self._bytes_read0
        if self._stream_bytes is not None and got < self._stream_bytes:
            return False
        return not self._pty_pending()

    def _stream_wants(self) -> bool:
        """Protocol hook: the streamer sends the moment it can (no wait for an answer whose time
        is this controller's); False: no line gate (the answers pace the stream)."""
        return False

    def _pty_pending(self) -> bool:
        if self._master < 0:
            return False
        try:
            return bool(select.select([self._master], [], [], 0)[0])
        except (OSError, ValueError):
            return False

    def _update_gates(self) -> None:
        if not self.lockstep:
            return
        clk = self.clock
        nxt = None
        if self._cur is not None and not (self.held or self.alarm or self.silent):
            nxt = self._seg_t1
        if self._hold_stop_at is not None:
            nxt = self._hold_stop_at if nxt is None else min(nxt, self._hold_stop_at)
        clk.gate(f"ctl-{id(self)}", nxt)
        line = None
        if self._expecting and not (self.alarm or self.silent):
            if self._stream_done and self._stream_read():
                self._expecting = False
            elif time.monotonic() - self._line_mark > LINE_GATE_WALL_S:
                self._expecting = False
                self._event("lockstep", f"no byte for {LINE_GATE_WALL_S:g} wall s: line gate off")
            elif self._stream_wants():
                line = max(self._line_free_t, self._expect_t)
        clk.gate(f"line-{id(self)}", line)

    def _lift_gates(self) -> None:
        if hasattr(self.clock, "gate"):
            self.clock.gate(f"ctl-{id(self)}", None)
            self.clock.gate(f"line-{id(self)}", None)
