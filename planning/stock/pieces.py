"""Moves cut in pieces: each linear move split into equal pieces no longer than a length, and
what each piece removed from the stock (:meth:`planning.stock.zmap.ZMap.cut_path` returns it)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planning.errors import PlanningError


@dataclass(frozen=True)
class PathCut:
    """What a sequence of linear moves removed, per piece and per move.

    Long moves are cut in pieces no longer than the requested piece length, in order, so the
    removed volume is known along each move (the feed post-processor splits blocks with it).

    Attributes
    ----------
    move : ndarray, shape (k,), int
        Index of the move each piece belongs to.
    start_mm, end_mm : ndarray, shape (k, 3), mm
        Tip positions at the ends of each piece.
    removed_mm3 : ndarray, shape (k,), mm^3
        Volume removed by each piece (given the stock left by everything before it).
    removed_per_move_mm3 : ndarray, shape (n,), mm^3
    """

    move: NDArray[np.intp]
    start_mm: NDArray[np.float64]
    end_mm: NDArray[np.float64]
    removed_mm3: NDArray[np.float64]
    removed_per_move_mm3: NDArray[np.float64]

    @property
    def length_mm(self) -> NDArray[np.float64]:
        """3-D length of each piece, mm."""
        length: NDArray[np.float64] = np.linalg.norm(self.end_mm - self.start_mm, axis=1)
        return length


def split_pieces(
    starts_mm: NDArray[np.float64], ends_mm: NDArray[np.float64], piece_mm: float
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Cut each move into equal pieces no longer than ``piece_mm`` (vectorised).

    Returns ``(move index (k,), piece starts (k, 3), piece ends (k, 3))``; zero-length moves give
    one piece.
    """
    starts = np.asarray(starts_mm, dtype=float).reshape(-1, 3)
    ends = np.asarray(ends_mm, dtype=float).reshape(-1, 3)
    n = len(starts)
    if not math.isfinite(piece_mm):
        return np.arange(n), starts, ends
    if not piece_mm > 0:
        raise PlanningError(f"piece_mm = {piece_mm}: must be > 0 (mm)")
    length = np.linalg.norm(ends - starts, axis=1)
    count = np.maximum(np.ceil(length / piece_mm - 1e-9), 1).astype(np.int64)
    move = np.repeat(np.arange(n), count)
    first = np.cumsum(count) - count
    k = np.arange(len(move)) - first[move]
    frac0 = (k / count[move])[:, None]
    frac1 = ((k + 1) / count[move])[:, None]
    d = (ends - starts)[move]
    p0 = starts[move] + frac0 * d
    p1 = np.where(frac1 >= 1.0, ends[move], starts[move] + frac1 * d)
    return move, p0, p1
