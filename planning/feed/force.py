"""Engagement of each cut piece from the Z-map, and its predicted peak force
(analysis.forces.endmill).

Private helper of :mod:`planning.feed.post` (the optional force limit and the force column of the
report, a step beyond seed 001).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from analysis.config import EndMill, EndMillCoefficients
from planning.stock import Simulation


class ForceModel:
    """Predicted peak force of each piece as a function of its feed (analysis.forces.endmill).

    Engagement from the Z-map: axial depth = the piece's deepest height drop, radial width =
    removed cross-section / depth (capped at the diameter), down milling. Pieces that remove
    nothing, or run with the spindle stopped, have no force (NaN).
    """

    def __init__(
        self, tool: EndMill, coef: EndMillCoefficients, sim: Simulation, rpm: NDArray
    ) -> None:
        self.tool, self.coef, self.rpm = tool, coef, rpm
        length = sim.piece_length_mm
        self.cutting = (sim.piece_removed_mm3 > 1e-9) & (length > 0) & (rpm > 0)
        c = self.cutting
        self.depth = np.clip(sim.piece_depth_mm[c], 1e-3, None)
        area = sim.piece_removed_mm3[c] / length[c]
        self.ae = np.clip(area / self.depth, 1e-3, tool.diameter_mm)

    def _peak(self, fz: NDArray) -> NDArray:
        from analysis.forces import EndMillCut, peak_force

        cut = EndMillCut.from_width(self.tool, fz, self.depth, self.ae, mode="down")
        return peak_force(self.tool, self.coef, cut, n_phi=90)

    def force_n(self, feed_mm_min: NDArray) -> NDArray:
        """Peak force per piece at the given feeds, N (NaN where not cutting)."""
        out = np.full(len(self.cutting), np.nan)
        c = self.cutting
        if c.any():
            fz = feed_mm_min[c] / (self.tool.flutes * self.rpm[c])
            out[c] = self._peak(np.maximum(fz, 1e-6))
        return out

    def feed_cap(self, limit_n: float) -> NDArray:
        """Feed per piece at which the peak force reaches ``limit_n``, mm/min (inf if none).

        The peak force grows with the feed per tooth (affine per edge, convex as a maximum), so
        a few secant steps from a small feed converge from below.
        """
        cap = np.full(len(self.cutting), np.inf)
        c = self.cutting
        if not c.any():
            return cap
        f0 = self._peak(np.full(c.sum(), 1e-4))
        lo = np.full(c.sum(), 1e-4)
        hi = np.full(c.sum(), 0.05)
        fh = self._peak(hi)
        for _ in range(6):
            slope = np.maximum((fh - f0) / (hi - lo), 1e-9)
            nxt = np.clip(lo + (limit_n - f0) / slope, 1e-6, 10.0)
            fn = self._peak(nxt)
            below = fn <= limit_n
            lo, f0 = np.where(below, nxt, lo), np.where(below, fn, f0)
            hi, fh = np.where(below, hi, nxt), np.where(below, fh, fn)
        fz = np.where(f0 <= limit_n, lo, 0.0)  # already above the limit at the smallest feed
        cap[c] = fz * self.tool.flutes * self.rpm[c]
        return cap
