"""Restarting a program at block N: the preamble that re-creates the modal state there.

A DNC streamer resuming at block N sends :func:`restart_preamble` of
:func:`~planning.nc.state_at_block` (N), then blocks N, N+1, ... The preamble sets units, plane,
distance modes, feed mode, work offset, compensation records, tool, spindle, coolant and feed, then
moves to the position: first X Y at a safe Z (rapid), then down to Z (rapid, or at feed when
``plunge_feed`` is set).
"""

from __future__ import annotations

from planning.nc.program import NumberStyle
from planning.nc.state import ModalState

INCH_MM = 25.4


def restart_preamble(
    state: ModalState,
    *,
    safe_z_mm: float | None = None,
    style: NumberStyle | None = None,
    work_offsets_mm: dict[int, tuple[float, float, float]] | None = None,
    plunge_feed: bool = False,
) -> list[str]:
    """NC blocks (texts) that bring a controller from power-on into ``state``.

    ``safe_z_mm`` (machine frame, mm) is where X/Y are approached from; default the state's own Z
    when it is higher than 0, else 0... i.e. ``max(z, 0)``. Positions are written in the state's
    units and work frame (``work_offsets_mm`` subtracted, default zero).
    """
    fmt = (style or NumberStyle()).format
    scale = 1.0 / INCH_MM if state.inch else 1.0
    off = (work_offsets_mm or {}).get(state.work_offset, (0.0, 0.0, 0.0))
    x, y, z = (c - o for c, o in zip(state.position_mm, off))
    safe = max(z, 0.0) if safe_z_mm is None else safe_z_mm - off[2]
    modes = [
        "G20" if state.inch else "G21",
        f"G{state.plane}",
        "G90.1" if state.arc_absolute else "G91.1",
        f"G{state.feed_mode}",
        f"G{state.work_offset}",
        "G40",
        "G49",
        "G98" if state.retract_initial else "G99",
        "G80",
    ]
    out = [" ".join(modes)]
    if state.tool:
        out.append(f"T{state.tool} M6")
    if state.tool_selected != state.tool:
        out.append(f"T{state.tool_selected}")
    if state.spindle_speed_rpm or state.spindle_dir:
        m = {1: " M3", -1: " M4", 0: " M5"}[state.spindle_dir]
        out.append(f"S{fmt(state.spindle_speed_rpm)}{m}")
    out.append("M8" if state.coolant else "M9")
    out.append(f"G90 G0 Z{fmt(safe * scale)}")
    out.append(f"X{fmt(x * scale)} Y{fmt(y * scale)}")
    if state.feed_mm_min == state.feed_mm_min:
        feed = f"F{fmt(state.feed_mm_min * scale)}"
    else:
        feed = ""
    if plunge_feed and feed:
        out.append(f"G1 Z{fmt(z * scale)} {feed}")
    else:
        out.append(f"Z{fmt(z * scale)}")
        if feed:
            out.append(feed)
    if state.cutter_comp != 40:
        out.append(f"G{state.cutter_comp} D{state.cutter_comp_d}")
    if state.tool_length == 43:
        out.append(f"G43 H{state.tool_length_h}")
    out.append("G90" if state.absolute else "G91")
    if state.motion in (1, 2, 3):
        out.append(f"G{state.motion}" if state.motion != 1 or feed else "G1")
    return out
