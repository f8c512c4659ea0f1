"""How even can feed changes alone make the cutting force of a program?

A load-based post-processor (seed 001) changes only F words, within the [min, max] feed of its
rule. For a program made of steady cuts (each an axial depth, an engagement and a length), the
per-revolution force of each cut is a function of its feed alone, so the evenness the
post-processor can reach is bounded by the feed limits and the cutting time one accepts.

The bound is traced by one family of feed choices: every cut runs at the feed that gives it the
same per-revolution force T, clamped to [min, max] (a clamped cut keeps the force of its limit).
Sweeping T gives, for each cutting time, the least coefficient of variation this family reaches;
tests/test_evenness.py checks with a global optimiser over all feed combinations that no feeds do
measurably better (there is no closed-form proof that the family is optimal).

Statistics are over revolutions, as a per-revolution force record sees them: cut i contributes
``length_i / (feed_i / rpm)`` revolutions of force ``F_i(feed_i)``; its time is ``length_i /
feed_i``. Transitions between cuts are ignored (they are a few revolutions each). The force is
the revolution mean of the feed-plane resultant |(Fx, Fy)|, from :mod:`analysis.forces.endmill`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from analysis.config import EndMill, EndMillCoefficients
from analysis.errors import AnalysisError
from analysis.forces.endmill import EndMillCut, endmill_forces

__all__ = ["EvennessFront", "ForceTable", "SteadyCut", "feed_plane_force_n", "force_cv"]


@dataclass(frozen=True)
class SteadyCut:
    """A stretch of a program cut at one depth and engagement: ``length_mm`` of feed travel."""

    depth_mm: float
    length_mm: float
    entry_deg: float = 0.0
    exit_deg: float = 180.0


def feed_plane_force_n(
    tool: EndMill, coef: EndMillCoefficients, cut: SteadyCut, rpm: float,
    feeds_mm_min: np.ndarray, n_phi: int = 180,
) -> np.ndarray:  # fmt: skip
    """Revolution mean of |(Fx, Fy)| at each feed, N (shape of ``feeds_mm_min``)."""
    f = np.asarray(feeds_mm_min, dtype=float)
    fz = f / (abs(rpm) * tool.flutes)
    phi = np.linspace(0.0, 2 * np.pi, n_phi, endpoint=False).reshape((n_phi,) + (1,) * f.ndim)
    ec = EndMillCut(fz, cut.depth_mm, cut.entry_deg, cut.exit_deg)
    forces = endmill_forces(phi, tool, coef, ec)
    out: NDArray[np.float64] = np.hypot(forces[..., 0], forces[..., 1]).mean(axis=0)
    return out


def force_cv(
    force_n: np.ndarray, feeds_mm_min: np.ndarray, lengths_mm: np.ndarray, rpm: float
) -> tuple[np.ndarray, np.ndarray]:
    """(CV over revolutions, cutting time s) of cuts at ``feeds`` giving ``force_n``.

    The last axis runs over the cuts; leading axes are alternatives.
    """
    revs = np.asarray(lengths_mm, float) * abs(rpm) / np.asarray(feeds_mm_min, float)
    w = revs / revs.sum(axis=-1, keepdims=True)
    mean = (w * force_n).sum(axis=-1)
    std = np.sqrt((w * (force_n - mean[..., None]) ** 2).sum(axis=-1))
    time_s = (60.0 * np.asarray(lengths_mm, float) / feeds_mm_min).sum(axis=-1)
    return std / mean, time_s


@dataclass(frozen=True)
class EvennessFront:
    """The equal-force family: per level ``force_n`` (m,), feeds (m, k), CV (m,), time (m,)."""

    force_n: np.ndarray
    feeds_mm_min: np.ndarray
    cv: np.ndarray
    time_s: np.ndarray

    def least_cv(self, time_s: float) -> float:
        """Least CV reachable within ``time_s`` of cutting (inf if no feeds are fast enough)."""
        ok = self.time_s <= time_s * (1 + 1e-9)
        return float(self.cv[ok].min()) if ok.any() else float("inf")

    def least_time(self, cv: float) -> float:
        """Shortest cutting time, s, at which a CV of at most ``cv`` is reachable (inf if none)."""
        ok = self.cv <= cv
        return float(self.time_s[ok].min()) if ok.any() else float("inf")


@dataclass(frozen=True)
class ForceTable:
    """Per-revolution force of each cut (k,) over a feed grid (n,): ``force_n`` (k, n), N."""

    feeds_mm_min: np.ndarray
    force_n: np.ndarray
    lengths_mm: np.ndarray
    rpm: float

    @classmethod
    def build(
        cls, tool: EndMill, coef: EndMillCoefficients, cuts: list[SteadyCut], rpm: float,
        feed_lo_mm_min: float, feed_hi_mm_min: float, n_feeds: int = 160,
    ) -> ForceTable:  # fmt: skip
        if not cuts:
            raise AnalysisError("evenness: no cuts given (need at least one steady cut)")
        if not 0 < feed_lo_mm_min < feed_hi_mm_min:
            raise AnalysisError(
                f"evenness: feed range [{feed_lo_mm_min}, {feed_hi_mm_min}] mm/min: "
                "need 0 < low < high"
            )
        # A geometric grid: the force changes fastest, relatively, at low feeds.
        grid = np.geomspace(feed_lo_mm_min, feed_hi_mm_min, n_feeds)
        table = np.stack([feed_plane_force_n(tool, coef, c, rpm, grid) for c in cuts])
        if np.any(np.diff(table, axis=1) <= 0):
            raise AnalysisError(
                "evenness: the force does not rise with feed for every cut "
                "(check the cutting coefficients: K_tc, K_rc, K_ac must not all be 0 N/mm^2)"
            )
        return cls(grid, table, np.array([c.length_mm for c in cuts]), float(rpm))

    def force(self, feeds_mm_min: np.ndarray) -> np.ndarray:
        """Each cut's force at its feed (last axis over the cuts), N, interpolated."""
        f = np.asarray(feeds_mm_min, dtype=float)
        return np.stack(
            [np.interp(f[..., i], self.feeds_mm_min, row) for i, row in enumerate(self.force_n)],
            axis=-1,
        )

    def stats(self, feeds_mm_min: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(CV, cutting time s) of the cuts at ``feeds_mm_min`` (last axis over the cuts)."""
        f = np.asarray(feeds_mm_min, dtype=float)
        return force_cv(self.force(f), f, self.lengths_mm, self.rpm)

    def front(
        self, feed_min_mm_min: float, feed_max_mm_min: float, n_levels: int = 2000
    ) -> EvennessFront:
        """The equal-force family (module doc) within [feed_min, feed_max], inside the grid."""
        lo = max(feed_min_mm_min, self.feeds_mm_min[0])
        hi = min(feed_max_mm_min, self.feeds_mm_min[-1])
        if not lo < hi:
            raise AnalysisError(
                f"evenness: feed limits [{feed_min_mm_min}, {feed_max_mm_min}] mm/min leave no "
                f"room inside the table's [{self.feeds_mm_min[0]:g}, {self.feeds_mm_min[-1]:g}]"
            )
        # Levels over the whole table, whatever the limits: then raising the maximum feed only
        # adds choices, level by level, which max_feed_needed's bisection relies on.
        levels = np.linspace(self.force_n.min(), self.force_n.max(), n_levels)
        feeds = np.stack([np.interp(levels, row, self.feeds_mm_min) for row in self.force_n], -1)
        feeds = np.clip(feeds, lo, hi)
        cv, time_s = self.stats(feeds)
        return EvennessFront(levels, feeds, cv, time_s)

    def max_feed_needed(self, feed_min_mm_min: float, time_s: float, cv: float) -> float:
        """Least maximum feed, mm/min, at which a CV <= ``cv`` is reachable within ``time_s``
        (inf if not even at the top of the table). Raising the maximum only adds choices, so
        the answer is found by bisection."""
        def ok(fmax: float) -> bool:
            return self.front(feed_min_mm_min, fmax).least_cv(time_s) <= cv

        lo, hi = feed_min_mm_min, float(self.feeds_mm_min[-1])
        if not ok(hi):
            return float("inf")
        while hi - lo > 1.0:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if ok(mid) else (mid, hi)
        return hi
