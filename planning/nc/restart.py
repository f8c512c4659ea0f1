"""Restarting a program at block N: the preamble that re-creates the modal state there.

A DNC streamer resuming at block N sends ``restart_preamble(state_at_block(program, N))`` and then
blocks N, N+1, ... The preamble

1. sets units, plane, arc-centre mode, G94, work offset and G98/G99, cancelling cutter and
   length compensation and any canned cycle (and the path control mode when not G64 P0), then
   writes back the work offsets the program's G10 L2/L20 set (``G90 G10 L2 Pn``);
2. changes to the tool in the spindle (``T M6``) and preselects the next tool;
3. starts the spindle (``S M3/M4``) and sets the coolant;
4. rapids up to the safe Z (with ``G43 H`` when length compensation was on), turns the rotary axes
   the program has used (A/B/C) to their positions, then rapids to X Y, then down to Z (rapid, or
   ``G1`` at the feed with ``plunge_feed``);
5. re-establishes the feed, cutter compensation, distance mode (G90/G91), motion mode and, last,
   inverse-time feed G93 if it was on (the preamble's own moves run under G94; under G93 every
   feed move carries its F, so there is no modal feed to restore).

The position is wherever the blocks before N left the tool, including a G28/G30 return to the
reference point: it is written back in the work frame like any other position.

Positions are written in the program's frame: the state's work offsets and G92 offset
(``state.origin_mm``) unless ``work_offsets_mm`` is given. A restart while a G92 / G52 offset is
in force is refused: it was set relative to where the tool was, which the preamble cannot
re-create.

A restart inside a run of canned-cycle blocks is refused: re-establishing the cycle would drill a
hole where the tool stands. Restart at the block that starts the cycle instead. So is a restart
after a G28/G30 that was interpreted without a machine config (machine zero assumed): the
preamble would approach a position the real machine does not have.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from planning.nc._codes import INCH_MM
from planning.nc.errors import NCError
from planning.nc.program import NumberStyle
from planning.nc.state import ModalState


def restart_preamble(
    state: ModalState,
    *,
    safe_z_mm: float | None = None,
    style: NumberStyle | None = None,
    work_offsets_mm: Mapping[int | float, tuple[float, float, float]] | None = None,
    plunge_feed: bool = False,
) -> list[str]:
    """NC blocks (texts, no line ends) that bring a controller into ``state``.

    ``safe_z_mm`` is the machine-frame Z from which X/Y are approached, default
    ``max(state Z, 0)``. Positions are written in the state's units and work frame
    (``work_offsets_mm`` subtracted, default the state's ``origin_mm``), with ``style`` (default
    4 decimals).
    """
    _refuse_restart(state)
    fmt = (style or NumberStyle()).format
    scale = 1.0 / INCH_MM if state.inch else 1.0
    if work_offsets_mm is None:
        off = state.origin_mm
    else:
        off = work_offsets_mm.get(state.work_offset, (0.0, 0.0, 0.0))
    x, y, z = (c - o for c, o in zip(state.position_mm, off))
    safe = max(z, 0.0) if safe_z_mm is None else safe_z_mm - off[2]
    out = [_modes_block(state, fmt, scale)]
    for idx in sorted(state.work_offsets_set):
        w = state.work_offsets_mm[idx]
        xyz = " ".join(f"{a}{fmt(c * scale)}" for a, c in zip("XYZ", w))
        out.append(f"G90 G10 L2 P{idx + 1} {xyz}")
    if state.tool:
        out.append(f"T{state.tool} M6")
    if state.tool_selected != state.tool:
        out.append(f"T{state.tool_selected}")
    if state.spindle_speed_rpm or state.spindle_dir:
        m = {1: " M3", -1: " M4", 0: " M5"}[state.spindle_dir]
        out.append(f"S{fmt(state.spindle_speed_rpm)}{m}")
    out.append("M8" if state.coolant else "M9")
    length = f" G43 H{state.tool_length_h}" if state.tool_length == 43 else ""
    if state.tool_length == 431:  # its own block: G43.1 takes the axis words
        tx, ty, tz = state.tool_length_offset_mm  # (not x, y, z: the restart position)
        xy = "".join(f"{c}{fmt(o * scale)} " for c, o in (("X", tx), ("Y", ty)) if o)
        out.append(f"G43.1 {xy}Z{fmt(tz * scale)}")
    out.append(f"G90 G0{length} Z{fmt(safe * scale)}")
    if state.rotary_named:  # turn the rotary axes at the safe height, before X Y
        out.append(
            " ".join(f"{c}{fmt(state.rotary_deg['ABC'.index(c)])}" for c in state.rotary_named)
        )
    out.append(f"X{fmt(x * scale)} Y{fmt(y * scale)}")
    feed = f"F{fmt(state.feed_mm_min * scale)}" if state.feed_mm_min == state.feed_mm_min else ""
    if plunge_feed and feed:
        out.append(f"G1 Z{fmt(z * scale)} {feed}")
    else:
        out.append(f"Z{fmt(z * scale)}")
        if feed:
            out.append(feed)
    if state.cutter_comp != 40:
        out.append(f"G{state.cutter_comp} D{state.cutter_comp_d}")
    last = ["G90" if state.absolute else "G91"]
    if state.motion != 0:
        last.append(f"G{state.motion}")
    if state.feed_mode == 93:
        last.append("G93")
    out.append(" ".join(last))
    return out


def _refuse_restart(state: ModalState) -> None:
    """States no preamble can bring a controller into."""
    if state.reference_assumed:
        raise NCError(
            "cannot restart after a G28/G30 interpreted without a machine config: the reference "
            "point (and so the position) is unknown; give the machine (reference_mm)"
        )
    if state.motion >= 81:
        raise NCError(
            f"cannot restart inside a canned cycle (G{state.motion} in force): restart at the "
            "block that starts the cycle"
        )
    if state.motion == 38:
        raise NCError(
            "cannot restart with a probe move mode (G38.x) in force: where the probe stopped is "
            "not known; restart at a block after the probing"
        )
    if any(state.g92_offset_mm):
        raise NCError(
            "cannot restart while a G92/G52 offset is in force: restart at or before the block "
            "that set it (or after a G92.1)"
        )


def _modes_block(state: ModalState, fmt: Callable[[float], str], scale: float) -> str:
    """The first block: the units, plane, distance and feed modes, work offset and path control
    of ``state`` (compensations and canned cycles cancelled)."""
    modes = [
        "G20" if state.inch else "G21",
        f"G{state.plane}",
        "G90.1" if state.arc_absolute else "G91.1",
        "G94",
        f"G{state.work_offset}",
        "G40",
        "G49",
        "G98" if state.retract_initial else "G99",
        "G80",
    ]
    if state.path_control != 64:
        modes.append(f"G{state.path_control}")
    elif state.path_tolerance_mm or state.naive_cam_tolerance_mm:
        p, q = state.path_tolerance_mm * scale, state.naive_cam_tolerance_mm * scale
        modes.append(f"G64 P{fmt(p)} Q{fmt(q)}")
    return " ".join(modes)
