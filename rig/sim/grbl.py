"""A simulated GRBL 1.1h controller on the other end of a pseudo-terminal.

Start it in-process::

    ctl = SimGrbl(machine, clock=SimClock(speed=20))
    path = ctl.start()                 # the tty path for the streamer
    ctl.add_listener(on_segment=machine.on_segment, on_spindle=machine.on_spindle)
    ctl.stop()

or ``cutlab dnc sim-controller --protocol grbl``.

Behaviour (GRBL 1.1h's source is the reference: ``grbl/serial.c``, ``protocol.c``, ``gcode.c``,
``report.c``, ``motion_control.c``, ``planner.c``, ``system.c``)
------------------------------------------------------------------------------------------
- Serial receive buffer of ``rx_buffer_bytes`` (RX_BUFFER_SIZE 128); a byte arriving into a full
  buffer is dropped and counted in ``overruns`` (the serial ISR does the same, silently).
- Real-time characters are picked out on arrival, wherever they stand: ``?`` status report, ``!``
  feed hold, ``~`` cycle start, 0x18 soft reset, and the overrides (protocol_exec_rt_system):
  feed 0x90 100 %, 0x91/0x92 +-10 %, 0x93/0x94 +-1 % (10-200 %), rapid 0x95/0x96/0x97 100/50/25
  %, spindle 0x99 100 %, 0x9A/0x9B +-10 %, 0x9C/0x9D +-1 % (10-200 %). A change is reported in
  the next status (``Ov:``) at once and moves the machine through the stepper's segment ring
  (planner.c plan_update_velocity_profile_parameters and plan_cycle_reinitialize, stepper.c's
  st_update_plan_block_parameters; the spindle's STEP_CONTROL_UPDATE_SPINDLE_PWM): while moving,
  the 4 segments of DT_SEGMENT (10 ms) already prepared behind the running one run first, so it
  applies at the 5th segment boundary of the sim clock after the byte (40-50 ms; idle or held,
  at once). Then the segment running is split there and goes on at the new speed, and every
  block planned runs at it, a feed never above the rapid rate; the spindle turns at the
  programmed speed x its override (``FS:`` reports it); a byte at a limit changes nothing and
  is not reported; a reset restores 100 %. Each change is an ``override`` event (at the byte).
- A line is read out of the receive buffer only when the previous one is done, filtered as
  protocol.c does (spaces, comments, ``/`` dropped, upper case; more than 79 characters left:
  ``error:11``) and checked by :class:`planning.nc.grbl.GrblParser`, gcode.c's checks, so each
  error code is the firmware's (``error:20`` O/M6/G41/G43/G81/G98/G90.1..., ``error:26`` G2
  without axis words, ``error:22`` no feed, ``error:9`` in Alarm, ...).
- ``ok`` means *planned*, not done: a straight move takes one planner block, an arc its
  ``mc_arc`` segments; the planner holds ``planner_blocks`` (BLOCK_BUFFER_SIZE 16 - 1 = 15, 14
  with line numbers). When the planner cannot take all of a line's blocks the line waits and its
  ``ok`` comes when they fit; the lines behind it stay in the receive buffer. Spindle, coolant,
  dwell and program pause/end lines first wait for the planner to empty (``protocol_buffer_
  synchronize``); a dwell's ``ok`` comes after the dwell, an ``M0``'s after the cycle start,
  ``M2``/``M30`` send ``[MSG:Pgm End]`` before theirs.
- Motion runs on the SimClock at the programmed feeds (planning.nc's time model, no acceleration);
  a feed hold decelerates for ``hold_decel_s`` (state ``Hold:1``, the tool moving on for half of
  it), then ``Hold:0``. A soft reset while moving or decelerating is ``ALARM:3`` (mc_reset), then
  the banner and ``[MSG:'$H'|'$X' to unlock]``; after ``Hold:0`` or in Idle it is clean (Idle).
- Status report as report.c writes it: ``<State|MPos:x,y,z|Bf:planner_free,rx_free|Ln:n|FS:feed,
  rpm|WCO:...|Ov:...|A:...>`` with the ``$10`` mask (``status_report_mask``, default 1 as
  defaults.h: MPos, no Bf; 3 adds Bf; 0 WPos), ``Ln`` only with ``line_numbers`` (USE_LINE_NUMBERS,
  off in the stock build), ``WCO``/``Ov`` every 10 reports idle, 30/20 busy. States Idle, Run,
  Hold:0, Hold:1, Alarm.
- Alarms: ``ALARM:1``/``ALARM:2`` (hard/soft limit) are critical: ``[MSG:Reset to continue]`` and
  then nothing is answered (no status either) until a soft reset, after which GRBL is in Alarm
  (``[MSG:'$H'|'$X' to unlock]``, every g-code line ``error:9``) until ``$X`` (``[MSG:Caution:
  Unlocked]``). Other alarms end like a reset into Alarm.
- ``$`` lines: ``$$``, ``$#``, ``$G``, ``$I``, ``$X``, ``$H`` (``error:5`` while ``$22=0``, as
  GRBL with homing disabled), ``$C``, ``$N``, ``$n=value``; others ``error:3``; ``$$`` and ``$I``
  while running or held ``error:8``.

Fault knobs (``sim_``): ``sim_stop_answering_after_block=k`` (after k lines: silence),
``sim_drop_port_after_block=k`` (close the pty; :meth:`reopen` gives a new path),
``sim_overrun_at_byte=n`` (drop received byte n, as an overrun would), ``sim_error_at_block=(k,
code)`` (answer line k with ``error:code`` once, not executing it), ``sim_alarm_at_block=(k,
code)`` (``ALARM:code`` when line k starts), ``sim_drop_ok_at_line=k`` (line k runs, its ``ok``
is never sent: line noise), ``sim_garble_ok_at_line=k`` (its ``ok`` arrives as ``oo``),
``sim_noise_at_line=k`` (a line of noise arrives before line k's ``ok``, which is not lost),
``sim_reset_at_block=k`` (a reset when line k starts: ``ALARM:3`` if moving),
``sim_stop_answering_at_s=t``, ``sim_alarm_at_s=(t, code)`` (at simulated time t). Lines count
from 0 among the g-code lines received (``$`` lines not counted).

Notes
-----
How it differs from GRBL: no acceleration planning (segments run at their programmed feed; a hold
decelerates in a fixed time; an override changes the speed at its segment boundary, where GRBL
ramps to it at $120-$122, e.g. 300 mm/min in 10 ms at 500 mm/s^2); an override's byte is taken
when it arrives (GRBL's main loop takes it within a pass; a ``?`` in the same pass is reported
first); the segments are 10 ms each (GRBL's are shorter near a block's end); the spindle
speed is not clamped to $30/$31; an arc runs as one segment while counting its ``mc_arc`` blocks
in the planner; motion starts as soon as a block is planned (GRBL's auto cycle start waits for a
full planner or an empty receive buffer); the line rate is emulated on the SimClock (a pty has
none; a wrong baud rate is garbage); no homing switches, probing or soft limits unless injected.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from analysis.config import MachineConfig
from planning.nc import DWELL
from planning.nc.grbl import (
    GRBL_MSG_ALARM_LOCK,
    GRBL_MSG_RESET_TO_CONTINUE,
    GRBL_PLANNER_BLOCKS,
    GRBL_RX_BUFFER_SIZE,
    GrblParser,
)
from rig.sim._controller import SimControllerBase, _Planned
from rig.sim._grbl_lines import GrblLinesMixin
from rig.sim._grbl_lockstep import GrblLockstepMixin
from rig.sim._grbl_overrides import GrblOverridesMixin
from rig.sim._grbl_report import (
    _CRITICAL_ALARMS,
    _SETTINGS,
    BANNER,
    StatusFields,
    StatusReport,
    wco_mm,
)
from rig.sim._grbl_state import _Pending


class SimGrbl(GrblLockstepMixin, GrblLinesMixin, GrblOverridesMixin, SimControllerBase):
    """GRBL 1.1h-like controller (see the module docstring).

    ``base_kw``: clock, speed and the ``sim_`` fault knobs of :class:`SimControllerBase` (a
    wrong name is a TypeError).
    """

    protocol = "grbl"

    def __init__(
        self,
        machine: MachineConfig | None = None,
        *,
        baudrate: int = 115200,
        rx_buffer_bytes: int = GRBL_RX_BUFFER_SIZE,
        planner_blocks: int | None = None,
        line_numbers: bool = False,
        status_report_mask: int = 1,
        hold_decel_s: float | None = None,
        sim_error_at_block: tuple[int, int] | None = None,
        sim_drop_ok_at_line: int | None = None,
        sim_garble_ok_at_line: int | None = None,
        sim_noise_at_line: int | None = None,
        sim_reset_at_block: int | None = None,
        **base_kw: Any,
    ) -> None:
        super().__init__(
            machine, baudrate=baudrate, bits_per_char=10, rx_buffer_bytes=rx_buffer_bytes, **base_kw
        )  # 8N1
        self.line_numbers = line_numbers
        default_blocks = GRBL_PLANNER_BLOCKS - (1 if line_numbers else 0)
        self.planner_blocks = planner_blocks or default_blocks
        self.hold_decel_s = hold_decel_s
        self.sim_error_at_block = sim_error_at_block
        self.sim_drop_ok_at_line = sim_drop_ok_at_line
        self.sim_garble_ok_at_line = sim_garble_ok_at_line
        self.sim_noise_at_line = sim_noise_at_line
        self.sim_reset_at_block = sim_reset_at_block
        self.settings: dict[int, float] = dict(_SETTINGS)
        self.settings[10] = status_report_mask
        self.grbl = GrblParser(arc_tolerance_mm=float(self.settings[12]))
        if machine is not None:
            for i, p in enumerate((machine.reference_point_mm, machine.second_reference_point_mm)):
                if p is not None:
                    self.grbl.state.home[i] = [float(c) for c in p]
        self.critical = False  # after ALARM:1/2: deaf but to a soft reset
        self._hold_done_at = 0.0
        self._spindle_prog = 0.0  # programmed rpm (signed) of the last block started
        self._advanced_t = 0.0  # the executor has run up to this simulated time
        self._grbl_state()

    def _grbl_state(self) -> None:
        self._rx_lines: deque[tuple[bytes, float]] = deque()
        self._partial = bytearray()
        self.fill = 0
        self.lines_received = 0
        self.oks = 0
        self.errors: list[tuple[int, str]] = []
        self.planner_waits = 0  # times a line had to wait for room in the planner
        #: (line k, simulated s) of each ok answering a g-code line: when GRBL planned it, at
        #: the event that let it (arrival, room, sync), not when this thread got round to it
        self.ok_times_s: list[tuple[int, float]] = []
        self._pending: _Pending | None = None
        self._report = StatusReport()  # its WCO and Ov refresh counters
        # main.c sets them to their defaults on every (re)start: a reset ends any override
        self.feed_ovr = self.rapid_ovr = self.spindle_ovr = 100  # sys.*: reported at once
        #: the overrides the motion runs at (the step segments prepared after a change), and
        #: the changes still behind the segments already in the ring: (time s, feed, rapid, spindle)
        self._run_ovr = (100, 100, 100)
        self._ovr_due: deque[tuple[float, int, int, int]] = deque()

    def start(self) -> str:
        path = super().start()
        with self._lock:
            if not self.lockstep:  # (lockstep: see rig.sim._grbl_lockstep.StreamerPeer)
                self._send(BANNER)
            if self.alarm:
                self._send(GRBL_MSG_ALARM_LOCK.encode() + b"\r\n")
        return path

    # -- receiving -----------------------------------------------------------------------------
    def _on_bytes(self, data: bytes, t: float) -> None:
        for b in data:
            if self.silent:
                return
            if b == 0x18:
                self._soft_reset()
                continue
            if self.critical:  # protocol.c's critical-event loop: only a reset gets out
                continue
            if b == 0x3F:  # ?
                self._status()
                continue
            if b == 0x21:  # !
                self._feed_hold_at(t)
                continue
            if b == 0x7E:  # ~
                self.cycle_start()
                continue
            if 0x90 <= b <= 0x9D:  # feed, rapid and spindle overrides
                self._override(b, t)
                continue
            if b > 0x7F:  # other real-time (extended ASCII) commands: not in the buffer
                continue
            if self._count_byte() or self.fill >= self.rx_capacity:
                self.overruns += 1
                self._event("overrun", f"byte {self.bytes_arrived} dropped", t)
                continue
            self.received.append(b)
            self.fill += 1
            self.max_fill = max(self.max_fill, self.fill)
            if b in (0x0A, 0x0D):
                self._rx_lines.append((bytes(self._partial), t))
                self._partial.clear()
            else:
                self._partial.append(b)
        self._process_lines(t)

    def _periodic(self, now: float) -> None:
        if self._pending is not None:
            self._process_lines(now)

    # -- executor hooks ------------------------------------------------------------------------
    def _before_block(self, b: _Planned, t0: float) -> bool:
        if self.sim_reset_at_block is not None and b.seq == self.sim_reset_at_block:
            self.sim_reset_at_block = None
            self._plan.appendleft(b)
            self._cur = None
            self._event("injected_reset", f"reset at line {b.seq}", t0)
            self._soft_reset(moving=True, advance=False)
            return False
        return True

    def _on_block_done(self, b: _Planned) -> None:
        if b.ends_program:
            self._event("program_end", f"{b.seq + 1} blocks", self._seg_t1)
            self._started = False
        if b.pause:  # M0: program pause is a feed hold (gcode.c)
            self.held = True
            self._hold_t = self._hold_done_at = self._seg_t1
            self._hold_frac = None
            self._event("hold", "M0 program pause", self._seg_t1)
        self._process_lines(self._seg_t1)

    def _on_alarm(self, code: int) -> None:
        self._plan.clear()
        self._cur = None
        self._pending = None
        self._hold_stop_at = None
        if code in _CRITICAL_ALARMS:  # the state first: whoever reads the message sees it
            self.critical = True
        self._send(f"ALARM:{code}\r\n".encode())
        if code in _CRITICAL_ALARMS:
            self._send(GRBL_MSG_RESET_TO_CONTINUE.encode() + b"\r\n")
        else:  # the reset that goes with it: banner, Alarm lock
            self._rx_lines.clear()
            self._partial.clear()
            self.fill = 0
            self._send(BANNER + GRBL_MSG_ALARM_LOCK.encode() + b"\r\n")

    # -- real-time -----------------------------------------------------------------------------
    def _moving(self) -> bool:
        """Motion under way (the stepper running or decelerating): a reset now loses position."""
        if self.alarm:
            return False
        if self._hold_stop_at is not None:
            return True
        if self.held:
            return self.clock.now() < self._hold_done_at
        b = self._cur
        if b is not None and len(b.motion):
            if int(b.motion.kind[self._seg_i]) != DWELL and self._seg_t1 > self.clock.now():
                return True
        return any(len(p.motion) and int(p.motion.kind[0]) != DWELL for p in self._plan)

    def state_name(self) -> str:
        if self.alarm:
            return "Alarm"
        now = self.clock.now()
        if self._hold_stop_at is not None or (self.held and now < self._hold_done_at):
            return "Hold:1"
        if self.held:
            return "Hold:0"
        b = self._cur
        if b is not None and len(b.motion) and int(b.motion.kind[self._seg_i]) == DWELL:
            return "Idle" if not self._plan else "Run"  # mc_dwell: synced, then Idle
        if b is not None or self._plan:
            return "Run"
        return "Idle"

    def _decel_s(self) -> float:
        if self.hold_decel_s is not None:
            return float(self.hold_decel_s)
        b = self._cur
        v = 0.0
        if b is not None and len(b.motion):
            v = self._speed_mm_min(b) / 60.0
        a = getattr(self.machine, "accel_mm_s2", None) or 500.0
        return min(max(v / a, 0.02), 1.0)

    def _speed_mm_min(self, b: _Planned) -> float:
        """The running segment's speed, mm/min: st_get_realtime_rate, overrides included."""
        i = self._seg_i
        run = self._seg_t1 - self._seg_t0
        if run <= 0:
            return 0.0
        return self._programmed_mm_min(b, i) * float(b.durations_s[i]) * (1 - self._seg_frac0) / run

    def _programmed_mm_min(self, b: _Planned, i: int) -> float:
        """Segment ``i``'s speed at 100 %, mm/min (0 for a dwell)."""
        if int(b.motion.kind[i]) == DWELL:
            return 0.0
        dur = float(b.durations_s[i])
        if dur <= 0:
            return 0.0
        d = np.linalg.norm(np.subtract(b.motion.end[i], b.motion.start[i]))
        feed = float(b.motion.feed_mm_min[i])
        return feed if feed == feed and int(b.motion.kind[i]) in (2, 3) else float(d / dur * 60)

    def _feed_hold_at(self, t: float) -> None:
        now = self.clock.now()
        self._advance(now)
        if self.held or self._hold_stop_at is not None or self.alarm:
            return
        moving = self._moving()
        decel = self._decel_s() if moving else 0.0
        if moving and decel > 0:
            self._hold_stop_at = now + decel / 2
            self._hold_done_at = now + decel
            self._event("hold_request", f"decelerating {decel:.3f} s", now)
        else:
            self._hold_done_at = now
            self.held = True
            self._hold_t = now
            self._interrupt(now, "hold")

    def feed_hold(self) -> None:
        """``!`` from the panel side (the same as receiving it)."""
        with self._lock:
            self._feed_hold_at(self.clock.now())

    def cycle_start(self) -> None:
        with self._lock:
            now = self.clock.now()
            self._advance(now)
            if self._hold_stop_at is not None or (self.held and now < self._hold_done_at):
                return  # a hold still under way is not resumed (protocol.c)
            super().cycle_start()
            self._process_lines(now)

    def position_mm(self) -> tuple[float, float, float]:
        b = self._cur
        if b is None or not len(b.motion) or self.held:
            return self._pos
        now = self.clock.now()
        dur = self._seg_t1 - self._seg_t0
        frac_run = min(1.0, (now - self._seg_t0) / dur) if dur > 0 else 1.0
        return self._point(self._seg_i, self._seg_frac0 + (1 - self._seg_frac0) * frac_run)

    def _status(self) -> None:
        """report_realtime_status (:class:`rig.sim._grbl_report.StatusReport`)."""
        now = self.clock.now()
        self._advance(now)
        state = self.state_name()
        mask = int(self.settings.get(10, 1))
        pos = self.position_mm()
        wco = wco_mm(self.grbl.state)
        free = None  # planner blocks, receive-buffer bytes: with $10 & 2 only
        if mask & 2:
            blocks = max(0, self.planner_blocks - self._planner_used())
            free = (blocks, self.rx_capacity - self.fill)
        b = self._cur
        ln = b.n_number if self.line_numbers and b is not None and b.n_number > 0 else None
        feed = 0.0
        if b is not None and len(b.motion) and not self.held and self._hold_stop_at is None:
            feed = self._speed_mm_min(b)
        ovr = (self.feed_ovr, self.rapid_ovr, self.spindle_ovr)
        coolant = bool(self.interp.state.coolant)
        fields = StatusFields(state, pos, wco, free, ln, feed, self._spindle, ovr, coolant)
        self._send(self._report.line(fields, mask).encode())

    def _soft_reset(self, moving: bool | None = None, advance: bool = True) -> None:
        """0x18: mc_reset, then main()'s re-initialisation."""
        now = self.clock.now()
        if advance:
            self._advance(now)
        moving = self._moving() if moving is None else moving
        alarm = self.alarm
        self.critical = False
        self.reset(clear_wire=False)
        self.grbl.reset()
        if moving and not alarm:
            self.alarm = "3"  # the state first: whoever reads the message sees it
            self._event("alarm", "3: reset while in motion", now)
            self._send(b"ALARM:3\r\n")
        else:
            self.alarm = alarm
        self._send(BANNER)
        if self.alarm:
            self._send(GRBL_MSG_ALARM_LOCK.encode() + b"\r\n")

    def soft_reset(self) -> None:
        """0x18 from the panel side (same as receiving it)."""
        with self._lock:
            self._soft_reset()

    def _after_reset(self) -> None:
        self.critical = False
        self._grbl_state()

    def _after_reopen(self) -> None:
        # the bytes of a line cut by the unplug would otherwise prefix the next stream's line
        self.fill -= len(self._partial)
        self._partial.clear()
