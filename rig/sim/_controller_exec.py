"""The executor of the simulated controllers: blocks in, segments run on the SimClock, listeners
told; feed hold, cycle start, alarms and reset. Mixed into
:class:`rig.sim._controller.SimControllerBase`, which owns the state it uses (the plan, the
current block, the clock, the listeners).
"""

from __future__ import annotations

import re
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planning.nc import ARC_CCW, ARC_CW, LINE, Motion
from rig.dnc.nc import segment_durations_s

if TYPE_CHECKING:
    from planning.nc import Interpreter
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
    blocks: int = 0  # planner blocks the line takes (GRBL: one per straight move, arc segments)
    pause: bool = False  # M0: hold when it has run (GRBL)
    done: bool = False  # executed to its end


def _xyz(a: np.ndarray) -> tuple[float, float, float]:
    """A point of a Motion's (3,) rows as three floats."""
    return (float(a[0]), float(a[1]), float(a[2]))


_N_WORD = re.compile(r"\s*/?\s*[Nn]\s*(\d+)")


# -- the state the mixins share -----------------------------------------------------------------
# SimControllerBase (rig.sim._controller) sets these fields (__init__, _init_state) and defines the
# hooks; LockstepMixin and ExecutorMixin read and write them. Declarations for the type checker:
# a class body annotation without a value creates no attribute at run time.


class ControllerState:
    """Fields of SimControllerBase that its mixins use (declarations, no values)."""

    clock: SimClock
    interp: Interpreter
    rapid_mm_min: float
    lockstep: bool
    sim_alarm_at_block: tuple[int, int] | None
    _lock: threading.RLock
    _master: int
    _seq: int
    # the executor
    executed: list[ExecutedBlock]
    started_s: dict[int, float]
    silent: bool
    alarm: str
    held: bool
    starved_s: float
    busy_s: float
    _started: bool
    _wire: deque[tuple[float, int, bytes]]
    _line_free_t: float
    _plan: deque[_Planned]
    _cur: _Planned | None
    _seg_i: int
    _seg_t0: float
    _seg_t1: float
    _seg_frac0: float
    _hold_t: float
    _hold_stop_at: float | None
    _hold_frac: float | None
    _block_t0: float
    _spindle: float
    _pos: tuple[float, float, float]
    _seg_listeners: list[Callable[[ExecutedSegment], None]]
    _spindle_listeners: list[Callable[[float, float], None]]
    _event_listeners: list[Callable[[ControllerEvent], None]]
    # the lockstep gates
    _expecting: bool
    _stream_done: bool
    _stream_bytes: int | None
    _bytes_read: int
    _bytes_read0: int
    _line_mark: float
    _expect_t: float

    if TYPE_CHECKING:
        # hooks SimControllerBase (and its protocol classes) define

        def _event(self, kind: str, detail: str = "", t: float | None = None) -> None: ...

        def _new_interpreter(self) -> None: ...

        def _next_block(self, now: float) -> _Planned | None: ...

        def _update_gates(self) -> None: ...


class ExecutorMixin(ControllerState):
    """Execution half of a simulated controller (state lives in SimControllerBase)."""

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
        the first block of a program, is counted as starvation. A feed hold being carried out
        (``_hold_stop_at``, GRBL's deceleration) stops the motion at that time.
        """
        stop_at = self._hold_stop_at
        if stop_at is not None:
            self._run_until(min(now, stop_at))
            if now >= stop_at and not self.alarm and not self.silent:
                self._hold_stop_at = None
                self.held = True
                self._hold_t = stop_at
                self._interrupt(stop_at, "hold")
            return
        self._run_until(now)

    def _before_block(self, b: _Planned, t0: float) -> bool:
        """Protocol hook: False keeps ``b`` from starting (an injected fault took over)."""
        return True

    def _run_until(self, now: float) -> None:
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
        if not self._before_block(b, t0):
            return
        self._cur = b
        self._seg_i = 0
        self._block_t0 = t0
        if b.seq >= 0:
            self.started_s[b.seq] = t0
        rpm = b.spindle_rpm * self._rpm_scale()
        if rpm != self._spindle:
            self._spindle = rpm
            for f in self._spindle_listeners:
                f(t0, rpm)
        if len(b.motion) == 0:
            self._seg_t1 = t0
            return
        self._start_segment(t0)

    def _start_segment(self, t0: float, frac0: float = 0.0) -> None:
        b = self._cur
        assert b is not None
        i = self._seg_i
        m = b.motion
        dur = float(b.durations_s[i]) * (1.0 - frac0) * self._time_scale(b, i)
        self._seg_t0, self._seg_t1, self._seg_frac0 = t0, t0 + dur, frac0
        self.busy_s += dur
        start = self._point(i, frac0) if frac0 > 0 else _xyz(m.start[i])
        self._pos = _xyz(m.end[i])
        c = m.center[i]
        seg = ExecutedSegment(
            t_start_s=t0,
            t_end_s=t0 + dur,
            start_mm=start,
            end_mm=_xyz(m.end[i]),
            spindle_rpm=float(m.spindle_rpm[i]) * self._rpm_scale(),
            block=b.seq,
            kind=int(m.kind[i]),
            center_mm=None if np.isnan(c[0]) else _xyz(c),
            feed_mm_min=float(m.feed_mm_min[i]),
            tool=int(m.tool[i]),
            coolant=bool(m.coolant[i]),
            line=b.n_number,
            text=b.text,
        )
        for f in self._seg_listeners:
            f(seg)

    def _time_scale(self, b: _Planned, i: int) -> float:
        """Protocol hook: the running time of segment ``i`` over its programmed time (GRBL's
        feed and rapid overrides); 1 without overrides."""
        return 1.0

    def _rpm_scale(self) -> float:
        """Protocol hook: the spindle's speed over the programmed one (GRBL's override)."""
        return 1.0

    def _point(self, i: int, frac: float) -> tuple[float, float, float]:
        """Where segment ``i`` of the current block is after ``frac`` of its time."""
        assert self._cur is not None  # only called while a block runs
        m = self._cur.motion
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
        return _xyz(p0 + frac * (p1 - p0))

    def _finish_block(self, t_end: float) -> None:
        b = self._cur
        assert b is not None
        self.executed.append(ExecutedBlock(b.seq, b.text, self._block_t0, t_end, len(b.motion)))
        b.done = True
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

    def reset(self, clear_wire: bool = True) -> None:
        """RESET: stop motion, clear buffers and the alarm (protocols refine this). The machine
        stays where it stopped: the next program starts from there. ``clear_wire`` False: bytes
        still on their way over the line arrive after the reset (a serial soft reset)."""
        with self._lock:
            now = self.clock.now()
            if self._cur is not None and not self.held:
                self._interrupt(now, "reset")
            else:
                self._event("reset", "", now)
            self._cur = None
            self._plan.clear()
            if clear_wire:
                self._wire.clear()
            self.held = False
            self._hold_stop_at = None
            self.alarm = ""
            self.silent = False
            self._started = False
            self._new_interpreter()
            self._after_reset()

    def _after_reset(self) -> None:
        """Protocol hook after reset."""
