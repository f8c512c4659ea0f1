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

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.config import MachineConfig
from planning.nc import DWELL, RAPID, NCError
from planning.nc.grbl import (
    GRBL_MSG_ALARM_LOCK,
    GRBL_MSG_PGM_END,
    GRBL_MSG_RESET_TO_CONTINUE,
    GRBL_MSG_UNLOCKED,
    GRBL_PLANNER_BLOCKS,
    GRBL_RX_BUFFER_SIZE,
    GrblParser,
    GrblResult,
    grbl_filter,
)
from rig.sim._controller import SimControllerBase, _Planned

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
_SETTINGS = {0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: 0.010, 12: 0.002, 13: 0,
             20: 0, 21: 0, 22: 0, 23: 0, 24: 25.0, 25: 500.0, 26: 250, 27: 1.0, 30: 1000, 31: 0,
             32: 0, 100: 250.0, 101: 250.0, 102: 250.0, 110: 500.0, 111: 500.0, 112: 500.0,
             120: 10.0, 121: 10.0, 122: 10.0, 130: 200.0, 131: 200.0, 132: 200.0}  # fmt: skip
_CRITICAL_ALARMS = (1, 2)  # hard and soft limit: protocol.c blocks until a reset
# config.h: MIN/MAX_FEED_RATE_OVERRIDE, MIN/MAX_SPINDLE_SPEED_OVERRIDE, %
FEED_OVR_MIN, FEED_OVR_MAX, SPINDLE_OVR_MIN, SPINDLE_OVR_MAX = 10, 200, 10, 200
# stepper.c: a step segment is DT_SEGMENT = 1 / ACCELERATION_TICKS_PER_SECOND (100) of motion;
# the segment ring (SEGMENT_BUFFER_SIZE 6) holds 5, the one running and 4 prepared ahead. An
# override recomputes the plan (plan_cycle_reinitialize) and the spindle PWM (STEP_CONTROL_
# UPDATE_SPINDLE_PWM) for the segments prepared from then on: what is already in the ring runs
# at the old values first.
DT_SEGMENT_S = 0.01
SEGMENTS_AHEAD = 4


@dataclass
class _Pending:
    """The line GRBL is busy with (out of the receive buffer, its answer not sent yet)."""

    k: int  # order among the g-code lines received
    res: GrblResult
    planned: _Planned | None
    stage: str  # "sync" (waits for the planner to empty) or "room" (waits for its answer)
    t: float


