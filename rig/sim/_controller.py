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
import re
import select
import termios
import threading
import tty
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from analysis.config import MachineConfig
from planning.nc import ARC_CCW, ARC_CW, LINE, Interpreter, Motion, NCError
from rig.dnc.nc import segment_durations_s
from rig.errors import RigError
from rig.sim.clock import SimClock


@dataclass(frozen=True)
class ExecutedSegment:
    """One segment as the controller starts it, on the SimClock.

    t_start_s, t_end_s : simulated s (planned end; an interruption adds a standstill segment)
    start_mm, end_mm : tool tip, mm, machine frame; center_mm : arc centre or None
    kind : RAPID 0, LINE 1, ARC_CW 2, ARC_CCW 3, DWELL 4 (``planning.nc``)
    feed_mm_min : programmed feed (NaN for rapids, dwells and standstills)
    spindle_rpm : signed (+ M3, - M4, 0 off); tool; coolant
    block : order of the block in what the controller received since the program started
        (0-based; the k-th row of the stream's record); seq is the same number
    line : N number of the block if it has one, else -1; text : the block as received
    """

    t_start_s: float
    t_end_s: float
    start_mm: tuple[float, float, float]
    end_mm: tuple[float, float, float]
    spindle_rpm: float
    block: int
    kind: int = LINE
    center_mm: tuple[float, float, float] | None = None
    feed_mm_min: float = float("nan")
    tool: int = 0
    coolant: bool = False
    line: int = -1
    text: str = ""

    @property
    def seq(self) -> int:
        return self.block


@dataclass(frozen=True)
class ExecutedBlock:
    """A block the controller finished: its order, text and start/end on the SimClock (s)."""

    seq: int
    text: str
    t_start_s: float
    t_end_s: float
    n_segments: int


@dataclass(frozen=True)
class ControllerEvent:
    """``kind``: program_start, program_end, hold, resume, reset, alarm, error, overrun,
    starved, fed, port_dropped; ``t_s`` simulated s; ``detail`` free text."""

    kind: str
    t_s: float
    detail: str = ""


@dataclass
class _Planned:
    seq: int
    text: str
    motion: Motion
    durations_s: np.ndarray
    spindle_rpm: float
    t_ready: float
    n_number: int = -1
    ends_program: bool = False  # M2/M30 in this block


_N_WORD = re.compile(r"\s*/?\s*[Nn]\s*(\d+)")

_BAUD_CONSTANTS = {
    b: getattr(termios, f"B{b}")
    for b in (50, 110, 150, 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400)
    if hasattr(termios, f"B{b}")
}


