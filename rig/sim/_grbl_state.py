"""What the GRBL simulator's mixins (:mod:`rig.sim._grbl_lines`, :mod:`rig.sim._grbl_overrides`)
share with :class:`rig.sim.grbl.SimGrbl`, which sets it: declarations for the type checker (a
class body annotation without a value creates no attribute at run time), like
:class:`rig.sim._controller_exec.ControllerState` for the controller's own mixins."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

from planning.nc.grbl import GrblParser, GrblResult
from rig.sim._controller_exec import ExecutorMixin, _Planned
from rig.sim._grbl_report import StatusReport


@dataclass
class _Pending:
    """The line GRBL is busy with (out of the receive buffer, its answer not sent yet)."""

    k: int  # order among the g-code lines received
    res: GrblResult
    planned: _Planned | None
    stage: str  # "sync" (waits for the planner to empty) or "room" (waits for its answer)
    t: float


class GrblFields(ExecutorMixin):
    """Fields and hooks of SimGrbl (and SimControllerBase) that the GRBL mixins use."""

    # SimControllerBase's line and receive buffer
    rx_capacity: int
    fill: int
    # SimGrbl's
    line_numbers: bool
    planner_blocks: int
    hold_decel_s: float | None
    sim_error_at_block: tuple[int, int] | None
    sim_drop_ok_at_line: int | None
    sim_garble_ok_at_line: int | None
    sim_noise_at_line: int | None
    sim_reset_at_block: int | None
    settings: dict[int, float]
    grbl: GrblParser
    critical: bool
    _hold_done_at: float
    _spindle_prog: float
    _advanced_t: float
    _rx_lines: deque[tuple[bytes, float]]
    _partial: bytearray
    lines_received: int
    oks: int
    errors: list[tuple[int, str]]
    planner_waits: int
    ok_times_s: list[tuple[int, float]]
    _pending: _Pending | None
    _report: StatusReport
    feed_ovr: int
    rapid_ovr: int
    spindle_ovr: int
    _run_ovr: tuple[int, int, int]
    _ovr_due: deque[tuple[float, int, int, int]]

    if TYPE_CHECKING:
        # hooks SimControllerBase and SimGrbl define

        def _send(self, data: bytes) -> None: ...

        def _block_received(self) -> bool: ...

        def _next_wake(self, now: float) -> float: ...

        def _moving(self) -> bool: ...

        def state_name(self) -> str: ...

        def _programmed_mm_min(self, b: _Planned, i: int) -> float: ...
