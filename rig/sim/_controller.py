"""What the simulated Fanuc and GRBL controllers share: a pseudo-terminal, an emulated line, a
finite receive buffer and an executor running canonical motion on the :class:`SimClock`.

The protocol classes (:mod:`rig.sim.fanuc`, :mod:`rig.sim.grbl`) implement ``_on_bytes`` (what the
receiver does with arriving bytes) and ``_next_block`` (hand the executor its next block).
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import select
import termios
import threading
import time
import tty
from collections import deque
from collections.abc import Callable

from analysis.config import MachineConfig
from planning.nc import Interpreter
from rig.dnc.protocols import FALLBACK, protocol_of
from rig.errors import RigError

# the records are part of this API: re-exported (the protocol classes import _Planned from here)
from rig.sim._controller_exec import ControllerEvent as ControllerEvent
from rig.sim._controller_exec import ExecutedBlock as ExecutedBlock
from rig.sim._controller_exec import ExecutedSegment as ExecutedSegment
from rig.sim._controller_exec import ExecutorMixin
from rig.sim._controller_exec import _Planned as _Planned
from rig.sim._controller_lockstep import LockstepMixin
from rig.sim.clock import SimClock

_BAUD_CONSTANTS = {
    b: getattr(termios, f"B{b}")
    for b in (50, 110, 150, 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400)
    if hasattr(termios, f"B{b}")
}


class SimControllerBase(LockstepMixin, ExecutorMixin):
    """A simulated controller behind a pseudo-terminal (see rig.sim.fanuc / rig.sim.grbl).

    Parameters
    ----------
    machine : MachineConfig, optional
        Rapid rate, arc tolerance, dialect; default a generic machine (rapid 10 m/min).
    clock : SimClock, optional
        Shared simulated clock; default a new one at ``speed``.
    baudrate, bits_per_char : the emulated line: each character takes ``bits_per_char /
        baudrate`` simulated seconds to arrive, whatever speed the pty delivers it at.
    rx_buffer_bytes : receive buffer size, bytes.
    sim_stop_answering_after_block : after receiving this many blocks, go silent (no answers,
        no DC1, nothing executed) — a hung controller.
    sim_drop_port_after_block : after receiving this many blocks, close the pty (the port
        disappears); :meth:`reopen` gives a new one.
    sim_overrun_at_byte : the receiver reports an overrun on this received byte (1-based).
    sim_alarm_at_block : ``(k, code)``: alarm ``code`` when block ``k`` (0-based order) starts.
    sim_stop_answering_at_s : go silent at this simulated time, s.
    sim_alarm_at_s : ``(t, code)``: alarm ``code`` at simulated time ``t``, s.
    """

    protocol = ""

    def __init__(
        self,
        machine: MachineConfig | None = None,
        *,
        clock: SimClock | None = None,
        speed: float = 1.0,
        baudrate: int = 9600,
        bits_per_char: int = 10,
        rx_buffer_bytes: int = 1024,
        sim_stop_answering_after_block: int | None = None,
        sim_drop_port_after_block: int | None = None,
        sim_overrun_at_byte: int | None = None,
        sim_alarm_at_block: tuple[int, int] | None = None,
        sim_stop_answering_at_s: float | None = None,
        sim_alarm_at_s: tuple[float, int] | None = None,
    ) -> None:
        self.machine = machine
        self.sim_stop_answering_at_s = sim_stop_answering_at_s
        self.sim_alarm_at_s = sim_alarm_at_s
        self.clock = clock if clock is not None else SimClock(speed)
        self.baudrate = int(baudrate)
        self.char_time_s = bits_per_char / float(baudrate)
        self.rx_capacity = int(rx_buffer_bytes)
        self.rapid_mm_min = machine.rapid_mm_min if machine is not None else 10_000.0
        self.sim_stop_answering_after_block = sim_stop_answering_after_block
        self.sim_drop_port_after_block = sim_drop_port_after_block
        self.sim_overrun_at_byte = sim_overrun_at_byte
        self.sim_alarm_at_block = sim_alarm_at_block
        self._seg_listeners: list[Callable[[ExecutedSegment], None]] = []
        self._spindle_listeners: list[Callable[[float, float], None]] = []
        self._event_listeners: list[Callable[[ControllerEvent], None]] = []
        self._lock = threading.RLock()
        self._stop = threading.Event()
        #: set while nothing can run: no block to execute, or halted (alarm, silent, hold)
        self.quiet = threading.Event()
        self._thread: threading.Thread | None = None
        self._master = -1
        self._slave = -1
        self.path = ""
        self.line_ok = True  # False while the streamer's line is at another baud rate
        self._baud_warned = False  # the framing event is reported once
        #: lockstep (the simulated rig's campaigns): the clock cannot pass this controller's next
        #: segment end before it has been run, nor, while a stream is expected, the arrival of
        #: the last byte received (see :meth:`expect_stream`); off for a controller on its own
        self.lockstep = False
        self._expecting = False
        self._stream_done = False
        self._stream_bytes: int | None = None  # what the streamer wrote in all (end_stream)
        self._bytes_read = 0  # every byte read from the pty, in all
        self._bytes_read0 = 0  # ... when the stream was expected
        self._line_mark = 0.0  # wall time of the last byte read (or of expect_stream)
        self._expect_t = 0.0
        self._init_state()

    # -- state ---------------------------------------------------------------------------------
    def _init_state(self) -> None:
        self.received = bytearray()  # every data byte delivered by the line, in order
        self.bytes_arrived = 0
        self.overruns = 0
        self.framing_errors = 0
        self.max_fill = 0
        self.executed: list[ExecutedBlock] = []
        # seq -> run-clock start of every block taken, finished or not: a reset after a feed
        # hold drops the held block from `executed`, but it ran (its cut is in the record)
        self.started_s: dict[int, float] = {}
        self.events: list[ControllerEvent] = []
        self.blocks_received = 0
        self.silent = False
        self.alarm: str = ""
        self.held = False
        self.starved_s = 0.0
        self.busy_s = 0.0
        self._started = False
        # (start of the busy line, characters before these on it since then, bytes): character
        # j of an entry arrives at start + (k0 + j + 1) * char_time, computed from the count, not
        # by adding up char times chunk by chunk, so how the pty happened to split a burst
        # cannot move an arrival by a rounding (it moved block starts by 1e-15 s)
        self._wire: deque[tuple[float, int, bytes]] = deque()
        self._line_free_t = 0.0
        self._line_t0 = 0.0  # when the line last began to be busy
        self._line_chars = 0  # characters sent on it since then
        self._outbox = bytearray()
        self._plan: deque[_Planned] = deque()
        self._cur: _Planned | None = None
        self._seg_i = 0
        self._seg_t0 = 0.0
        self._seg_t1 = 0.0
        self._seg_frac0 = 0.0  # fraction of the current segment done before a resume
        self._hold_t = 0.0
        self._hold_stop_at: float | None = None  # a feed hold decelerating: motion stops then
        self._block_t0 = 0.0
        self._spindle = 0.0
        self._pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._hold_frac: float | None = None
        self._new_interpreter()

    def _new_interpreter(self) -> None:
        """A fresh modal state; the machine stays where it is."""
        d = protocol_of(self.protocol or FALLBACK).dialect_name  # the dialect it streams
        self.interp = Interpreter(self.machine, file=f"<{self.protocol} controller>", dialect=d)
        self.interp.state.position_mm = self._pos
        self._seq = 0

    # -- listeners -----------------------------------------------------------------------------
    def add_listener(
        self,
        on_segment: Callable[[ExecutedSegment], None] | None = None,
        on_spindle: Callable[[float, float], None] | None = None,
        on_event: Callable[[ControllerEvent], None] | None = None,
    ) -> None:
        """Called from the controller's thread: each segment as it starts (planned times), each
        spindle change ``(t_s, rpm signed)``, each :class:`ControllerEvent`."""
        if on_segment is not None:
            self._seg_listeners.append(on_segment)
        if on_spindle is not None:
            self._spindle_listeners.append(on_spindle)
        if on_event is not None:
            self._event_listeners.append(on_event)

    def _event(self, kind: str, detail: str = "", t: float | None = None) -> None:
        ev = ControllerEvent(kind, self.clock.now() if t is None else t, detail)
        self.events.append(ev)
        for f in self._event_listeners:
            f(ev)

    # -- lifecycle -----------------------------------------------------------------------------
    def start(self) -> str:
        """Open a pty, start the controller thread, return the tty path a streamer opens."""
        if self._thread is not None and self._thread.is_alive():
            return self.path
        self._open_pty()
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name=f"sim-{self.protocol}", daemon=True)
        self._thread.start()
        return self.path

    def _open_pty(self) -> None:
        m, s = os.openpty()
        tty.setraw(s)
        os.set_blocking(m, False)
        self._master, self._slave = m, s
        self.path = os.ttyname(s)

    def _close_pty(self) -> None:
        self._expecting = False  # what was in the old pty never comes: no line gate for it
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1

    def stop(self) -> None:
        """Stop the thread and close the pty."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        with self._lock:
            self._close_pty()
            self._expecting = False
            self._lift_gates()

    def reopen(self) -> str:
        """A new pty after the port was dropped (the adapter plugged in again); returns its path."""
        with self._lock:
            self._close_pty()
            self._open_pty()
            self._wire.clear()
            self._outbox.clear()
            self._after_reopen()
        return self.path

    def _after_reopen(self) -> None:
        """Protocol hook: what a re-plugged port clears (a partial line)."""

    def __enter__(self) -> SimControllerBase:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- figures -------------------------------------------------------------------------------
    def received_sha256(self) -> str:
        return hashlib.sha256(bytes(self.received)).hexdigest()

    @property
    def starved_fraction(self) -> float:
        """Time the executor waited for blocks after the first one / time since it started."""
        total = self.busy_s + self.starved_s
        return self.starved_s / total if total > 0 else 0.0

    @property
    def last_completed_block(self) -> int:
        """Order (0-based) of the last block executed to its end, -1 if none."""
        return self.executed[-1].seq if self.executed else -1

    def executed_texts(self) -> list[str]:
        return [b.text for b in self.executed]

    # -- output --------------------------------------------------------------------------------
    def _send(self, data: bytes) -> None:
        if self.silent:
            return
        self._outbox.extend(data)
        self._flush_out()

    def _flush_out(self) -> None:
        if not self._outbox or self._master < 0:
            return
        try:
            n = os.write(self._master, self._outbox)
            del self._outbox[:n]
        except BlockingIOError:
            pass
        except OSError:
            self._outbox.clear()

    # -- the loop ------------------------------------------------------------------------------
    def _loop(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                now = self.clock.now()
                self._deliver(now)
                self._time_knobs(now)
                self._advance(now)
                self._periodic(now)
                self._flush_out()
                halted = self.alarm or self.silent or self.held
                if halted or (self._cur is None and not self._plan and not self._wire):
                    self.quiet.set()
                else:
                    self.quiet.clear()
                self._update_gates()
                wake = self._next_wake(now)
                fd = self._master
            delay = min(self.clock.wall_delay(wake), 0.01)
            if fd < 0:
                self._stop.wait(delay)
                continue
            try:
                r, _, _ = select.select([fd], [], [], delay)
            except (OSError, ValueError):
                self._stop.wait(0.01)
                continue
            if r:
                self._read(fd)

    def _read(self, fd: int) -> None:
        try:
            data = os.read(fd, 65536)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO:  # no streamer has the slave open: nothing to read
                self._stop.wait(0.005)
                return
            raise
        if not data:
            return
        with self._lock:
            self._bytes_read += len(data)
            if self.silent:
                return
            self._check_line_settings()
            now = self.clock.now()
            if now > self._line_free_t:  # the line was idle: a new burst starts now
                self._line_t0, self._line_chars = now, 0
            self._wire.append((self._line_t0, self._line_chars, data))
            self._line_chars += len(data)
            self._line_free_t = self._line_t0 + self._line_chars * self.char_time_s
            self._line_mark = time.monotonic()
            self._update_gates()

    def _check_line_settings(self) -> None:
        """A streamer at the wrong baud rate sends garbage: count it as framing errors."""
        want = _BAUD_CONSTANTS.get(self.baudrate)
        if want is None or self._slave < 0:
            return
        try:
            attrs = termios.tcgetattr(self._slave)
        except termios.error:
            return
        self.line_ok = attrs[5] == want
        if not self.line_ok and not self._baud_warned:
            self._baud_warned = True
            self._event("framing", f"line at the wrong baud rate (controller: {self.baudrate})")

    def _deliver(self, now: float) -> None:
        """Move bytes whose arrival time has come from the wire into the receiver."""
        ct = self.char_time_s
        while self._wire:
            base, k0, data = self._wire[0]
            t0 = base + (k0 + 1) * ct
            if t0 > now:
                return
            n = min(len(data), int((now - t0) / ct) + 1)
            while n > 1 and base + (k0 + n) * ct > now:  # the division may round either way
                n -= 1
            while n < len(data) and base + (k0 + n + 1) * ct <= now:
                n += 1
            part, rest = data[:n], data[n:]
            if rest:
                self._wire[0] = (base, k0 + n, rest)
            else:
                self._wire.popleft()
            if not self.line_ok:
                self.framing_errors += len(part)
                self._on_framing_error(t0)
                continue
            if self.lockstep:
                # each character at its own arrival: how the loop happened to split the wire
                # (when the host let it run) must not move a block's arrival
                for j in range(len(part)):
                    self._on_bytes(part[j : j + 1], base + (k0 + j + 1) * ct)
                continue
            self._on_bytes(part, base + (k0 + n) * ct)

    def _on_framing_error(self, t: float) -> None:
        """Protocol hook: characters at the wrong baud rate arrived (garbage)."""

    def _next_wake(self, now: float) -> float:
        t = now + 0.05
        if self._wire:
            base, k0, _ = self._wire[0]
            t = min(t, base + (k0 + 1) * self.char_time_s)
        if self._cur is not None and not self.held and not self.alarm:
            t = min(t, self._seg_t1)
        if self._hold_stop_at is not None:
            t = min(t, self._hold_stop_at)
        return max(t, now)

    def advance_to(self, t_s: float) -> None:
        """Run the executor up to simulated time ``t_s`` (never past now).

        The simulated machine calls this before it samples the executed motion for the DAQ, so
        the sample clock never runs ahead of the block clock when this controller's thread is
        late (a loaded host): otherwise a segment that started at t would be reported after the
        DAQ had already sampled the tool standing still at t.
        """
        with self._lock:
            now = min(t_s, self.clock.now())
            self._deliver(now)
            self._advance(now)
            self._update_gates()

    def _periodic(self, now: float) -> None:
        """Protocol hook run every loop pass (e.g. Fanuc re-sending DC1 while it waits)."""

    def _time_knobs(self, now: float) -> None:
        if self.sim_alarm_at_s is not None and now >= self.sim_alarm_at_s[0]:
            t, code = self.sim_alarm_at_s
            self.sim_alarm_at_s = None
            self._advance(t)
            self._raise_alarm(int(code), f"injected at t = {t:g} s", t)
        if self.sim_stop_answering_at_s is not None and now >= self.sim_stop_answering_at_s:
            t = self.sim_stop_answering_at_s
            self.sim_stop_answering_at_s = None
            self._advance(t)
            self._go_silent(f"stopped answering at t = {t:g} s")

    def _go_silent(self, detail: str) -> None:
        self.silent = True
        self._event("silent", detail)

    # -- receiving (protocol) ------------------------------------------------------------------
    def _on_bytes(self, data: bytes, t: float) -> None:
        raise NotImplementedError

    def _next_block(self, now: float) -> _Planned | None:
        """Give the executor its next block, or None (nothing ready)."""
        return self._plan.popleft() if self._plan else None

    def _count_byte(self) -> bool:
        """Count one arriving byte; True if the injected overrun hits it."""
        self.bytes_arrived += 1
        return (
            self.sim_overrun_at_byte is not None and self.bytes_arrived == self.sim_overrun_at_byte
        )

    def _block_received(self) -> bool:
        """Count a received block; apply the drop/silence knobs. False: stop taking bytes."""
        self.blocks_received += 1
        k = self.blocks_received
        stop_after = self.sim_stop_answering_after_block
        if stop_after is not None and k >= stop_after:
            self.sim_stop_answering_after_block = None  # one-shot: a reset brings it back
            self._go_silent(f"stopped answering after {k} blocks")
            return False
        if self.sim_drop_port_after_block is not None and k >= self.sim_drop_port_after_block:
            # The block that arrived is kept (and runs); nothing more comes in.
            self.sim_drop_port_after_block = None
            self._close_pty()
            self._wire.clear()
            self._event("port_dropped", f"port dropped after {k} blocks")
        return True


class SimControllerError(RigError):
    """A simulated controller cannot start as asked."""
