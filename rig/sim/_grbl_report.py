"""What the simulated GRBL reports (report.c): the real-time status report with its refresh
counters, the work coordinate offset, the ``$G`` modes; its banner and ``$$`` settings
(defaults.h). Used by :class:`rig.sim.grbl.SimGrbl`.
"""

from __future__ import annotations

from dataclasses import dataclass

from planning.nc.grbl import GrblState

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
_SETTINGS = {0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: 0.010, 12: 0.002, 13: 0,
             20: 0, 21: 0, 22: 0, 23: 0, 24: 25.0, 25: 500.0, 26: 250, 27: 1.0, 30: 1000, 31: 0,
             32: 0, 100: 250.0, 101: 250.0, 102: 250.0, 110: 500.0, 111: 500.0, 112: 500.0,
             120: 10.0, 121: 10.0, 122: 10.0, 130: 200.0, 131: 200.0, 132: 200.0}  # fmt: skip
_CRITICAL_ALARMS = (1, 2)  # hard and soft limit: protocol.c blocks until a reset


@dataclass(frozen=True)
class StatusFields:
    """One status report's values: the state name; the machine position and the work
    coordinate offset, mm; free planner blocks and receive-buffer bytes (None: not asked by
    ``$10``); the running block's N number (None: none or not reported); the feed, mm/min, and
    spindle speed, rpm (signed: + M3, - M4); the overrides (feed, rapid, spindle), %; coolant on.
    """

    state: str
    mpos_mm: tuple[float, float, float]
    wco_mm: tuple[float, float, float]
    buffer_free: tuple[int, int] | None
    line_number: int | None
    feed_mm_min: float
    spindle_rpm: float
    overrides_pct: tuple[int, int, int]
    coolant: bool


class StatusReport:
    """report_realtime_status, fields in report.c's order, with its refresh counters: ``WCO``
    every 10 reports idle and 30 busy, ``Ov`` every 10 and 20 (and in the report after a
    ``WCO``), at once after an override changed."""

    def __init__(self) -> None:
        self.wco_counter = 0
        self.ovr_counter = 0

    def override_changed(self) -> None:
        self.ovr_counter = 0  # report the change at once

    def line(self, f: StatusFields, mask: int) -> str:
        """The report for ``f`` with the ``$10`` ``mask`` (1 MPos, else WPos; 2 adds Bf)."""
        (x, y, z), wco = f.mpos_mm, f.wco_mm
        if mask & 1:
            pos = f"|MPos:{x:.3f},{y:.3f},{z:.3f}"
        else:
            pos = f"|WPos:{x - wco[0]:.3f},{y - wco[1]:.3f},{z - wco[2]:.3f}"
        out = f"<{f.state}{pos}"
        if f.buffer_free is not None:
            out += f"|Bf:{f.buffer_free[0]},{f.buffer_free[1]}"
        if f.line_number is not None:
            out += f"|Ln:{f.line_number}"
        out += f"|FS:{f.feed_mm_min:.0f},{abs(f.spindle_rpm):.0f}"
        busy = f.state.startswith(("Run", "Hold"))
        if self.wco_counter > 0:
            self.wco_counter -= 1
        else:
            self.wco_counter = (30 if busy else 10) - 1
            if self.ovr_counter == 0:
                self.ovr_counter = 1
            out += f"|WCO:{wco[0]:.3f},{wco[1]:.3f},{wco[2]:.3f}"
        if self.ovr_counter > 0:
            self.ovr_counter -= 1
        else:
            self.ovr_counter = (20 if busy else 10) - 1
            ovr = f.overrides_pct
            out += f"|Ov:{ovr[0]},{ovr[1]},{ovr[2]}"
            rpm = f.spindle_rpm
            acc = ("S" if rpm > 0 else "C" if rpm < 0 else "") + ("F" if f.coolant else "")
            if acc:
                out += f"|A:{acc}"
        return f"{out}>\r\n"


def wco_mm(g: GrblState) -> tuple[float, float, float]:
    """The work coordinate offset: the coordinate system's, G92's and the tool length's."""
    c = g.coord_systems[g.coord_select]
    return (c[0] + g.coord_offset[0], c[1] + g.coord_offset[1],
            c[2] + g.coord_offset[2] + g.tool_length_offset)  # fmt: skip


def gcode_modes(g: GrblState) -> str:
    """report_gcode_modes: ``[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]``."""
    motion = f"{g.motion}" if g.motion < 100 else f"38.{g.motion - 136}"
    sp = {1: 3, -1: 4, 0: 5}[g.spindle]
    return (
        f"[GC:G{motion} G{54 + g.coord_select} G{17 + g.plane} G{21 - g.inches} "
        f"G{90 + g.incremental} G{94 - g.inverse_time} M{sp} M{8 if g.coolant else 9} "
        f"T{g.tool} F{g.feed / (25.4 if g.inches else 1):.0f} S{g.spindle_speed:.0f}]"
    )
