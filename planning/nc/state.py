"""The modal state of an NC interpreter: everything a block inherits from the blocks before it.

:class:`ModalState` is a plain mutable dataclass that the :class:`~planning.nc.Interpreter` updates
block by block; ``state.copy()`` snapshots it (the simulated controllers keep one per buffered
block; the DNC streamer restarts from one). Codes are stored as their G/M numbers where that is
the clearest name (``plane`` 17/18/19, ``work_offset`` 54..59, ``motion`` 0/1/2/3/80/81/82/83).

Positions are in mm in the machine frame the :class:`~planning.nc.Motion` arrays use, whatever
the program units; ``feed_mm_min`` likewise. :func:`planning.nc.restart.restart_preamble` turns a
state back into NC blocks.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field


@dataclass
class CannedCycle:
    """Parameters of the active G81/G82/G83 drilling cycle (all mm / s, machine frame)."""

    r_mm: float = math.nan  # retract (R) plane, absolute Z
    z_mm: float = math.nan  # hole bottom, absolute Z
    q_mm: float = math.nan  # G83 peck depth (positive)
    dwell_s: float = 0.0  # G82 dwell at the bottom
    initial_z_mm: float = math.nan  # Z when the cycle started: the G98 return level


@dataclass
class ModalState:
    """Modal state after the blocks seen so far (all lengths mm, machine frame)."""

    position_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    motion: int = 0  # G0, G1, G2, G3, G80 (none), G81, G82, G83
    plane: int = 17
    inch: bool = False  # G20 (True) / G21
    absolute: bool = True  # G90 (True) / G91
    arc_absolute: bool = False  # G90.1 (True) / G91.1: I J K absolute or relative to start
    feed_mode: int = 94  # G94 units per minute / G93 inverse time (F per block, not modal)
    cutter_comp: int = 40  # G40 / G41 / G42 (recorded; motion is not offset)
    cutter_comp_d: int = 0  # D register
    tool_length: int = 49  # G43 / G49 (recorded; positions are the programmed tool tip)
    tool_length_h: int = 0  # H register
    work_offset: int = 54  # G54..G59
    retract_initial: bool = True  # G98 (True) / G99 canned-cycle return level
    feed_mm_min: float = math.nan  # G94 F in mm/min; NaN until set and under G93
    spindle_speed_rpm: float = 0.0  # S (unsigned)
    spindle_dir: int = 0  # +1 M3, -1 M4, 0 M5
    tool: int = 0  # tool in the spindle (after M6)
    tool_selected: int = 0  # last T word
    coolant: bool = False  # M7/M8 on, M9 off
    program_number: int | None = None  # O word
    sequence_number: int | None = None  # last N word
    rotary_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)  # A B C, deg
    rotary_named: str = ""  # the rotary letters the program has used, in "ABC" order
    canned: CannedCycle = field(default_factory=CannedCycle)
    reference_assumed: bool = False  # a G28/G30 went to machine zero for want of a machine config
    # The last G28/G30 intermediate point per axis (machine frame, NaN: never named), for G29.
    intermediate_mm: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    stopped: bool = False  # M0 / M1 seen in the last block
    ended: bool = False  # M2 / M30 seen
    tape_marks: int = 0  # '%' lines seen

    @property
    def spindle_rpm(self) -> float:
        """Signed spindle speed as in :class:`~planning.nc.Motion`: + M3, - M4, 0 stopped."""
        return self.spindle_dir * self.spindle_speed_rpm

    def copy(self) -> ModalState:
        """An independent snapshot (cheap: the mutable parts are copied, the rest is immutable)."""
        new = copy.copy(self)
        new.canned = copy.copy(self.canned)
        return new
