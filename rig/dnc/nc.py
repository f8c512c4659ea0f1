"""What the DNC link takes from ``planning.nc``: checking a program before it is sent, the modal
state at a block for a restart, and segment durations for the simulated controllers."""

from __future__ import annotations

import numpy as np

from analysis.config import MachineConfig
from planning.nc import ModalState, Motion, NCError, interpret, segment_time_s, state_at_block
from rig.dnc.errors import DncError


def nc_text(text: str) -> str:
    """The program with GRBL ``$`` lines (settings, ``$H``, ``$X``) blanked: they are sent as
    they are and are not NC, so the interpreter skips them; line numbers are kept."""
    if "$" not in text:
        return text
    return "\n".join("" if ln.lstrip().startswith("$") else ln for ln in text.splitlines())


def check_program(text: str, name: str, machine: MachineConfig | None = None) -> None:
    """Interpret the whole program; an NC error is a DncError naming file:line:column."""
    try:
        interpret(nc_text(text), machine, file=name)
    except NCError as exc:
        raise DncError(f"{exc} (nothing was sent)") from None


def modal_state_at(
    text: str, block: int, name: str, machine: MachineConfig | None = None
) -> ModalState:
    """The modal state in force just before ``block`` (0-based) executes."""
    try:
        return state_at_block(nc_text(text), block, machine, file=name)
    except NCError as exc:
        raise DncError(f"restart from block {block}: {exc} (nothing was sent)") from None


def segment_durations_s(motion: Motion, rapid_mm_min: float) -> np.ndarray:
    """Time (n,) each segment takes at its programmed feed, s: planning.nc's time model (feed
    moves length / feed, rapids the longest axis travel at ``rapid_mm_min``, dwells their time;
    no acceleration), so the simulated controllers run programs as ``cutlab nc`` times them."""
    return np.nan_to_num(segment_time_s(motion, rapid_mm_min=rapid_mm_min), nan=0.0)
