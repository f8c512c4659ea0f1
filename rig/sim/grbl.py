"""A simulated GRBL 1.1 controller on the other end of a pseudo-terminal.

Start it in-process::

    ctl = SimGrbl(machine, clock=SimClock(speed=20))
    path = ctl.start()                 # the tty path for the streamer
    ctl.add_listener(on_segment=machine.on_segment, on_spindle=machine.on_spindle)
    ctl.stop()

or ``cutlab dnc sim-controller --protocol grbl``.

Behaviour
---------
- Serial receive buffer of ``rx_buffer_bytes`` (127 as on an Uno); a byte arriving into a full
  buffer is dropped and counted in ``overruns`` (GRBL does the same, silently).
- Real-time commands are picked out on arrival: ``?`` status report, ``!`` feed hold, ``~`` cycle
  start, 0x18 soft reset (banner ``Grbl 1.1h ['$' for help]``; a reset during motion leaves
  ``ALARM:3`` and the Alarm lock).
- Lines are taken from the receive buffer when the planner (``planner_blocks`` segments) has room;
  each is answered ``ok`` when it is planned, ``error:N`` when rejected: unsupported codes (G98/G99,
  canned cycles G81-G83, cutter compensation G41/G42, G43 without .1, M6, G90.1, letters other
  than N G M F S T X Y Z I J K R P L such as O program numbers -> 20), more than
  79 characters (11), an NC error from the interpreter (arcs 33, missing feed 22, number format 2,
  otherwise 20), any line while in Alarm (9). Empty lines are answered ``ok``.
- ``$`` lines: ``$$`` (settings), ``$I``, ``$G``, ``$#``, ``$X`` (unlock), ``$H`` (homing: goes to
  0,0,0), ``$C``, ``$N``, ``$n=value`` are answered; others ``error:3``.
- M2/M30 ends the program (event ``program_end`` when it has run) and resets the modal state.
- Status report ``<State|MPos:x,y,z|Bf:planner_free,rx_free|FS:feed,rpm>`` (as with ``$10=2``
  plus buffer data); states Idle, Run, Hold:0, Alarm.

Fault knobs (``sim_``): ``sim_stop_answering_after_block=k`` (after k lines: silence),
``sim_drop_port_after_block=k`` (close the pty; :meth:`reopen` gives a new path),
``sim_overrun_at_byte=n`` (drop received byte n, as an overrun would), ``sim_error_at_block=(k,
code)`` (answer line k with ``error:code`` once, not executing it), ``sim_alarm_at_block=(k,
code)`` (``ALARM:code`` when line k starts; motion stops, buffers flushed, Alarm lock until ``$X``),
``sim_stop_answering_at_s=t``, ``sim_alarm_at_s=(t, code)`` (the same at simulated time t).

Notes
-----
How it differs from GRBL:

- The line rate is emulated on the SimClock (a pty has none); only a wrong baud rate is detected
  (the bytes are then dropped as framing garbage). Data bits/parity are not seen on a pty.
- No acceleration planning: each segment runs at its programmed feed; arcs are one planner block
  each (GRBL splits them into many short lines). A line is planned only when the planner has a free
  slot; a line with several segments may then overfill it.
- Positions are the programmed tool tip in the machine frame (no homing cycle, no soft limits
  unless injected as an alarm).
"""

from __future__ import annotations

import re
from collections import deque
from typing import Any

import numpy as np

from analysis.config import MachineConfig
from planning.nc import NCError
from rig.sim._controller import SimControllerBase, _Planned

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
_WORD = re.compile(r"([A-Z])([-+]?[0-9]*\.?[0-9]*)")
_UNSUPPORTED = {("G", 98.0), ("G", 99.0), ("G", 81.0), ("G", 82.0), ("G", 83.0), ("G", 41.0),
                ("G", 42.0), ("G", 43.0), ("G", 90.1), ("M", 6.0)}  # fmt: skip


_LETTERS = frozenset("NGMFSTXYZIJKRPL")


def _unsupported(code: str) -> bool:
    """True if a word of the (upper-case, comment-free) line is a code GRBL 1.1 rejects."""
    for letter, num in _WORD.findall(code):
        if letter not in _LETTERS:  # O program numbers, A/B/C, D/H registers, ...
            return True
        if letter in "GM" and num not in ("", ".", "+", "-"):
            if (letter, round(float(num), 1)) in _UNSUPPORTED:
                return True
    return False


_COMMENT = re.compile(r"\([^)]*\)|;.*$")
_SETTINGS = {0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 3, 11: 0.010, 12: 0.002, 13: 0,
             20: 0, 21: 0, 22: 0, 23: 0, 24: 25.0, 25: 500.0, 26: 250, 27: 1.0, 30: 1000, 31: 0,
             32: 0, 100: 250.0, 101: 250.0, 102: 250.0, 110: 500.0, 111: 500.0, 112: 500.0,
             120: 10.0, 121: 10.0, 122: 10.0, 130: 200.0, 131: 200.0, 132: 200.0}  # fmt: skip