class SimControllerBase:
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
        self._init_state()

    # -- state ---------------------------------------------------------------------------------
    def _init_state(self) -> None:
        self.received = bytearray()  # every data byte delivered by the line, in order
        self.bytes_arrived = 0
        self.overruns = 0
        self.framing_errors = 0
        self.max_fill = 0
        self.executed: list[ExecutedBlock] = []
        self.events: list[ControllerEvent] = []
        self.blocks_received = 0
        self.silent = False
        self.alarm: str = ""
        self.held = False
        self.starved_s = 0.0
        self.busy_s = 0.0
        self._started = False
        self._wire: deque[tuple[float, bytes]] = deque()  # (arrival of first byte, bytes)
        self._line_free_t = 0.0
        self._outbox = bytearray()
        self._plan: deque[_Planned] = deque()
        self._cur: _Planned | None = None
        self._seg_i = 0
        self._seg_t0 = 0.0
        self._seg_t1 = 0.0
        self._seg_frac0 = 0.0  # fraction of the current segment done before a resume
        self._hold_t = 0.0
        self._block_t0 = 0.0
        self._spindle = 0.0
        self._pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._hold_frac: float | None = None
        self._new_interpreter()

    def _new_interpreter(self) -> None:
        """A fresh modal state; the machine stays where it is."""
        dialect = self.protocol if self.protocol in ("fanuc", "grbl") else "fanuc"
        self.interp = Interpreter(
            self.machine, file=f"<{self.protocol} controller>", dialect=dialect
        )
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
            if self.silent:
                return
            self._check_line_settings()
            t = max(self.clock.now(), self._line_free_t)
            self._wire.append((t + self.char_time_s, data))
            self._line_free_t = t + len(data) * self.char_time_s

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
        if not self.line_ok and not getattr(self, "_baud_warned", False):
            self._baud_warned = True
            self._event("framing", f"line at the wrong baud rate (controller: {self.baudrate})")

    line_ok = True

    def _deliver(self, now: float) -> None:
        """Move bytes whose arrival time has come from the wire into the receiver."""
        ct = self.char_time_s
        while self._wire:
            t0, data = self._wire[0]
            if t0 > now:
                return
            n = min(len(data), int((now - t0) / ct) + 1)
            part, rest = data[:n], data[n:]
            if rest:
                self._wire[0] = (t0 + n * ct, rest)
            else:
                self._wire.popleft()
            if not self.line_ok:
                self.framing_errors += len(part)
                continue
            self._on_bytes(part, t0 + (n - 1) * ct)

    def _next_wake(self, now: float) -> float:
        t = now + 0.05
        if self._wire:
            t = min(t, self._wire[0][0])
        if self._cur is not None and not self.held and not self.alarm:
            t = min(t, self._seg_t1)
        return max(t, now)

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

    # -- planning ------------------------------------------------------------------------------
    def _interpret(self, text: str, t_ready: float) -> _Planned:
        """Interpret one block ready at ``t_ready``; raises NCError (state unchanged)."""
        seq = self._seq
        ended = self.interp.state.ended
        motion = self.interp.execute(text, block=seq)
        self._seq += 1
        st = self.interp.state
        rpm = float(st.spindle_speed_rpm * st.spindle_dir)
        dur = segment_durations_s(motion, self.rapid_mm_min)
        m = _N_WORD.match(text)
        n = int(m.group(1)) if m else -1
        return _Planned(seq, text, motion, dur, rpm, t_ready, n, st.ended and not ended)

    # -- execution -----------------------------------------------------------------------------
    def _advance(self, now: float) -> None:
        """Run the executor up to ``now``: finish segments, start the next blocks.

        A block starts when the previous one ended or, if it was not ready then (its last byte
        had not arrived, or the planner had not taken it), when it became ready; that gap, after
        the first block of a program, is counted as starvation.
        """
        while not self.held and not self.alarm and not self.silent:
            if self._cur is None:
                nxt = self._next_block(now)
                if nxt is None:
                    return
                if self._started:
                    gap = nxt.t_ready - self._seg_t1
                    if gap > 0:
                        self.starved_s += gap
                        self._event("starved", f"{gap:.6f} s before block {nxt.seq}", nxt.t_ready)
                    t0 = max(self._seg_t1, nxt.t_ready)
                else:
                    t0 = nxt.t_ready
                    self._started = True
                self._start_block(nxt, min(t0, now))
                continue
            if now < self._seg_t1:
                return
            t_end = self._seg_t1
            self._seg_i += 1
            if self._seg_i < len(self._cur.motion):
                self._start_segment(t_end)
                continue
            self._finish_block(t_end)

    def _start_block(self, b: _Planned, t0: float) -> None:
        if self.sim_alarm_at_block is not None and b.seq == self.sim_alarm_at_block[0]:
            self._plan.appendleft(b)
            self._raise_alarm(self.sim_alarm_at_block[1], f"injected at block {b.seq}", t0)
            self.sim_alarm_at_block = None
            return
        self._cur = b
        self._seg_i = 0
        self._block_t0 = t0
        if b.spindle_rpm != self._spindle:
            self._spindle = b.spindle_rpm
            for f in self._spindle_listeners:
                f(t0, b.spindle_rpm)
        if len(b.motion) == 0:
            self._seg_t1 = t0
            return
        self._start_segment(t0)

    def _start_segment(self, t0: float, frac0: float = 0.0) -> None:
        b = self._cur
        assert b is not None
        i = self._seg_i
        m = b.motion
        dur = float(b.durations_s[i]) * (1.0 - frac0)
        self._seg_t0, self._seg_t1, self._seg_frac0 = t0, t0 + dur, frac0
        self.busy_s += dur
        start = self._point(i, frac0) if frac0 > 0 else tuple(map(float, m.start[i]))
        self._pos = tuple(map(float, m.end[i]))  # type: ignore[assignment]
        c = m.center[i]
        seg = ExecutedSegment(
            t_start_s=t0,
            t_end_s=t0 + dur,
            start_mm=start,
            end_mm=tuple(map(float, m.end[i])),
            spindle_rpm=float(m.spindle_rpm[i]),
            block=b.seq,
            kind=int(m.kind[i]),
            center_mm=None if np.isnan(c[0]) else tuple(map(float, c)),
            feed_mm_min=float(m.feed_mm_min[i]),
            tool=int(m.tool[i]),
            coolant=bool(m.coolant[i]),
            line=b.n_number,
            text=b.text,
        )
        for f in self._seg_listeners:
            f(seg)

    def _point(self, i: int, frac: float) -> tuple[float, float, float]:
        """Where segment ``i`` of the current block is after ``frac`` of its time."""
        m = self._cur.motion  # type: ignore[union-attr]
        p0, p1 = m.start[i], m.end[i]
        if m.kind[i] in (ARC_CW, ARC_CCW) and m.plane[i] == 17:
            c = m.center[i]
            a0 = np.arctan2(p0[1] - c[1], p0[0] - c[0])
            a1 = np.arctan2(p1[1] - c[1], p1[0] - c[0])
            ccw = m.kind[i] == ARC_CCW
            sweep = np.mod(a1 - a0, 2 * np.pi) if ccw else -np.mod(a0 - a1, 2 * np.pi)
            if abs(sweep) < 1e-12:
                sweep = 2 * np.pi if ccw else -2 * np.pi
            r = np.hypot(p0[0] - c[0], p0[1] - c[1])
            a = a0 + frac * sweep
            z = p0[2] + frac * (p1[2] - p0[2])
            return (float(c[0] + r * np.cos(a)), float(c[1] + r * np.sin(a)), float(z))
        return tuple(map(float, p0 + frac * (p1 - p0)))  # type: ignore[return-value]

    def _finish_block(self, t_end: float) -> None:
        b = self._cur
        assert b is not None
        self.executed.append(ExecutedBlock(b.seq, b.text, self._block_t0, t_end, len(b.motion)))
        self._cur = None
        self._seg_t1 = t_end
        self._on_block_done(b)

    def _on_block_done(self, b: _Planned) -> None:
        """Protocol hook after a block finished (GRBL frees a planner slot)."""

    def _interrupt(self, now: float, kind: str, detail: str = "") -> None:
        """Stop the current segment at ``now``: report a standstill segment at the point reached."""
        b = self._cur
        if b is not None and len(b.motion) and self._seg_t1 > now:
            i = self._seg_i
            dur = self._seg_t1 - self._seg_t0
            frac_run = (now - self._seg_t0) / dur if dur > 0 else 1.0
            frac = self._seg_frac0 + (1.0 - self._seg_frac0) * frac_run
            self.busy_s -= self._seg_t1 - now
            self._hold_frac = frac
            p = self._point(i, frac)
            self._pos = p
            seg = ExecutedSegment(now, now, p, p, self._spindle, b.seq, LINE, text=b.text)
            for f in self._seg_listeners:
                f(seg)
        else:
            self._hold_frac = None
        self._event(kind, detail, now)

    # -- operator / real-time commands ---------------------------------------------------------
    def feed_hold(self) -> None:
        with self._lock:
            if self.held:
                return
            now = self.clock.now()
            self._advance(now)
            self.held = True
            self._hold_t = now
            self._interrupt(now, "hold")

    def cycle_start(self) -> None:
        with self._lock:
            if not self.held:
                return
            now = self.clock.now()
            self.held = False
            self._event("resume", "", now)
            if self._cur is not None and self._hold_frac is not None:
                self._start_segment(now, self._hold_frac)
            elif self._cur is not None:
                self._seg_t1 = now

    def _raise_alarm(self, code: int, detail: str, t: float) -> None:
        now = max(t, self.clock.now()) if t is not None else self.clock.now()
        self._interrupt(now, "alarm", f"{code}: {detail}")
        self.alarm = str(code)
        self._on_alarm(code)

    def _on_alarm(self, code: int) -> None:
        """Protocol hook: tell the streamer (GRBL) or hold the line (Fanuc)."""

    def reset(self) -> None:
        """RESET: stop motion, clear buffers and the alarm (protocols refine this)."""
        with self._lock:
            now = self.clock.now()
            if self._cur is not None:
                self._interrupt(now, "reset")
            else:
                self._event("reset", "", now)
            if self._cur is not None and len(self._cur.motion):
                pass  # _interrupt left self._pos at the point reached
            self._cur = None
            self._plan.clear()
            self._wire.clear()
            self.held = False
            self.alarm = ""
            self.silent = False
            self._started = False
            self._new_interpreter()
            self._after_reset()

    def _after_reset(self) -> None:
        """Protocol hook after reset."""


def nc_error_text(exc: NCError) -> str:
    return exc.reason


class SimControllerError(RigError):
    """A simulated controller cannot start as asked."""
