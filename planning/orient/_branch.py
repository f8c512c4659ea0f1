"""The solution branch of each CL point's inverse kinematics (planning.orient.kinematics): of
(tilt, C) and (-tilt, C + 180 deg), the sequence that moves the rotary axes least."""

from __future__ import annotations

import numpy as np


def solution_branches(t0: np.ndarray, c0: np.ndarray, rho: np.ndarray, a_lo: float,
                      a_hi: float, start_c_deg: float) -> np.ndarray:  # fmt: skip
    """The solution branch per point (0: (tilt, C), 1: (-tilt, C + 180)) that moves the rotary
    axes least over the whole program (Viterbi over the two branches; |d tilt| + |d C| with C
    the shorter way round; a branch outside the tilt limits is barred), so that a branch forced
    by a limit later on is taken from the start rather than flipped mid-path."""
    m = len(t0)
    if m == 0:
        return np.zeros(0, int)
    A = np.stack([t0, -t0], 1)
    C = np.stack([c0, c0 + 180.0], 1)
    for k in np.flatnonzero(rho < 1e-12):  # C free: carry the previous C through (no cost)
        C[k] = C[k - 1] if k else np.nan
    barred = (A < a_lo - 1e-9) | (A > a_hi + 1e-9)
    cost = np.where(barred[0], np.inf, np.abs(A[0]) + c_distance_deg(C[0], start_c_deg))
    back = np.zeros((m, 2), int)
    for i in range(1, m):
        dc = c_distance_deg(C[i][None, :], C[i - 1][:, None])
        step = np.abs(A[i][None, :] - A[i - 1][:, None]) + dc
        tot = cost[:, None] + step  # from branch (row) to branch (column)
        back[i] = np.argmin(tot, 0)
        cost = np.where(barred[i], np.inf, tot.min(0))
    out = np.zeros(m, int)
    out[-1] = int(np.argmin(cost))
    for i in range(m - 1, 0, -1):
        out[i - 1] = back[i, out[i]]
    return out


def c_distance_deg(c1: float | np.ndarray, c0: float | np.ndarray) -> np.ndarray:
    """|c1 - c0| the shorter way round, deg; 0 where either is NaN (C free)."""
    d: np.ndarray = np.abs((np.asarray(c1, float) - np.asarray(c0, float) + 180.0) % 360.0 - 180.0)
    return np.asarray(np.nan_to_num(d, nan=0.0))
