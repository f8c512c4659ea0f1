"""The modal state of an NC interpreter: everything a block inherits from the blocks before it.

:class:`ModalState` is a plain mutable dataclass that the :class:`~planning.nc.Interpreter` updates
block by block; ``state.copy()`` snapshots it (the simulated controllers keep one per buffered
block; the DNC streamer restarts from one). Codes are stored as their G/M numbers where that is
the clearest name (``plane`` 17/18/19, ``work_offset`` 54..59 or 59.1..59.3, ``motion``
0/1/2/3/80/81/82/83, ``path_control`` 61, 61.1, 64).

Positions are in mm in the machine frame the :class:`~planning.nc.Motion` arrays use, whatever
the program units; ``feed_mm_min`` likewise. A program position (what X Y Z words mean under G90)
plus ``origin_mm`` is the machine position; ``origin_mm`` is the active work offset (one of
``work_offsets_mm``, set by the interpreter's options or by G10 L2/L20) plus the G92 / G52 offset.
:func:`planning.nc.restart.restart_preamble` turns a state back into NC blocks.

The tables a program can write (work offsets, G92, G28/G30 points, tool table) are immutable
tuples or dicts that are replaced, never changed in place, so ``copy()`` stays cheap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from operator import attrgetter

_OFFSET_INDEX = {54: 0, 55: 1, 56: 2, 57: 3, 58: 4, 59: 5, 59.1: 6, 59.2: 7, 59.3: 8}


@dataclass(slots=True)
class CannedCycle:
    """Parameters of the active G81/G82/G83 drilling cycle (all mm / s, machine frame; Z is the
    drilling axis)."""

    r_mm: float = math.nan  # retract (R) plane, absolute Z
    z_mm: float = math.nan  # hole bottom, absolute Z
    q_mm: float = math.nan  # G83 peck depth (positive)
    dwell_s: float = 0.0  # G82 dwell at the bottom
    initial_z_mm: float = math.nan  # Z when the cycle started: the G98 return level (the
    # drilling axis: Z in G17, Y in G18, X in G19)
    mode: int = 0  # the cycle (81, 82, 83) of the last cycle block, 0 none yet
    # the words as written and the initial level in program units (LinuxCNC computes with them)
    r_number: float = math.nan
    z_number: float = math.nan
    q_number: float = math.nan
    initial_number: float = math.nan


@dataclass(slots=True)  # slots: fast attribute access for its 40-odd fields
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
    tool_length: int = 49  # G43 / G43.1 (431) / G49 (positions are the programmed tool tip)
    tool_length_h: int = 0  # H register
    # G43.1's offset (X Y Z, mm): setting it shifts the current position by the change, as
    # LinuxCNC and GRBL do (an incremental move after it shows it); G43 H and G49 set it to 0
    tool_length_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    work_offset: int | float = 54  # G54..G59, G59.1..G59.3 (59.1 ...)
    retract_initial: bool = True  # G98 (True) / G99 canned-cycle return level
    feed_mm_min: float = math.nan  # G94 F in mm/min; NaN until set and under G93
    feed_word: float = math.nan  # that F as written (LinuxCNC: the deg/min of rotary-only moves)
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
    path_control: int | float = 64  # G61 exact path, G61.1 exact stop, G64 blending (motion is
    # the programmed path whatever the mode)
    path_tolerance_mm: float = 0.0  # G64 P: blending tolerance (0: as fast as possible)
    naive_cam_tolerance_mm: float = 0.0  # G64 Q: collinear points merged within this
    # Work offsets G54..G59.3 (index 0..8), machine mm; the interpreter's options or G10 L2/L20.
    work_offsets_mm: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),) * 9
    work_offsets_set: frozenset[int] = frozenset()  # indices a G10 of the program has written
    g92_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)  # G92 / G52 offset in force
    g92_saved_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)  # what G92.3 restores
    origin_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)  # active work offset + G92 offset
    # G28 / G30 points (machine mm; None: unknown, machine zero is assumed with a warning);
    # from the machine config or the options, G28.1 / G30.1 store the current position
    reference_mm: tuple[float, float, float] | None = None
    second_reference_mm: tuple[float, float, float] | None = None
    reference_rotary_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)  # A B C of G28 (LinuxCNC)
    second_reference_rotary_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)  # of G30
    # G10 L1/L10/L11 tool table entries: tool -> (x, y, z offset, radius) mm (recorded only)
    tool_table: dict[int, tuple[float, float, float, float]] = field(default_factory=dict)
    reference_assumed: bool = False  # a G28/G30 went to machine zero for want of a machine config
    # The last G28/G30 intermediate point per axis (machine frame, NaN: never named), for G29.
    intermediate_mm: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    stopped: bool = False  # M0 / M1 seen in the last block
    ended: bool = False  # M2 / M30 seen
    tape_marks: int = 0  # '%' lines seen

    @property
    def work_offset_index(self) -> int:
        """Index of the active work offset in ``work_offsets_mm`` (G54 -> 0 ... G59.3 -> 8)."""
        return _OFFSET_INDEX[self.work_offset]

    @property
    def spindle_rpm(self) -> float:
        """Signed spindle speed as in :class:`~planning.nc.Motion`: + M3, - M4, 0 stopped."""
        return self.spindle_dir * self.spindle_speed_rpm

    def copy(self) -> ModalState:
        """An independent snapshot (cheap: the mutable parts are copied, the rest is immutable)."""
        new = ModalState(*_modal_fields(self))
        new.canned = CannedCycle(*_canned_fields(self.canned))
        return new


_modal_fields = attrgetter(*(f.name for f in fields(ModalState)))
_canned_fields = attrgetter(*(f.name for f in fields(CannedCycle)))
