"""The feed post-processor's options and result (:func:`planning.feed.post.post_process`): what
to cut and how, the sections of a program that changes tools, and the per-block table, times and
summary of the adjusted program."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from analysis.config import EndMill, EndMillCoefficients
from analysis.rules import FeedRule
from analysis.validation import JsonObject
from planning.errors import PlanningError
from planning.nc import Motion, Program
from planning.stock import ZMap
from planning.stock.machining import DEFAULT_CHORD_TOL_MM, Simulation

if TYPE_CHECKING:
    import pandas as pd

#: a per-piece feed cap: (simulation, rpm per piece) -> highest feed per piece, mm/min
FeedCap = Callable[[Simulation, NDArray[np.float64]], NDArray[np.float64]]


@dataclass(frozen=True)
class FeedPostOptions:
    """Settings of the post-processor.

    min_piece_mm : shortest block a split may create, mm
    split : split blocks where the load changes (else one feed per block)
    chord_tol_mm : chordal tolerance of arc linearisation in the simulation, mm
    check_holder : check holder and spindle nose against the stock
    force_limit_n : optional largest predicted peak force, N (needs ``coefficients``)
    coefficients : end-mill force coefficients (analysis.config.EndMillCoefficients)
    spindle_rpm : spindle speed for the force prediction when the program has none, rpm
    feed_step_mm_min : written feeds are floored to a multiple of this, mm/min
    feed_cap : optional f(simulation, rpm per piece) -> highest feed per piece, mm/min (the
        physical limits of planning.limits; the rule then works below the cap)
    """

    min_piece_mm: float = 5.0
    split: bool = True
    chord_tol_mm: float = DEFAULT_CHORD_TOL_MM
    check_holder: bool = True
    force_limit_n: float | None = None
    coefficients: EndMillCoefficients | None = None
    spindle_rpm: float | None = None
    feed_step_mm_min: float = 1.0
    feed_cap: FeedCap | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.min_piece_mm) and self.min_piece_mm > 0):
            raise PlanningError(f"min_piece_mm = {self.min_piece_mm}: must be > 0 (mm)")
        if not self.feed_step_mm_min > 0:
            raise PlanningError(f"feed_step_mm_min = {self.feed_step_mm_min}: must be > 0")
        if self.force_limit_n is not None:
            if not self.force_limit_n > 0:
                raise PlanningError(f"force_limit_n = {self.force_limit_n}: must be > 0 (N)")
            if self.coefficients is None:
                raise PlanningError(
                    "force_limit_n needs end-mill force coefficients (material [endmill] table)"
                )


@dataclass(frozen=True)
class Section:
    """One tool's run of a program that changes tools: segments ``lo:hi`` of its motion, cut by
    ``tool``; ``rule`` None leaves the section's feeds as programmed (a drill, a probe, a tool
    with no rule)."""

    lo: int
    hi: int
    tool: EndMill
    rule: FeedRule | None
    tool_number: int = 0
    tool_name: str = ""


@dataclass(frozen=True)
class BlockTable:
    """One row per block that has feed moves (arrays of equal length)."""

    block: NDArray[np.int64]
    line: NDArray[np.int64]
    length_mm: NDArray[np.float64]
    removed_mm3: NDArray[np.float64]
    load_pct: NDArray[np.float64]  # seed 001: over the whole block
    load_max_pct: NDArray[np.float64]  # most loaded piece
    feed_before_mm_min: NDArray[np.float64]
    feed_after_mm_min: NDArray[np.float64]  # slowest of the block's new feeds
    pieces: NDArray[np.int64]  # blocks it became (1 = not split)
    time_before_s: NDArray[np.float64]
    time_after_s: NDArray[np.float64]
    force_max_n: NDArray[np.float64] | None = None  # predicted peak force at the new feed, N

    def to_dataframe(self) -> pd.DataFrame:
        import pandas as pd

        cols = {k: getattr(self, k) for k in self.__dataclass_fields__}
        if cols["force_max_n"] is None:
            del cols["force_max_n"]
        return pd.DataFrame(cols)


@dataclass(frozen=True)
class FeedPostResult:
    """What the post-processor did; ``program`` is the adjusted program (not yet written)."""

    program: Program
    motion_before: Motion
    motion_after: Motion
    simulation: Simulation
    piece_load_pct: NDArray[np.float64]
    piece_feed_mm_min: NDArray[np.float64]
    piece_force_n: NDArray[np.float64]  # predicted peak force, N (NaN without coefficients)
    blocks: BlockTable
    time_before_s: float
    time_after_s: float
    split_blocks: int
    rule: FeedRule
    stock: ZMap
    notes: tuple[str, ...] = field(default=())
    # With the machine's acceleration (planning.nc.accel); None when the machine gives none.
    accel_time_before_s: float | None = None
    accel_time_after_s: float | None = None
    sections: tuple[Section, ...] = ()  # each tool's run (one for a one-tool program)

    @property
    def time_saved_pct(self) -> float:
        return 100.0 * (1.0 - self.time_after_s / self.time_before_s) if self.time_before_s else 0.0

    def load_rate_max(self) -> tuple[float, float]:
        """Highest cutting load per unit time (load % x feed, %.mm/min) before and after."""
        seg_feed = self.motion_before.feed_mm_min[self.simulation.piece_segment]
        before = np.nan_to_num(self.piece_load_pct * seg_feed)
        after = np.nan_to_num(self.piece_load_pct * self.piece_feed_mm_min)
        return float(before.max(initial=0.0)), float(after.max(initial=0.0))

    def summary(self) -> JsonObject:
        before, after = self.load_rate_max()
        bins = np.bincount(
            self.rule.bin_of(self.blocks.load_pct[self.blocks.removed_mm3 > 0]),
            minlength=self.rule.n_bins,
        )
        cutting = self.motion_before.is_feed[self.simulation.piece_segment]
        path = np.bincount(
            self.rule.bin_of(self.piece_load_pct[cutting]),
            weights=self.simulation.piece_length_mm[cutting],
            minlength=self.rule.n_bins,
        )
        return {
            "blocks": int(len(self.program)),
            "feed_blocks": int(len(self.blocks.block)),
            "split_blocks": self.split_blocks,
            "time_before_s": self.time_before_s,
            "time_after_s": self.time_after_s,
            "time_saved_pct": self.time_saved_pct,
            "accel_time_before_s": self.accel_time_before_s,
            "accel_time_after_s": self.accel_time_after_s,
            "removed_mm3": self.simulation.removed_total_mm3,
            "load_rate_max_before": before,
            "load_rate_max_after": after,
            "load_histogram": bins.tolist(),  # cutting blocks per rule bin (block loads)
            "load_histogram_path_mm": path.tolist(),  # feed path per rule bin (piece loads)
            "holder_contacts": [
                {"block": c.block, "line": c.line, "part": c.part, "overlap_mm": c.overlap_mm}
                for c in self.simulation.contacts
            ],
            "rapid_cut_blocks": [
                int(self.motion_before.block[i]) for i in self.simulation.rapid_cut_segments
            ],
            "notes": list(self.notes),
        }
