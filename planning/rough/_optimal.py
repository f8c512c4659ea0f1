"""The optimal planner's interval dynamic programme (planning.rough.planner.RoughPlanner
.plan_optimal): the cost of a level between candidate heights."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

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
