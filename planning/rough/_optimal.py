"""The optimal planner's interval dynamic programme (planning.rough.planner.RoughPlanner
.plan_optimal): each level's paths between candidate heights, its cost, the programme over
intervals and the cutting order of its choice."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from planning.rough._levels import LevelGeometry
from planning.rough.part import Cutting, Rough

#: cost(a, cs, b): the costs of levels at candidate heights cs for lower a and upper b
LevelCost = Callable[[int, npt.NDArray[np.intp], int], npt.NDArray[np.float64]]


def level_cost_fn(
    r: Rough,
    c: Cutting,
    top_mm: float,
    P: npt.NDArray[np.float64],
    path: npt.NDArray[np.float64],
    n_closed: npt.NDArray[np.float64],
    n_pass: npt.NDArray[np.float64],
    link: npt.NDArray[np.float64],
) -> LevelCost:
    """cost(a, cs, b): vector of level costs for lower a, heights cs, upper b (path mm, or
    time s with ``r.objective = "time"``) below the stock top ``top_mm``."""
    if r.objective == "path":
        return lambda a, cs, b: path[a, cs]
    feed = c.feed_mm_min
    plunge = c.plunge_feed_mm_min or feed / 2
    rapid = c.rapid_mm_min
    safe = top_mm + r.clearance_mm
    sin_a = math.sin(math.radians(r.ramp_angle_deg))

    def cost(a: int, cs: npt.NDArray[np.intp], b: int) -> npt.NDArray[np.float64]:
        z = P[cs]
        enter = P[b] + r.clearance_mm - z
        n_open = n_pass[a, cs] - n_closed[a, cs]
        seconds: npt.NDArray[np.float64] = (
            path[a, cs] / feed
            + n_closed[a, cs] * enter / sin_a / feed
            + n_open * enter / plunge
            + n_pass[a, cs] * ((safe - z) + (safe - P[b] - r.clearance_mm)) / rapid
            + link[a, cs] / rapid
        )
        return seconds

    return cost


def level_stats(
    geom: LevelGeometry, P: npt.NDArray[np.float64], tick: Callable[[str], None]
) -> tuple[npt.NDArray[np.float64], ...]:
    """Per (lower a, height c) of the candidate heights ``P``: the level's path length, mm,
    its closed passes, all its passes, and its link moves' length, mm (inf, 0 where a >= c)."""
    n = len(P)
    path = np.full((n, n), np.inf)
    n_closed = np.zeros((n, n))
    n_pass = np.zeros((n, n))
    link = np.zeros((n, n))
    for c in range(1, n - 1):
        z = float(P[c])
        lo_ok = P[c] - P[:c] > 0
        for a_lo in np.flatnonzero(lo_ok):
            lp = geom.level(z, None if a_lo == 0 else float(P[a_lo]))
            path[a_lo, c] = lp.path_mm
            n_closed[a_lo, c] = lp.n_closed
            n_pass[a_lo, c] = len(lp.passes)
            link[a_lo, c] = lp.link_xy_mm
        tick(f"optimal: costs at height {c}/{n - 2}")
    return path, n_closed, n_pass, link


def solve_intervals(
    P: npt.NDArray[np.float64], need: npt.NDArray[np.bool_], cost: LevelCost, depth_mm: float
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int_]]:
    """f[a, b], the least cost of the shoulder between heights a and b (0 where ``need`` says
    its cusp is within the limit; inf where no level within ``depth_mm`` below b helps), and
    choice[a, b], the height cut first in it (-1: none)."""
    n = len(P)
    f = np.zeros((n, n))
    choice = np.full((n, n), -1, dtype=int)
    for span in range(2, n):
        for a in range(0, n - span):
            b = a + span
            if not need[a, b]:
                continue
            cs = np.arange(a + 1, b)
            cs = cs[P[b] - P[cs] <= depth_mm]
            if cs.size == 0:
                f[a, b] = np.inf
                continue
            tot = cost(a, cs, b) + f[a, cs] + f[cs, b]
            k = int(np.argmin(tot))
            f[a, b], choice[a, b] = tot[k], cs[k]
    return f, choice


def cut_order(choice: npt.NDArray[np.int_]) -> list[tuple[int, int, int]]:
    """The chosen levels as (lower, height, upper) indices in cutting order: a cut before the
    cuts inside its two new shoulders."""
    out: list[tuple[int, int, int]] = []
    todo: deque[tuple[int, int]] = deque([(0, len(choice) - 1)])
    while todo:
        a, b = todo.popleft()
        c = int(choice[a, b])
        if c < 0:
            continue
        out.append((a, c, b))
        todo.append((c, b))
        todo.append((a, c))
    return out
