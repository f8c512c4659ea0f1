"""The stepped test block of a campaign's cuts, analytic or as a Z-map stock.

Top face at the step tops, X from ``step_x_mm[0]`` to ``step_x_mm[-1]``, Y from ``y_min_mm`` to
``y_max_mm``. The campaign's programs cut it (:mod:`rig.campaign.programs`) and the simulated
machine removes it (:mod:`rig.sim.machine`), so it lives below both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.config import EndMill
from planning.stock.zmap import ZMap

ZMAP_SPACING_MM = 0.25  # grid of the simulated stock: 1/40 of the smallest test tool (phi 10)


@dataclass(frozen=True)
class SteppedBlock:
    """A test block with a stepped top (the workpiece of a campaign's test cut).

    ``step_x_mm`` (k+1,) are the X edges of k steps, ``step_top_mm`` (k,) their top Z, mm.
    """

    y_min_mm: float
    y_max_mm: float
    step_x_mm: tuple[float, ...]
    step_top_mm: tuple[float, ...]

    @property
    def x_min_mm(self) -> float:
        return self.step_x_mm[0]

    @property
    def x_max_mm(self) -> float:
        return self.step_x_mm[-1]

    def top_z(self, x_mm: np.ndarray, y_mm: np.ndarray) -> np.ndarray:
        """Top of the uncut block at (x, y), mm; -inf outside the block. Any matching shapes."""
        x = np.asarray(x_mm, dtype=float)
        y = np.asarray(y_mm, dtype=float)
        edges = np.asarray(self.step_x_mm)
        tops = np.append(np.asarray(self.step_top_mm), -np.inf)
        k = np.searchsorted(edges, x, side="right") - 1
        k = np.where((k < 0) | (k >= len(self.step_top_mm)), len(tops) - 1, k)
        inside = (y >= self.y_min_mm) & (y <= self.y_max_mm)
        return np.where(inside, tops[k], -np.inf)

    def to_zmap(self, tool: EndMill, spacing_mm: float = ZMAP_SPACING_MM) -> ZMap:
        """The block as a Z-map (one tool radius of margin around it; the material outside the
        block sits a flute length below its lowest step)."""
        r = tool.radius_mm
        s = spacing_mm
        x = np.arange(self.x_min_mm - r, self.x_max_mm + r, s) + s / 2
        y = np.arange(self.y_min_mm - r, self.y_max_mm + r, s) + s / 2
        xx, yy = np.meshgrid(x, y)
        top = self.top_z(xx, yy)
        bottom = min(self.step_top_mm) - tool.flute_length_mm
        heights = np.where(np.isfinite(top), top, bottom)
        return ZMap.from_heights(heights, x[0] - s / 2, y[0] - s / 2, s, bottom)
