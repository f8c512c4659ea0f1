"""Restart from block N: the safe preamble sent before block N.

The modal state in force just before block N is worked out by running ``planning.nc``'s
interpreter over blocks 0..N-1 (nothing is sent for them); :func:`planning.nc.restart_preamble`
writes it back as NC. What the preamble restores, in this order:

1. a comment ``(RESTART AT BLOCK N LINE L)``;
2. units G20/G21, plane G17/G18/G19, arc centre mode G90.1/G91.1, feed mode G94, work offset
   G54..G59, and G40 G49 G98/G99 G80 (compensation off, canned cycle cancelled);
3. the tool in the spindle (``T.. M6``) and the next tool selected (``T..``);
4. spindle speed and direction (``S.. M3/M4/M5``), coolant (M8 or M9);
5. a safe retract and rapid approach: ``G90 G0 Z<safe>``, then ``X.. Y..`` of the position before
   block N, then down to its Z at the feed (``G1 Z.. F..``), so the tool never rapids into stock;
6. cutter compensation G41/G42 with D, tool length G43 with H, if they were on;
7. distance mode G90/G91 and the motion mode G1/G2/G3, and the feed F.

Positions and feeds are written with 4 decimals in the units in force: exact to 0.1 um in mm,
to the control's 0.0001 in (at most 1.27 um off) in inch (tests/test_dnc_restart.py checks that
the preamble plus the rest moves like the whole program from block N).

``safe_z_mm`` is in mm, machine frame (the program frame: the controllers here apply no work
offsets); default the higher of the position's Z and 0.

Refused (a clear DncError, nothing sent): N past the end or after M2/M30; N inside a canned cycle
(G81..G83 modal: restart at the cycle's first block); for GRBL, a state that needs codes GRBL does
not take (cutter compensation, G43). For GRBL the preamble leaves out what GRBL rejects (G98/G99,
G90.1 and M6: the tool change is done by hand there; ``T..`` is kept).
"""

from __future__ import annotations

import re

from analysis.config import MachineConfig
from planning.nc import NCError, restart_preamble
from rig.dnc.errors import DncError
from rig.dnc.nc import modal_state_at
from rig.dnc.program import Program

_GRBL_DROP = re.compile(r"\b(G98|G99|G90\.1|M6)\b")


def restart_blocks(
    program: Program,
    block: int,
    protocol: str,
    machine: MachineConfig | None = None,
    safe_z_mm: float | None = None,
) -> list[str]:
    """The preamble blocks to send before ``program``'s block ``block`` (0-based)."""
    if block <= 0:
        return []
    state = modal_state_at(program.text, block, program.name, machine)
    where = f"{program.name}: restart at block {block} (line {block + 1})"
    if state.ended:
        raise DncError(f"{where}: the program ended (M2/M30) before that block")
    if protocol == "grbl" and (state.cutter_comp != 40 or state.tool_length == 43):
        raise DncError(
            f"{where}: needs G{state.cutter_comp}/G{state.tool_length} compensation, which GRBL "
            "does not take"
        )
    try:  # refusals of the preamble itself (canned cycle in force, unknown reference point)
        pre = restart_preamble(state, safe_z_mm=safe_z_mm, plunge_feed=True)
    except NCError as exc:
        raise DncError(f"{where}: {exc} (nothing was sent)") from None
    out = [f"(RESTART AT BLOCK {block} LINE {block + 1})"]
    for text in pre:
        if protocol == "grbl":
            text = " ".join(_GRBL_DROP.sub("", text).split())
            if not text:
                continue
        out.append(text)
    return out
