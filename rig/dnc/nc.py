"""What the DNC link takes from ``planning.nc``: checking a program before it is sent, the modal
state at a block for a restart, and segment durations for the simulated controllers."""

from __future__ import annotations

import numpy as np

from analysis.config import MachineConfig
from planning.nc import (
    DWELL,
    RAPID,
    ModalState,
    Motion,
    NCError,
    interpret,
    segment_length_mm,
    state_at_block,
)
from rig.dnc.errors import DncError


def check_program(text: str, name: str, machine: MachineConfig | None = None) -> None:
    """Interpret the whole program; an NC error is a DncError naming file:line:column."""
    try:
        interpret(text, machine, file=name)
    except NCError as exc:
        raise DncError(f"{exc} (nothing was sent)") from None


def modal_state_at(
    text: str, block: int, name: str, machine: MachineConfig | None = None
) -> ModalState:
    """The modal state in force just before ``block`` (0-based) executes."""
    try:
        return state_at_block(text, block, machine, file=name)
    except NCError as exc:
        raise DncError(f"restart from block {block}: {exc} (nothing was sent)") from None


def segment_durations_s(motion: Motion, rapid_mm_min: float) -> np.ndarray:
    """Time (n,) each segment takes at its programmed feed, s.

    Feed moves: path length / feed. Rapids: the longest axis travel at ``rapid_mm_min`` (each axis
    at full rapid, as a control moves them). Dwells: their dwell time. Acceleration is ignored.
    """
    length = segment_length_mm(motion)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(motion.kind == RAPID, 0.0, length / motion.feed_mm_min * 60.0)
    travel = np.abs(motion.end - motion.start).max(axis=1) if len(motion) else np.zeros(0)
    t = np.where(motion.kind == RAPID, travel / rapid_mm_min * 60.0, t)
    t = np.where(motion.kind == DWELL, motion.dwell_s, t)
    return np.nan_to_num(t, nan=0.0)
