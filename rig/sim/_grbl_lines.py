"""GRBL's main loop over the receive buffer (protocol.c, planner.c, system.c): each line read
when the one before is done, checked, planned (``ok`` means *planned*) and answered; the ``$``
lines (``$$``, ``$G``, ``$I``, ``$X``, ``$H``, ``$n=value``). Mixed into
:class:`rig.sim.grbl.SimGrbl`, which owns the state it uses (see its module docstring).
"""

from __future__ import annotations

import math

import numpy as np

from planning.nc import NCError
from planning.nc.grbl import GRBL_MSG_PGM_END, GRBL_MSG_UNLOCKED, grbl_filter
from rig.sim._controller import _Planned
from rig.sim._grbl_report import gcode_modes
from rig.sim._grbl_state import GrblFields, _Pending


class GrblLinesMixin(GrblFields):
    """The line protocol of SimGrbl: planner room, line processing, answers, ``$`` lines."""

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
            # in lockstep the clock stands at t_room (a gate): the room is there then, whatever
            # the last bit of the count's rounding says
            at_room = self.lockstep and t_room is not None and self.clock.now() >= t_room
            if self._planner_used() > self.planner_blocks and not at_room:
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
            self._send(gcode_modes(self.grbl.state).encode() + b"\r\n")
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
