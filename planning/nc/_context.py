"""The interpreter's state object (private): the options every part of the interpreter reads, the
modal state and the per-block scratch they share, and how problems become errors or warnings.

:class:`Context` is built once by :class:`~planning.nc.interpreter.Interpreter` and handed to each
of its parts (words, modes, settings, moves, canned cycles, the fast path), which read and write
it explicitly (``ctx.state``, ``ctx.fail(...)``); none of them holds state of its own.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from planning.nc import _lexer
from planning.nc._codes import OFFSET_INDEX
from planning.nc.dialects import Dialect
from planning.nc.errors import NCError, NCWarning
from planning.nc.state import ModalState

if TYPE_CHECKING:
    from analysis.config import MachineConfig

NAN = math.nan
Codes = list[tuple[int, int]]  # a block's G or M codes: (key, index of the word)
Point = tuple[float, float, float]


class _FloatRow(Protocol):
    def extend(self, values: Iterable[float], /) -> None: ...


class _IntRow(Protocol):
    def extend(self, values: Iterable[int], /) -> None: ...


class Sink(Protocol):
    """Where segments go: a :class:`~planning.nc.motion.MotionBuilder` (18 floats and 6 ints a
    segment) or a stand-in that drops them."""

    @property
    def fbuf(self) -> _FloatRow: ...

    @property
    def ibuf(self) -> _IntRow: ...


@dataclass(slots=True, eq=False)  # slots: the hot path reads it per block
class Context:
    """What the interpreter's parts share: fixed options, the modal state, per-block scratch."""

    # ---- options (fixed for the interpreter's life)
    file: str
    strict: bool
    dialect: str
    rules: Dialect
    g_group: dict[int, int]  # G code key -> modal group, of this dialect
    known_m: frozenset[int]  # M numbers this dialect knows
    arc_tolerance_mm: float
    spiral_tol_mm: float | None  # LinuxCNC's spiral tolerance; None: its own default
    peck_clearance_mm: float
    peck_default: bool  # no peck clearance given: the dialect's (LinuxCNC: in program units)
    feed_max_mm_min: float
    spindle_max_rpm: float
    cutter_comp: str  # "warn" / "refuse"
    probing: str  # "allow" / "refuse"
    # ---- running state
    state: ModalState
    warnings: list[NCWarning] = field(default_factory=list)
    inverse_f: float = NAN  # this block's F under G93 (1/min)
    rotary_to: tuple[float, float, float] | None = None  # this block's A B C target, deg
    comp_warned: bool = False  # the G41/G42 warning is given once
    reference_warned: bool = False  # the "no G28/G30 point" warning is given once

    def problem(self, raw: str, index: int, reason: str, line: int) -> None:
        """Strict: raise; lenient: record a warning about word ``index`` of the block."""
        err = _lexer.word_error(raw, index, reason, self.file, line)
        if self.strict:
            raise err
        self.warn(err)

    def note(self, raw: str, letter_or_index: str | int, reason: str, line: int) -> None:
        """A warning in both modes (the block is still executed as written)."""
        self.warn(self.fail(raw, letter_or_index, reason, line))

    def warn(self, err: NCError) -> None:
        self.warnings.append(NCWarning(err.reason, err.file, err.line, err.column, err.word))

    def fail(self, raw: str, letter_or_index: str | int, reason: str, line: int) -> NCError:
        """The error about a word of the block (by letter or by index), to raise."""
        idx = letter_or_index
        if isinstance(idx, str):
            idx = _lexer.find_word(raw, idx)
        return _lexer.word_error(raw, idx, reason, self.file, line)

    def word_error(self, raw: str, index: int, reason: str, line: int) -> NCError:
        """The error about word ``index`` of the block (no letter lookup), to raise."""
        return _lexer.word_error(raw, index, reason, self.file, line)


def set_origin(st: ModalState) -> None:
    """``st.origin_mm`` from the active work offset and the G92 offset."""
    w = st.work_offsets_mm[st.work_offset_index]
    g = st.g92_offset_mm
    st.origin_mm = (w[0] + g[0], w[1] + g[1], w[2] + g[2])


def set_tool_length_offset(st: ModalState, off: tuple[float, float, float]) -> None:
    """A new tool length offset: the tool tip does not move, so the current position (in
    program coordinates) changes by the offset's change."""
    old = st.tool_length_offset_mm
    if off != old:
        p = st.position_mm
        st.position_mm = (p[0] - (off[0] - old[0]), p[1] - (off[1] - old[1]),
                          p[2] - (off[2] - old[2]))  # fmt: skip
        st.tool_length_offset_mm = off


def start_state(
    machine: MachineConfig | None,
    state: ModalState | None,
    work_offsets_mm: Mapping[int | float, Sequence[float]] | None,
    reference_mm: Sequence[float] | None,
    second_reference_mm: Sequence[float] | None,
) -> ModalState:
    """The state an interpreter starts from: ``state`` (copied) or a new one, with the work
    offsets and the G28/G30 points of the options, else of the machine."""
    if reference_mm is None and machine is not None:
        reference_mm = machine.reference_point_mm
    if second_reference_mm is None and machine is not None:
        second_reference_mm = machine.second_reference_point_mm
    st = state.copy() if state is not None else ModalState()
    if work_offsets_mm:
        table = list(st.work_offsets_mm)
        for code, off in work_offsets_mm.items():
            key = round(float(code) * 10.0)
            if key not in OFFSET_INDEX:
                raise ValueError(f"work_offsets_mm: no work offset G{code}")
            table[OFFSET_INDEX[key]] = (float(off[0]), float(off[1]), float(off[2]))
        st.work_offsets_mm = tuple(table)
    # None: machine zero = work zero, said once in a warning when a G28/G30 needs it
    if reference_mm is not None and (state is None or st.reference_mm is None):
        st.reference_mm = _point(reference_mm)
    second = second_reference_mm if second_reference_mm is not None else reference_mm
    if second is not None and (state is None or st.second_reference_mm is None):
        st.second_reference_mm = _point(second)
    set_origin(st)
    return st


def _point(p: Sequence[float]) -> Point:
    return (float(p[0]), float(p[1]), float(p[2]))
