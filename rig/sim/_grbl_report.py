"""What the simulated GRBL reports and its ``$`` commands (report.c, system.c, settings.c): the
status report, ``$$``, ``$G``, ``$I``, ``$X``, ``$H``, ``$n=value``. Mixed into
:class:`rig.sim.grbl.SimGrbl`, which owns the state it uses (see its module docstring).
"""

from __future__ import annotations

from planning.nc.grbl import GRBL_MSG_UNLOCKED

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
_SETTINGS = {0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: 0.010, 12: 0.002, 13: 0,
             20: 0, 21: 0, 22: 0, 23: 0, 24: 25.0, 25: 500.0, 26: 250, 27: 1.0, 30: 1000, 31: 0,
             32: 0, 100: 250.0, 101: 250.0, 102: 250.0, 110: 500.0, 111: 500.0, 112: 500.0,
             120: 10.0, 121: 10.0, 122: 10.0, 130: 200.0, 131: 200.0, 132: 200.0}  # fmt: skip
_CRITICAL_ALARMS = (1, 2)  # hard and soft limit: protocol.c blocks until a reset


class GrblReportMixin:
    """The status report and the ``$`` lines of SimGrbl."""

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