class SimGrbl(SimControllerBase):
    """GRBL-like controller (see the module docstring).

    ``base_kw``: clock, speed and the ``sim_`` fault knobs of :class:`SimControllerBase` (a
    wrong name is a TypeError).
    """

    protocol = "grbl"

    def __init__(
        self,
        machine: MachineConfig | None = None,
        *,
        baudrate: int = 115200,
        rx_buffer_bytes: int = 127,
        planner_blocks: int = 15,
        sim_error_at_block: tuple[int, int] | None = None,
        **base_kw: Any,
    ) -> None:
        super().__init__(
            machine, baudrate=baudrate, bits_per_char=10, rx_buffer_bytes=rx_buffer_bytes, **base_kw
        )  # 8N1
        self.planner_blocks = planner_blocks
        self.sim_error_at_block = sim_error_at_block
        self.settings = dict(_SETTINGS)
        self._grbl_state()

    def _grbl_state(self) -> None:
        self._rx_lines: deque[tuple[bytes, float]] = deque()
        self._partial = bytearray()
        self.fill = 0
        self.lines_received = 0
        self.oks = 0
        self.errors: list[tuple[int, str]] = []
        self.planner_waits = 0  # times a line had to wait for a free planner slot
        self._waiting_planner = False

    def start(self) -> str:
        path = super().start()
        with self._lock:
            self._send(BANNER)
        return path

    # -- receiving -----------------------------------------------------------------------------
    def _on_bytes(self, data: bytes, t: float) -> None:
        for b in data:
            if self.silent:
                return
            if b == 0x3F:  # ?
                self._status()
                continue
            if b == 0x21:  # !
                if self._cur is not None or self._plan:
                    self._feed_hold_at(t)
                continue
            if b == 0x7E:  # ~
                self.cycle_start()
                continue
            if b == 0x18:
                self._soft_reset()
                continue
            if self._count_byte() or self.fill >= self.rx_capacity:
                self.overruns += 1
                self._event("overrun", f"byte {self.bytes_arrived} dropped", t)
                continue
            self.received.append(b)
            if b in (0x0A, 0x0D):
                self._rx_lines.append((bytes(self._partial), t))
                self.fill += 1
                self._partial.clear()
            else:
                self._partial.append(b)
                self.fill += 1
            self.max_fill = max(self.max_fill, self.fill)
        self._process_lines(t)

    def _feed_hold_at(self, t: float) -> None:
        self._advance(self.clock.now())
        if not self.held:
            self.held = True
            self._interrupt(self.clock.now(), "hold")

    def _planner_used(self) -> int:
        used = sum(max(1, len(p.motion)) for p in self._plan)
        return used + (1 if self._cur is not None else 0)

    def _process_lines(self, t: float) -> None:
        """Take lines out of the receive buffer while the planner has room."""
        while self._rx_lines and not self.silent:
            if self._planner_used() >= self.planner_blocks:
                if not self._waiting_planner:
                    self._waiting_planner = True
                    self.planner_waits += 1
                return
            self._waiting_planner = False
            raw, t_arr = self._rx_lines.popleft()
            self.fill -= len(raw) + 1
            text = raw.decode("ascii", "replace").strip()
            if not text:  # empty line: 'ok' (so CR LF gives two; streamers send LF only)
                self._reply(b"ok")
                continue
            self._line(text, max(t, t_arr))

    def _reply(self, msg: bytes) -> None:
        if msg == b"ok":
            self.oks += 1
        self._send(msg + b"\r\n")

    def _error(self, code: int, text: str) -> None:
        self.errors.append((code, text))
        self._event("error", f"error:{code} {text}")
        self._reply(f"error:{code}".encode())

    def _line(self, text: str, t: float) -> None:
        if text.startswith("$"):
            self._dollar(text)
            return
        k = self.lines_received
        if not self._block_received():
            return
        self.lines_received += 1
        if self.alarm:
            self._error(9, text)
            return
        code = _COMMENT.sub("", text).replace(" ", "").upper()
        if len(code) > 79:
            self._error(11, text)
            return
        if _unsupported(code):
            self._error(20, text)
            return
        if self.sim_error_at_block is not None and k == self.sim_error_at_block[0]:
            code_n = self.sim_error_at_block[1]
            self.sim_error_at_block = None
            self._error(code_n, text)
            return
        try:
            planned = self._interpret(text, t)
        except NCError as exc:
            self._error(_error_code(exc.reason), text)
            return
        self._plan.append(planned)
        if planned.ends_program:  # M2/M30: GRBL resets its modal state for the next program
            pos = self.interp.state.position_mm  # where the planned motion ends
            self._new_interpreter()
            self.interp.state.position_mm = pos
        self._reply(b"ok")

    def _dollar(self, text: str) -> None:
        cmd = text.upper().replace(" ", "")
        if cmd in ("$$", "$I") and self.state_name() not in ("Idle", "Alarm"):
            self._error(8, text)  # GRBL 1.1: "not idle" for these while running or held
            return
        if cmd == "$$":
            out = "".join(
                f"${k}={v:.3f}\r\n" if isinstance(v, float) else f"${k}={v}\r\n"
                for k, v in sorted(self.settings.items())
            )
            self._send(out.encode())
        elif cmd == "$X":
            if self.alarm:
                self.alarm = ""
                self._send(b"[MSG:Caution: Unlocked]\r\n")
        elif cmd == "$H":
            self._pos = (0.0, 0.0, 0.0)
            self.interp.state.position_mm = self._pos
            self.alarm = ""
        elif cmd == "$I":
            self._send(b"[VER:1.1h.20190825:cutlab-sim]\r\n[OPT:V,15,128]\r\n")
        elif cmd == "$G":
            st = self.interp.state
            self._send(
                f"[GC:G{st.motion} G54 G{st.plane} G{21 - st.inch} G{91 - st.absolute} G94 "
                f"M{5 if not st.spindle_dir else (3 if st.spindle_dir > 0 else 4)} "
                f"M{8 if st.coolant else 9} T{st.tool} F{np.nan_to_num(st.feed_mm_min):g} "
                f"S{st.spindle_speed_rpm:g}]\r\n".encode()
            )
        elif cmd in ("$#", "$C", "$N"):
            pass
        elif re.fullmatch(r"\$\d+=[-+]?\d*\.?\d+", cmd):
            k, v = cmd[1:].split("=")
            if int(k) not in self.settings:
                self._error(3, text)
                return
            self.settings[int(k)] = float(v)
        else:
            self._error(3, text)
            return
        self._reply(b"ok")

    # -- executor hooks ------------------------------------------------------------------------
    def _on_block_done(self, b: _Planned) -> None:
        if b.ends_program:
            self._event("program_end", f"{b.seq + 1} blocks", self._seg_t1)
            self._started = False
        self._process_lines(self._seg_t1)

    def _next_block(self, now: float) -> _Planned | None:
        b = super()._next_block(now)
        if b is None and self._rx_lines:
            self._process_lines(now)
            b = super()._next_block(now)
        return b

    def _on_alarm(self, code: int) -> None:
        self._plan.clear()
        self._rx_lines.clear()
        self._partial.clear()
        self.fill = 0
        self._cur = None
        self._send(f"ALARM:{code}\r\n".encode())

    # -- real-time -----------------------------------------------------------------------------
    def state_name(self) -> str:
        if self.alarm:
            return "Alarm"
        if self.held:
            return "Hold:0"
        if self._cur is not None or self._plan:
            return "Run"
        return "Idle"

    def position_mm(self) -> tuple[float, float, float]:
        b = self._cur
        if b is None or not len(b.motion) or self.held:
            return self._pos
        now = self.clock.now()
        dur = self._seg_t1 - self._seg_t0
        frac_run = min(1.0, (now - self._seg_t0) / dur) if dur > 0 else 1.0
        return self._point(self._seg_i, self._seg_frac0 + (1 - self._seg_frac0) * frac_run)

    def _status(self) -> None:
        self._advance(self.clock.now())
        x, y, z = self.position_mm()
        free = max(0, self.planner_blocks - self._planner_used())
        feed = 0.0
        if self._cur is not None and len(self._cur.motion) and not self.held:
            feed = float(np.nan_to_num(self._cur.motion.feed_mm_min[self._seg_i]))
        self._send(
            f"<{self.state_name()}|MPos:{x:.3f},{y:.3f},{z:.3f}|Bf:{free},"
            f"{self.rx_capacity - self.fill}|FS:{feed:.0f},{abs(self._spindle):.0f}>\r\n".encode()
        )

    def _soft_reset(self) -> None:
        moving = (self._cur is not None or bool(self._plan)) and not self.alarm
        alarm = self.alarm
        self.reset()
        if moving:
            self.alarm = "3"
            self._send(b"ALARM:3\r\n")
        elif alarm:
            self.alarm = alarm
        self._send(BANNER)

    def soft_reset(self) -> None:
        """0x18 from the panel side (same as receiving it)."""
        with self._lock:
            self._soft_reset()

    def _after_reset(self) -> None:
        self._grbl_state()

    def _after_reopen(self) -> None:
        # the bytes of a line cut by the unplug would otherwise prefix the next stream's line
        self.fill -= len(self._partial)
        self._partial.clear()


def _error_code(reason: str) -> int:
    r = reason.lower()
    if "arc" in r or "radius" in r:
        return 33
    if "feed" in r:
        return 22
    if "number" in r or "value" in r:
        return 2
    return 20
