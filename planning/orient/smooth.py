"""A smooth orientation field: the per-point answers of the planner, pulled towards their
neighbours' tool axes inside the collision-free set and the lead/tilt limits.

Projected Gauss-Seidel smoothing: each sweep moves every point's axis to the weighted mean of its
own and its neighbours' axes (weight ``lam`` along the path, ``lam * cross`` to the points of the
same rank on the neighbouring paths; ``cross`` is 0 by default: on the impeller a pull across the
paths raised the largest jump along them from 1.8 to 5-7 deg), expressed as (alpha, beta) in the
point's frame and clipped to the limits. The move is kept only if it stays collision-free (eq 7
U = 0) with no local overcut (K - kappa >= margin), else half of it, else none. The points that
moved are gated on the dense check mesh at the end; one that fails goes back to its planner
answer. The tool axis can only turn with the surface within the lead/tilt band, so where the
surface itself turns fast between two CC points (the mask's nose: 50 deg in 6.4 mm) the jump
left is the part's; the refinement of :mod:`planning.orient.between` inserts CC points there.
"""

from __future__ import annotations

import time

import numpy as np

from planning.orient._energy import Site
from planning.orient._search import _Context, _free
from planning.orient.planner import CCPoints, OrientResult, assemble
from planning.orient.tool import tool_axis


def angles_of(axis: np.ndarray, b: np.ndarray, f: np.ndarray, n: np.ndarray) -> np.ndarray:
    """(alpha, beta) rad, shape (..., 2), of unit axes in the frames (b, f, n): the inverse of
    :func:`planning.orient.tool.tool_axis` (u . f = sin alpha, u . n = cos alpha cos beta)."""
    alpha = np.arcsin(np.clip((axis * f).sum(-1), -1.0, 1.0))
    beta = np.arctan2(-(axis * b).sum(-1), (axis * n).sum(-1))
    return np.stack([alpha, beta], -1)


def neighbour_edges(cc: CCPoints, cross: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Directed edges (i, j, weight) between neighbours: 1 along a line, ``cross`` between the
    points of equal rank (by the feed parameter) on neighbouring lines of equal length."""
    I, J, W = [], [], []
    same = cc.line[1:] == cc.line[:-1]
    k = np.flatnonzero(same)
    I += [k, k + 1]
    J += [k + 1, k]
    W += [np.ones(len(k)), np.ones(len(k))]
    lines = np.unique(cc.line)
    ranked = []
    for ln in lines:
        idx = np.flatnonzero(cc.line == ln)
        feed_par = cc.u[idx] if np.ptp(cc.u[idx]) >= np.ptp(cc.v[idx]) else cc.v[idx]
        ranked.append(idx[np.argsort(feed_par)])
    if cross > 0:
        for a, b in zip(ranked[:-1], ranked[1:]):
            if len(a) == len(b):
                I += [a, b]
                J += [b, a]
                W += [np.full(len(a), cross)] * 2
    return np.concatenate(I), np.concatenate(J), np.concatenate(W)


def smooth_result(
    ctx: _Context, res: OrientResult, sweeps: int = 4, lam: float = 50.0, cross: float = 0.0
) -> OrientResult:
    """The smoothed field of a fully feasible ``res`` (see the module docstring); the time it
    takes is shared out over the points' ``seconds``."""
    t0 = time.perf_counter()
    e0 = ctx.evals
    cc = res.cc
    th0 = np.radians(np.stack([res.alpha_deg, res.beta_deg], 1))
    th = th0.copy()
    I, J, W = neighbour_edges(cc, cross)
    order = np.argsort(I, kind="stable")
    I, J, W = I[order], J[order], W[order]
    start = np.searchsorted(I, np.arange(len(th) + 1))
    u = tool_axis(th[:, 0], th[:, 1], cc.binormal, cc.feed, cc.normal)
    lo, hi = ctx.bounds[:, 0], ctx.bounds[:, 1]
    kappa = cc.kappa_per_mm
    sites = [Site(cc.point[i], cc.normal[i], cc.binormal[i], cc.feed[i]) for i in range(len(th))]
    for _ in range(sweeps):
        moved = 0
        for i in range(len(th)):
            s, e = start[i], start[i + 1]
            t = u[i] + lam * (W[s:e, None] * u[J[s:e]]).sum(0)
            t /= np.linalg.norm(t)
            tgt = np.clip(angles_of(t, cc.binormal[i], cc.feed[i], cc.normal[i]), lo, hi)
            if np.abs(tgt - th[i]).max() < 1e-4:
                continue
            for cand in (tgt, 0.5 * (th[i] + tgt)):
                if _free(ctx, sites[i], float(kappa[i]), cand):
                    th[i] = cand
                    u[i] = tool_axis(cand[0], cand[1], cc.binormal[i], cc.feed[i], cc.normal[i])
                    moved += 1
                    break
        if not moved:
            break
    clr = res.clearance_mm.copy()
    for k in np.flatnonzero(np.abs(th - th0).max(1) > 0):
        gate = ctx.gate(sites[k], th[k])
        if gate.ok:
            clr[k] = gate.min_mm
        else:
            th[k] = th0[k]
    share = (time.perf_counter() - t0) / len(th)
    nev = res.evaluations + (ctx.evals - e0) // len(th)
    return assemble(ctx, cc, th, res.energy, clr, res.reasons, res.seconds + share, nev)
