"""Blocks other than a plain move (private): a G4 dwell, a group-0 code (G10, G28, G92 ...) and
axis words under a canned cycle or G80, checked for what cannot share the block and handed to
the part that executes them.

:class:`Blocks` is a part of :class:`~planning.nc.interpreter.Interpreter`: it works on the
interpreter's :class:`~planning.nc._context.Context` and dispatches to
:class:`~planning.nc._settings.Settings`, :class:`~planning.nc._moves.Moves` and
:class:`~planning.nc._cycles.Cycles`.
"""

from __future__ import annotations

from planning.nc._codes import gname
from planning.nc._context import Context, Sink
from planning.nc._cycles import Cycles
from planning.nc._moves import Moves
from planning.nc._settings import Settings

# codes that set something from the block's words (no motion): G10, G28.1, G30.1, G43.1 (group
# 8), G52, G92, G92.1, G92.2, G92.3
SETTING_CODES = frozenset({100, 281, 301, 431, 520, 920, 921, 922, 923})


class Blocks:
    """Dwell, group-0 and canned-cycle blocks of the Interpreter (a part: works on ``ctx``)."""

    def __init__(self, ctx: Context, settings: Settings, moves: Moves, cycles: Cycles) -> None:
        self.ctx = ctx
        self.settings = settings
        self.moves = moves
        self.cycles = cycles

    def dwell(
        self, raw: str, v: dict[str, str], line: int, block: int, out: Sink,
        explicit_motion: bool,
    ) -> None:  # fmt: skip
        """G4: the dwell (Fanuc / GRBL: alone; LinuxCNC: before the block's move)."""
        ctx = self.ctx
        if ctx.rules.dwell_then_move:
            if explicit_motion and ctx.state.motion in (2, 3):
                raise ctx.fail(raw, "P", "G4 and G2/G3 cannot share a block (both use P)", line)
        else:
            if "A" in v or "B" in v or "C" in v:
                raise ctx.fail(
                    raw, next(L for L in "ABC" if L in v), "A/B/C words cannot move in a G4 "
                    "block (program the rotary move in its own G0/G1 block)", line,
                )  # fmt: skip
            if "Y" in v or "Z" in v or ("X" in v and "P" in v):
                raise ctx.fail(
                    raw,
                    next(L for L in "YZX" if L in v),
                    "G4 dwell cannot share its block with a move",
                    line,
                )
        self.moves.dwell(raw, v, line, block, out)

    def group0(
        self, raw: str, v: dict[str, str], scale: float, line: int, block: int, out: Sink,
        home: tuple[int, int], has_axes: bool, explicit_motion: bool,
    ) -> None:  # fmt: skip
        """A block with G10, G28, G28.1, G29, G30, G30.1, G52 or a G92 code (``home``: its key
        and word index)."""
        ctx = self.ctx
        key, k = home
        mode = ctx.state.motion
        if key in SETTING_CODES:
            if has_axes and explicit_motion and mode != 80:
                raise ctx.word_error(
                    raw, k, f"{gname(key)} and G{mode} both use the axis words and cannot "
                    "share a block", line,
                )  # fmt: skip
            self.settings.setting(raw, v, scale, line, key, k)
            return
        if ctx.rotary_to is not None and not (ctx.rules.home_rotary and key != 290):
            raise ctx.fail(
                raw, next(L for L in "ABC" if L in v), f"A/B/C words cannot move in a "
                f"{gname(key)} block (program the rotary move in its own G0/G1 block)", line,
            )  # fmt: skip
        if explicit_motion and mode >= 81:
            raise ctx.word_error(raw, k, f"{gname(key)} and G{mode} cannot share a block", line)
        self.moves.home(raw, v, scale, line, block, out, key, k)

    def cycle(
        self, raw: str, v: dict[str, str], scale: float, line: int, block: int, out: Sink,
        rotary: bool,
    ) -> None:  # fmt: skip
        """A block with axis words under G80 (an error) or a canned cycle."""
        mode = self.ctx.state.motion
        if rotary:
            raise self.ctx.fail(
                raw, next(L for L in "ABC" if L in v), f"A/B/C words cannot move in a G{mode} "
                "block (program the rotary move in its own G0/G1 block)", line,
            )  # fmt: skip
        if mode == 80:
            raise self.ctx.fail(
                raw,
                next(L for L in "XYZABC" if L in v),
                "axis word with no motion mode in force (G80 cancelled it; program G0/G1)",
                line,
            )
        self.cycles.canned(raw, v, scale, line, block, out)