class SimGrbl(SimControllerBase):
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
        self._wco_counter = 0
        self._ovr_counter = 0
        # main.c sets them to their defaults on every (re)start: a reset ends any override
        self.feed_ovr = self.rapid_ovr = self.spindle_ovr = 100  # sys.*: reported at once
        #: the overrides the motion runs at (the step segments prepared after a change), and
        #: the changes still behind the segments already in the ring: (time s, feed, rapid, spindle)
        self._run_ovr = (100, 100, 100)
        self._ovr_due: deque[tuple[float, int, int, int]] = deque()

    def start(self) -> str:
        path = super().start()
        with self._lock:
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

    # -- planner ------------------------------------------------------------------------------
    def _remaining_blocks(self, b: _Planned, now: float) -> int:
        if b.blocks <= 0 or not len(b.motion):
            return 0
        total = float(np.sum(b.durations_s))
        if total <= 0:
            return b.blocks
        i = self._seg_i
        rest = float(np.sum(b.durations_s[i + 1 :]))
        # in programmed time (an override scales the running segment, not the block's total)
        if not self.held and self._seg_t1 > now:
            run = self._seg_t1 - self._seg_t0
            frac = self._seg_frac0 + (1 - self._seg_frac0) * (now - self._seg_t0) / run
            rest += float(b.durations_s[i]) * (1 - frac)
        elif self.held:
            rest += float(b.durations_s[i]) * (1 - (self._hold_frac or 0.0))
        return min(b.blocks, math.ceil(b.blocks * rest / total - 1e-9))

    def _planner_used(self) -> int:
        used = sum(p.blocks for p in self._plan)
        if self._cur is not None:
            used += self._remaining_blocks(self._cur, self.clock.now())
        return used

    def _planner_empty(self) -> bool:
        return self._cur is None and not self._plan

    def _process_lines(self, t: float) -> None:
        """GRBL's main loop: finish the line it is busy with, then read the next ones."""
        while not self.silent and not self.critical:
            if self._pending is not None:
                t_ok = self._finish_pending(t)
                if t_ok is None:
                    return
                t = t_ok  # the lines behind it are read from then on
                continue
            if not self._rx_lines:
                return
            raw, t_arr = self._rx_lines.popleft()
            self.fill -= len(raw) + 1
            self._line(raw.decode("ascii", "replace"), max(t, t_arr))

    def _finish_pending(self, t: float) -> float | None:
        """Answer the pending line if it can be answered by ``t``; the answer's time, or None."""
        p = self._pending
        assert p is not None
        if p.stage == "sync":
            if not self._planner_empty():
                return None
            p.stage = "room"
            if p.planned is not None:
                self._plan_line(p.planned)
        b = p.planned
        t_room = None
        if p.res.dwell_s > 0 or p.res.program_flow == "pause":
            if b is not None and not b.done:
                return None
            if p.res.program_flow == "pause" and self.held:
                return None
        elif b is not None and b.blocks > 0:
            t_room = self._room_time()
            if self._planner_used() > self.planner_blocks:
                return None
        self._pending = None
        if p.res.program_flow == "end":
            self._send(GRBL_MSG_PGM_END.encode() + b"\r\n")
        t_ok = max(p.t, t_room) if t_room is not None else max(t, p.t)
        self._ok(p.k, t_ok)
        return t_ok

    def _room_time(self) -> float | None:
        """When the running line (an arc's mc_arc blocks) will have freed the planner room the
        pending line waits for, if within its running segment: the answer's time is then this,
        not the moment this thread ran (late on a loaded host, by seconds at speed 10)."""
        p, b = self._pending, self._cur
        if p is None or p.stage != "room" or p.planned is None or p.planned.blocks <= 0:
            return None
        if b is None or b.blocks <= 0 or self.held or self._hold_stop_at is not None:
            return None
        keep = self.planner_blocks - sum(q.blocks for q in self._plan)  # cur's share, blocks
        total = float(np.sum(b.durations_s))
        i = self._seg_i
        dur, run = float(b.durations_s[i]), self._seg_t1 - self._seg_t0
        after = float(np.sum(b.durations_s[i + 1 :]))
        if keep < 0 or total <= 0 or dur <= 0 or run <= 0 or self._seg_frac0 >= 1.0:
            return None
        # _remaining_blocks <= keep once the programmed time left is <= keep * total / blocks
        rest_max = keep * total / b.blocks
        if not after <= rest_max <= after + dur:
            return None
        frac = 1.0 - (rest_max - after) / dur
        return self._seg_t0 + max(0.0, frac - self._seg_frac0) / (1.0 - self._seg_frac0) * run

    def _plan_line(self, planned: _Planned) -> None:
        self._plan.append(planned)
        if planned.ends_program:  # M2/M30: the modal state for the next program
            pos = self.interp.state.position_mm
            self._new_interpreter()
            self.interp.state.position_mm = pos
        if planned.blocks and self._planner_used() > self.planner_blocks:
            self.planner_waits += 1

    # -- answering ------------------------------------------------------------------------------
    def _reply(self, msg: bytes) -> None:
        self._send(msg + b"\r\n")

    def _ok(self, k: int | None = None, t: float | None = None) -> None:
        if k is not None:
            self.ok_times_s.append((k, self.clock.now() if t is None else t))
        if k is not None and k == self.sim_drop_ok_at_line:
            self.sim_drop_ok_at_line = None
            self._event("ok_dropped", f"line {k}: its ok is lost")
            return
        if k is not None and k == self.sim_garble_ok_at_line:
            self.sim_garble_ok_at_line = None
            self._event("ok_garbled", f"line {k}: its ok arrives as 'oo'")
            self._reply(b"oo")
            return
        if k is not None and k == self.sim_noise_at_line:
            self.sim_noise_at_line = None
            self._event("noise", f"line {k}: a line of noise before its ok")
            self._reply(b"\xfe~#q")
        self.oks += 1
        self._reply(b"ok")

    def _error(self, code: int, text: str) -> None:
        self.errors.append((code, text))
        self._event("error", f"error:{code} {text}")
        self._reply(f"error:{code}".encode())

    def _line(self, text: str, t: float) -> None:
        f = grbl_filter(text)
        if f.overflow:
            self._error(11, text)
            return
        if not f.text:  # empty or comment line: 'ok' (for syncing, protocol.c)
            self._ok()
            return
        if f.text.startswith("$"):
            self._dollar(f.text, text)
            return
        k = self.lines_received
        if not self._block_received():
            return
        self.lines_received += 1
        if self.alarm:
            self._error(9, text)
            return
        if self.sim_error_at_block is not None and k == self.sim_error_at_block[0]:
            code_n = self.sim_error_at_block[1]
            self.sim_error_at_block = None
            self._error(code_n, text)
            return
        res = self.grbl.parse(f.text)
        if not res.ok:
            self._error(res.code, text)
            return
        try:
            planned = self._interpret(f.text, t)
        except NCError as exc:  # accepted by GRBL, beyond what planning.nc runs
            self._event("unsimulated", f"{text}: {exc.reason}")
            planned = None
        if planned is not None:
            planned.text = text
            planned.blocks = res.planner_blocks
            planned.pause = res.program_flow == "pause"
        self._pending = _Pending(k, res, planned, "sync" if res.sync else "room", t)
        if not res.sync and planned is not None:
            self._plan_line(planned)

    def _dollar(self, cmd: str, text: str) -> None:
        state = self.state_name()
        if cmd in ("$$", "$I") and state.startswith(("Run", "Hold")):
            self._error(8, text)  # "not idle" for these while running or held
            return
        if cmd[1:2] in ("#", "H", "I", "N") and state not in ("Idle", "Alarm"):
            self._error(8, text)
            return
        if cmd == "$$":
            out = "".join(
                f"${k}={v:.3f}\r\n" if isinstance(v, float) else f"${k}={v:g}\r\n"
                for k, v in sorted(self.settings.items())
            )
            self._send(out.encode())
        elif cmd == "$X":
            if self.alarm:
                self.alarm = ""
                self._send(GRBL_MSG_UNLOCKED.encode() + b"\r\n")
        elif cmd == "$H":
            if not self.settings[22]:
                self._error(5, text)  # homing not enabled ($22=0)
                return
            self._pos = (0.0, 0.0, 0.0)
            self.interp.state.position_mm = self._pos
            self.grbl.state.position = [0.0, 0.0, 0.0]
            self.alarm = ""
        elif cmd == "$I":
            opt = f"V{'N' if self.line_numbers else ''},{self.planner_blocks},{self.rx_capacity}"
            self._send(f"[VER:1.1h.20190825:cutlab-sim]\r\n[OPT:{opt}]\r\n".encode())
        elif cmd == "$G":
            self._send(self._gcode_modes().encode() + b"\r\n")
        elif cmd in ("$#", "$C", "$N"):
            pass
        elif cmd[1:].partition("=")[0].isdigit() and "=" in cmd:
            k, _, v = cmd[1:].partition("=")
            try:
                value = float(v)
            except ValueError:
                self._error(2, text)
                return
            if int(k) not in self.settings:
                self._error(3, text)
                return
            self.settings[int(k)] = value
            if int(k) == 12:
                self.grbl.arc_tolerance_mm = value
        else:
            self._error(3, text)
            return
        self._ok()

    def _gcode_modes(self) -> str:
        """report_gcode_modes: ``[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]``."""
        g = self.grbl.state
        motion = f"{g.motion}" if g.motion < 100 else f"38.{g.motion - 136}"
        sp = {1: 3, -1: 4, 0: 5}[g.spindle]
        return (
            f"[GC:G{motion} G{54 + g.coord_select} G{17 + g.plane} G{21 - g.inches} "
            f"G{90 + g.incremental} G{94 - g.inverse_time} M{sp} M{8 if g.coolant else 9} "
            f"T{g.tool} F{g.feed / (25.4 if g.inches else 1):.0f} S{g.spindle_speed:.0f}]"
        )

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

    # -- overrides (protocol_exec_rt_system, plan_compute_profile_nominal_speed) ---------------
    def _override(self, code: int, t: float) -> None:
        """One override byte arrived at ``t``: the new value within GRBL's limits; a change is
        reported in the next status (``Ov:``) and applied to the segment running (split there)
        and to every one after it (the planner recomputes the blocks it holds)."""
        f, r, s = self.feed_ovr, self.rapid_ovr, self.spindle_ovr
        if code == 0x90:
            f = 100
        elif 0x91 <= code <= 0x94:
            f += {0x91: 10, 0x92: -10, 0x93: 1, 0x94: -1}[code]
        elif code <= 0x97:
            r = {0x95: 100, 0x96: 50, 0x97: 25}[code]
        elif code == 0x99:
            s = 100
        elif 0x9A <= code <= 0x9D:
            s += {0x9A: 10, 0x9B: -10, 0x9C: 1, 0x9D: -1}[code]
        else:  # 0x98 is unused in 1.1h
            return
        f = min(max(f, FEED_OVR_MIN), FEED_OVR_MAX)
        s = min(max(s, SPINDLE_OVR_MIN), SPINDLE_OVR_MAX)
        if (f, r, s) == (self.feed_ovr, self.rapid_ovr, self.spindle_ovr):
            return  # at a limit: nothing changes, nothing is reported
        now = max(t, self._advanced_t)  # never before what the executor has already run
        self._advance(now)
        self._ovr_counter = 0  # report the change at once
        self.feed_ovr, self.rapid_ovr, self.spindle_ovr = f, r, s
        self._event("override", f"feed {f} %, rapid {r} %, spindle {s} %", now)
        # moving, the segments already prepared run first: the change starts with the first
        # segment prepared after it, SEGMENTS_AHEAD segment times after the running one ends
        # (40-50 ms); idle or held, nothing is prepared and it applies at once
        due = now
        if self._moving() and not self.held and self._hold_stop_at is None:
            due = (math.floor(now / DT_SEGMENT_S + 1e-9) + 1 + SEGMENTS_AHEAD) * DT_SEGMENT_S
        self._ovr_due.append((max(due, self._ovr_due[-1][0] if self._ovr_due else due), f, r, s))
        self._advance(now)

    def _apply_override(self, now: float, f: int, r: int, s: int) -> None:
        """The stepper reaches the segments prepared at the new values: the running segment is
        split at ``now`` and goes on at them, the spindle turns at its new speed."""
        f0, r0, _ = self._run_ovr
        self._run_ovr = (f, r, s)
        if (f, r) != (f0, r0):
            self._replan(now)
        rpm = self._spindle_prog * self._rpm_scale()
        if rpm != self._spindle:
            self._spindle = rpm
            for fn in self._spindle_listeners:
                fn(now, rpm)

    def _replan(self, now: float) -> None:
        """The running segment goes on from where it is at its new speed (a hold being carried
        out, or held, takes the new speed when it resumes)."""
        b = self._cur
        if b is None or not len(b.motion) or self.held or self._hold_stop_at is not None:
            return
        if int(b.motion.kind[self._seg_i]) == DWELL or self._seg_t1 <= now:
            return
        run = self._seg_t1 - self._seg_t0
        frac = self._seg_frac0 + (1 - self._seg_frac0) * (now - self._seg_t0) / run
        self.busy_s -= self._seg_t1 - now
        self._start_segment(now, frac)

    def _time_scale(self, b: _Planned, i: int) -> float:
        kind = int(b.motion.kind[i])
        feed_ovr, rapid_ovr, _ = self._run_ovr
        if kind == DWELL:
            return 1.0
        if kind == RAPID:
            return 100.0 / rapid_ovr
        if feed_ovr == 100:
            return 1.0
        v = self._programmed_mm_min(b, i)
        if v <= 0:
            return 1.0
        # the overridden feed stays below the rapid rate (block->rapid_rate)
        return v / min(v * feed_ovr / 100.0, max(self.rapid_mm_min, v))

    def _rpm_scale(self) -> float:
        return self._run_ovr[2] / 100.0

    def _start_block(self, b: _Planned, t0: float) -> None:
        super()._start_block(b, t0)
        if self._cur is b:
            self._spindle_prog = b.spindle_rpm

    def _advance(self, now: float) -> None:
        while self._ovr_due and self._ovr_due[0][0] <= now:
            t_due, f, r, s = self._ovr_due.popleft()
            t_due = max(t_due, self._advanced_t)
            super()._advance(t_due)
            self._advanced_t = max(self._advanced_t, t_due)
            self._apply_override(t_due, f, r, s)
        super()._advance(now)
        self._advanced_t = max(self._advanced_t, now)

    def _next_wake(self, now: float) -> float:
        t = super()._next_wake(now)
        return max(min(t, self._ovr_due[0][0]), now) if self._ovr_due else t

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

    def _wco(self) -> tuple[float, float, float]:
        g = self.grbl.state
        c = g.coord_systems[g.coord_select]
        return (c[0] + g.coord_offset[0], c[1] + g.coord_offset[1],
                c[2] + g.coord_offset[2] + g.tool_length_offset)  # fmt: skip

    def _status(self) -> None:
        """report_realtime_status, fields in report.c's order."""
        now = self.clock.now()
        self._advance(now)
        state = self.state_name()
        mask = int(self.settings.get(10, 1))
        x, y, z = self.position_mm()
        wco = self._wco()
        if mask & 1:
            pos = f"|MPos:{x:.3f},{y:.3f},{z:.3f}"
        else:
            pos = f"|WPos:{x - wco[0]:.3f},{y - wco[1]:.3f},{z - wco[2]:.3f}"
        out = f"<{state}{pos}"
        if mask & 2:
            free = max(0, self.planner_blocks - self._planner_used())
            out += f"|Bf:{free},{self.rx_capacity - self.fill}"
        b = self._cur
        if self.line_numbers and b is not None and b.n_number > 0:
            out += f"|Ln:{b.n_number}"
        feed = 0.0
        if b is not None and len(b.motion) and not self.held and self._hold_stop_at is None:
            feed = self._speed_mm_min(b)
        out += f"|FS:{feed:.0f},{abs(self._spindle):.0f}"
        busy = state.startswith(("Run", "Hold"))
        if self._wco_counter > 0:
            self._wco_counter -= 1
        else:
            self._wco_counter = (30 if busy else 10) - 1
            if self._ovr_counter == 0:
                self._ovr_counter = 1
            out += f"|WCO:{wco[0]:.3f},{wco[1]:.3f},{wco[2]:.3f}"
        if self._ovr_counter > 0:
            self._ovr_counter -= 1
        else:
            self._ovr_counter = (20 if busy else 10) - 1
            out += f"|Ov:{self.feed_ovr},{self.rapid_ovr},{self.spindle_ovr}"
            acc = ("S" if self._spindle > 0 else "C" if self._spindle < 0 else "") + (
                "F" if self.interp.state.coolant else ""
            )
            if acc:
                out += f"|A:{acc}"
        self._send(f"{out}>\r\n".encode())

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
