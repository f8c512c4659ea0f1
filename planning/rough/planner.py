"""Z-level roughing with one flat end mill: level heights by bisection (seed 000) and baselines.

Methods (all under the same cusp limit and the tool's depth limit L):

``bisection``  seed 000 2.5 exactly. The stock is one big shoulder (bottom of the offset surface,
               stock top). For a shoulder (lo, hi) whose largest cusp exceeds the allowed cusp:
               try candidates every dh from lo + h_cusp to hi - h_cusp (and no deeper than L below
               hi), cut the one of highest MRR = Area f h / l, and recurse into the two new
               shoulders, upper first. A shoulder whose cusp lies between 1x and 2x the allowance
               is simply halved; those are queued and halved after the MRR splits (this reproduces
               the order of the paper's Table 1). A shoulder under the allowance is done.
``equal``      the usual CAM way (Table 2): levels every h_cusp from the stock top down, each
               clearing the whole stock section.
``lee``        Lee's method as the paper describes it: levels every ``lee_factor`` x h_cusp from the
               top (first tool), then each new shoulder lowered to the allowance by levels every
               <= h_cusp cut in the shoulder only (second tool, default the same tool).
``optimal``    beyond the paper: the set of levels *and* their cutting order minimising the total
               cutting path (or time) subject to the same cusp and depth limits, by dynamic
               programming over intervals of candidate heights (a grid every ``optimal_dh_mm`` plus
               the heights the other methods chose, so its optimum is never worse than theirs).

A level's cost depends on its height z, the lower level lo of its shoulder (the region it clears
is A(lo) - C(z), see :mod:`planning.rough._levels`) and, for time, the upper level hi. Cutting a
level first inside a shoulder splits it into two independent shoulders, so the best plan of a
shoulder is ``f(lo, hi) = min_z cost(lo, z, hi) + f(lo, z) + f(z, hi)``, or 0 when its cusp is
already within the allowance.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from analysis.validation import JsonObject
from planning.errors import PlanningError
from planning.rough._levels import CuspTable, LevelGeometry, LevelPaths
from planning.rough._optimal import (
    LevelCost,
    cut_order,
    level_cost_fn,
    level_stats,
    solve_intervals,
)
from planning.rough.part import Part

METHODS = ("bisection", "equal", "lee", "optimal")
_EPS = 1e-9
#: work bounds: beyond them a plan would allocate gigabytes or run for hours, so the input is
#: refused naming the fields that set the count
MAX_CANDIDATES = 20_000  # candidate heights of one method (height / dh_mm)
MAX_OPTIMAL_CANDIDATES = 2_000  # the optimal planner's n x n tables (5 of them, 32 MB each)
MAX_OFFSETS = 2_000  # offset rings of one level (footprint / (step_factor x tool radius))
MAX_CONTOUR_POINTS = 2_000_000  # points of one contour (perimeter / contour_tolerance_mm)


@dataclass(frozen=True, eq=False)
class Level:
    """One cut level of a plan, in cutting order (the columns of seed 000 Table 1).

    z_mm: level height; lo_mm: lower level of its shoulder (None: the stock bottom, nothing cut
    below); hi_mm: upper level (or the stock top); area_mm2: area cleared; path_mm: cutting path in
    the area; mrr_mm3_min: Area x f x h / l; tool: 1 (first tool) or 2 (Lee's second tool);
    paths: the passes. ``row()`` also gives Area x h / l (mm^2, "mrr_per_path_mm2"): the numbers
    seed 000 Table 1 prints as "MMR/회 (mm^3)" are this, the MRR per unit feed (e.g. its level 1:
    7039.85 x (82 - 56.5) / 632.99 = 283.6 vs 285.78 printed; every row fits a stock top near 82 mm
    with h = the level above minus z).
    """

    order: int
    z_mm: float
    lo_mm: float | None
    hi_mm: float
    area_mm2: float
    path_mm: float
    mrr_mm3_min: float
    tool: int
    paths: LevelPaths = field(repr=False)

    @property
    def height_mm(self) -> float:
        return self.hi_mm - self.z_mm

    def row(self) -> JsonObject:
        return {
            "order": self.order,
            "z_mm": round(self.z_mm, 3),
            "area_mm2": round(self.area_mm2, 2),
            "path_mm": round(self.path_mm, 2),
            "height_mm": round(self.height_mm, 3),
            "mrr_mm3_min": round(self.mrr_mm3_min, 1),
            "mrr_per_path_mm2": round(self.area_mm2 * self.height_mm / self.path_mm, 2)
            if self.path_mm > 0
            else 0.0,
            "lo_mm": None if self.lo_mm is None else round(self.lo_mm, 3),
            "hi_mm": round(self.hi_mm, 3),
            "tool": self.tool,
        }


@dataclass(frozen=True, eq=False)
class RoughPlan:
    """Levels of one method in cutting order, and its shoulder cusps."""

    method: str
    levels: tuple[Level, ...]
    bottom_mm: float
    top_mm: float
    max_cusp_mm: float
    note: str = ""

    @property
    def path_mm(self) -> float:
        return float(sum(lv.path_mm for lv in self.levels))

    @property
    def heights_mm(self) -> list[float]:
        return sorted(lv.z_mm for lv in self.levels)


def mrr_mm3_min(area_mm2: float, feed_mm_min: float, height_mm: float, path_mm: float) -> float:
    """Seed 000 2.4.2: MRR = Area x f_r x h / l (mm^3/min); 0 for a level with no path."""
    if path_mm <= 0:
        return 0.0
    return area_mm2 * feed_mm_min * height_mm / path_mm


class RoughPlanner:
    """Plans the levels of one part by any of :data:`METHODS`.

    Builds the offset surface (finish allowance), the level geometry for the tool (and Lee's second
    tool) and the cusp table once; each ``plan_*`` method returns a :class:`RoughPlan`.
    """

    def __init__(self, part: Part, progress: Callable[[str], None] | None = None) -> None:
        cfg = part.config
        self.part = part
        self.rough = cfg.rough
        self.feed = cfg.cutting.feed_mm_min
        self._progress = progress
        st = cfg.stock
        self.stock_xy = (st.x_min_mm, st.x_max_mm, st.y_min_mm, st.y_max_mm)
        self.top = st.z_max_mm
        self.L = part.max_depth_mm
        self._check_inputs(part)
        self.offset_surface = part.surface.offset(self.rough.finish_allowance_mm)
        self._check_cover()
        self.geom = LevelGeometry(
            self.offset_surface,
            self.stock_xy,
            part.tool.radius_mm,
            self.rough.first_offset_factor,
            self.rough.step_factor,
            self.rough.contour_tolerance_mm,
        )
        if part.lee_tool is part.tool:
            self.geom2 = self.geom
        else:
            self.geom2 = LevelGeometry(
                self.offset_surface,
                self.stock_xy,
                part.lee_tool.radius_mm,
                self.rough.first_offset_factor,
                self.rough.step_factor,
                self.rough.contour_tolerance_mm,
                maker=self.geom.maker,
            )
        self.cusps = CuspTable(
            self.offset_surface,
            self.stock_xy,
            model=self.rough.cusp_model,
            contour=self.geom.contour_points,
        )
        self.bottom = self.cusps.z_bottom_mm
        if not self.top > self.bottom:
            raise PlanningError(
                f"{part.where}: stock.z_max_mm = {self.top} is not above the lowest point of the "
                f"offset surface ({self.bottom:.3f} mm): nothing to rough"
            )

    # --------------------------------------------------------------------------- input checks
    def _check_inputs(self, part: Part) -> None:
        w, r = part.where, self.rough
        st = part.config.stock
        size = min(st.x_max_mm - st.x_min_mm, st.y_max_mm - st.y_min_mm)
        d = part.tool.diameter_mm
        if d >= size:
            raise PlanningError(
                f"{w}: tool {part.config.tool.name} (diameter {d} mm) is larger than the part: "
                f"the stock is only {size} mm across; use a tool smaller than the part"
            )
        if r.cusp_mm < r.dh_mm:
            raise PlanningError(
                f"{w}: rough.cusp_mm = {r.cusp_mm} mm is smaller than what the levels can achieve: "
                f"levels are placed every rough.dh_mm = {r.dh_mm} mm, so the smallest cusp a flat "
                f"end mill can be held to is {r.dh_mm} mm (raise cusp_mm or lower dh_mm)"
            )
        if r.cusp_mm < 2 * r.contour_tolerance_mm:
            raise PlanningError(
                f"{w}: rough.cusp_mm = {r.cusp_mm} mm is below twice the contour tolerance "
                f"({r.contour_tolerance_mm} mm)"
            )
        if self.L < r.dh_mm:
            raise PlanningError(
                f"{w}: the tool's maximum depth L = {self.L} mm is below rough.dh_mm = {r.dh_mm} mm"
            )
        self._check_work(part)

    def _check_work(self, part: Part) -> None:
        """Refuse inputs whose plan would not finish: counts that scale with 1/spacing."""
        w, r, st = part.where, self.rough, part.config.stock
        height = st.z_max_mm - st.z_min_mm
        span = max(st.x_max_mm - st.x_min_mm, st.y_max_mm - st.y_min_mm)
        counts = (
            (height / r.dh_mm, MAX_CANDIDATES,
             f"stock height {height:g} mm / rough.dh_mm = {r.dh_mm}"),
            (height / r.optimal_dh_mm, MAX_OPTIMAL_CANDIDATES,
             f"stock height {height:g} mm / rough.optimal_dh_mm = {r.optimal_dh_mm}"),
            (span / (r.step_factor * part.tool.radius_mm), MAX_OFFSETS,
             f"stock span {span:g} mm / (rough.step_factor = {r.step_factor} x tool radius "
             f"{part.tool.radius_mm} mm)"),
            (4 * span / r.contour_tolerance_mm, MAX_CONTOUR_POINTS,
             f"stock perimeter {4 * span:g} mm / rough.contour_tolerance_mm = "
             f"{r.contour_tolerance_mm}"),
        )  # fmt: skip
        for n, limit, what in counts:
            if n > limit:
                raise PlanningError(
                    f"{w}: {what} gives {n:.3g} steps, more than {limit}: raise the spacing or "
                    "check the units (mm)"
                )

    def _check_cover(self) -> None:
        x0, x1, y0, y1 = self.part.surface.bounds_xy()
        sx0, sx1, sy0, sy1 = self.stock_xy
        tol = 1e-6
        if sx0 < x0 - tol or sx1 > x1 + tol or sy0 < y0 - tol or sy1 > y1 + tol:
            raise PlanningError(
                f"{self.part.where}: the stock footprint x {sx0}..{sx1}, y {sy0}..{sy1} mm is not "
                f"covered by the part surface (x {x0:.3f}..{x1:.3f}, y {y0:.3f}..{y1:.3f} mm)"
            )

    # ----------------------------------------------------------------------------- shared bits
    def _tick(self, msg: str) -> None:
        if self._progress is not None:
            self._progress(msg)

    def _level(self, order: int, z: float, lo: float | None, hi: float, tool: int = 1) -> Level:
        if hi - z > self.L + _EPS:
            raise PlanningError(
                f"{self.part.where}: level z = {z:.3f} mm cuts {hi - z:.3f} mm deep: over the "
                f"tool's maximum depth L = {self.L} mm"
            )
        if tool == 1:
            lp = self.geom.level(z, lo)
        else:
            lo_region = self.geom.above(lo)
            lp = self.geom2.level(z, lo, lo_region=lo_region)
        mrr = mrr_mm3_min(lp.area_mm2, self.feed, hi - z, lp.path_mm)
        return Level(order, z, lo, hi, lp.area_mm2, lp.path_mm, mrr, tool, lp)

    def cusp(self, lo: float | None, hi: float) -> float:
        return self.cusps.cusp(self.bottom if lo is None else lo, hi)

    def _max_cusp(self, heights: list[float]) -> float:
        edges = [self.bottom, *sorted(heights), self.top]
        return max(self.cusps.cusp(a, b) for a, b in zip(edges[:-1], edges[1:]))

    def split_level(self, plan: RoughPlan, index: int, parts: int) -> RoughPlan:
        """``plan`` with level ``index`` cut as ``parts`` equal sub-levels, top down, in its
        place (a depth limit: planning.limits). Each sub-level clears its shoulder's region at
        its height, A(lo) - C(z), under the material the one above left; the last is the
        level's own height, so every other level keeps its height, region and paths."""
        lv = plan.levels[index]
        step = lv.height_mm / parts
        subs, hi = [], lv.hi_mm
        for j in range(1, parts + 1):
            z = lv.z_mm if j == parts else lv.hi_mm - j * step
            subs.append(self._level(0, z, lv.lo_mm, hi, lv.tool))
            hi = z
        levels = [*plan.levels[:index], *subs, *plan.levels[index + 1 :]]
        levels = [replace(v, order=i + 1) for i, v in enumerate(levels)]
        note = (plan.note + "; " if plan.note else "") + (
            f"level z = {lv.z_mm:.3f} mm ({lv.height_mm:.3f} mm deep) split in {parts}"
        )
        return replace(plan, levels=tuple(levels), note=note)

    def plan_all(self) -> dict[str, RoughPlan]:
        """Every method on this part; optimal gets the others' heights as extra candidates."""
        out = {m: self.plan(m) for m in ("bisection", "equal", "lee")}
        extra = [h for m in ("bisection", "equal") for h in out[m].heights_mm]
        if self.geom2 is self.geom:
            extra += out["lee"].heights_mm
        out["optimal"] = self.plan_optimal(extra)
        return out

    def plan(self, method: str) -> RoughPlan:
        if method not in METHODS:
            raise PlanningError(f"method = {method!r}: expected one of {', '.join(METHODS)}")
        planners: dict[str, Callable[[], RoughPlan]] = {
            "bisection": self.plan_bisection,
            "equal": self.plan_equal,
            "lee": self.plan_lee,
            "optimal": self.plan_optimal,
        }
        return planners[method]()

    # ------------------------------------------------------------------------------ bisection
    def plan_bisection(self) -> RoughPlan:
        """Seed 000 2.5: MRR-maximising splits, halving between 1x and 2x, stop under 1x."""
        h_c, dh, L = self.rough.cusp_mm, self.rough.dh_mm, self.L
        levels: list[Level] = []
        halve: deque[tuple[float | None, float]] = deque()

        def split_mrr(lo: float | None, hi: float) -> None:
            c = self.cusp(lo, hi)
            if c <= h_c:
                return
            if c < 2 * h_c:
                halve.append((lo, hi))
                return
            lo_z = self.bottom if lo is None else lo
            n = int(math.floor((hi - h_c - (lo_z + h_c)) / dh + 1e-9))
            cands = lo_z + h_c + dh * np.arange(n + 1)
            cands = cands[hi - cands <= L + _EPS]
            if cands.size == 0:  # the depth limit rules out the band: cut as deep as allowed
                cands = np.array([hi - L])
            best, best_mrr = None, -1.0
            for z in cands:
                lp = self.geom.level(float(z), lo)
                m = mrr_mm3_min(lp.area_mm2, self.feed, hi - z, lp.path_mm)
                if m > best_mrr:
                    best, best_mrr = float(z), m
            assert best is not None  # cands is never empty, and every mrr is >= 0
            self._tick(f"bisection: level {best:.2f} mm in shoulder ({lo_z:.2f}, {hi:.2f})")
            levels.append(self._level(len(levels) + 1, best, lo, hi))
            todo.append((lo, best))
            todo.append((best, hi))  # popped first: upper shoulder first, as the paper's Table 1

        # depth first, upper shoulder first (the paper's Table 1 order), without recursion
        todo: list[tuple[float | None, float]] = [(None, self.top)]
        while todo:
            split_mrr(*todo.pop())
        while halve:
            lo, hi = halve.popleft()
            c = self.cusp(lo, hi)
            if c <= h_c:
                continue
            lo_z = self.bottom if lo is None else lo
            z = max(0.5 * (lo_z + hi), hi - L)
            levels.append(self._level(len(levels) + 1, z, lo, hi))
            halve.append((z, hi))
            halve.append((lo, z))
        return RoughPlan(
            "bisection",
            tuple(levels),
            self.bottom,
            self.top,
            self._max_cusp([lv.z_mm for lv in levels]),
        )

    # ------------------------------------------------------------------------------ baselines
    def _top_down(self, step: float) -> list[float]:
        """Levels every ``step`` from the stock top until the bottom shoulder is within limits."""
        out: list[float] = []
        z = self.top
        while True:
            z = z - step
            if z <= self.bottom + _EPS:
                break
            out.append(z)
            if self.cusp(None, z) <= self.rough.cusp_mm:
                break
        return out

    def plan_equal(self) -> RoughPlan:
        """Equal-interval levels every h_cusp (or L if smaller) from the stock top, top down."""
        step = min(self.rough.cusp_mm, self.L)
        heights = self._top_down(step)
        levels: list[Level] = []
        hi = self.top
        for z in heights:
            levels.append(self._level(len(levels) + 1, z, None, hi))
            hi = z
        return RoughPlan(
            "equal", tuple(levels), self.bottom, self.top, self._max_cusp(heights), f"step {step}"
        )

    def plan_lee(self) -> RoughPlan:
        """Lee's two-tool method: big steps (lee_factor x h_cusp) then each shoulder lowered."""
        h_c = self.rough.cusp_mm
        big = min(self.rough.lee_factor * h_c, self.L)
        primary = self._top_down(big)
        if not primary:
            primary = []
        levels: list[Level] = []
        hi = self.top
        for z in primary:
            levels.append(self._level(len(levels) + 1, z, None, hi, tool=1))
            hi = z
        lows: list[float | None] = [None, *sorted(primary)]
        for lo, top in zip(lows, [*sorted(primary), self.top]):
            lo_z = self.bottom if lo is None else lo
            if self.cusp(lo, top) <= h_c:
                continue
            n = max(1, math.ceil((top - lo_z) / h_c - 1e-9) - 1)
            step = (top - lo_z) / (n + 1)
            hi = top
            for j in range(1, n + 1):
                z = top - j * step
                levels.append(self._level(len(levels) + 1, z, lo, hi, tool=2))
                hi = z
        heights = [lv.z_mm for lv in levels]
        return RoughPlan(
            "lee", tuple(levels), self.bottom, self.top, self._max_cusp(heights), f"step {big}"
        )

    # -------------------------------------------------------------------------------- optimal
    def plan_optimal(
        self, extra_heights: list[float] | None = None, candidates_mm: list[float] | None = None
    ) -> RoughPlan:
        """Interval dynamic programme over candidate heights (see the module docstring).

        Candidates: every ``optimal_dh_mm`` above the bottom, plus ``extra_heights`` (default: the
        levels bisection, equal and Lee choose, so the optimum is never worse than theirs); or
        exactly ``candidates_mm`` when given.
        """
        r = self.rough
        P = self._optimal_candidates(extra_heights, candidates_mm)
        n = len(P)
        need = self.cusps.matrix(P) > r.cusp_mm + _EPS
        path, n_closed, n_pass, link = level_stats(self.geom, P, self._tick)
        cost = self._cost_fn(P, path, n_closed, n_pass, link)
        f, choice = solve_intervals(P, need, cost, self.L + _EPS)
        if not np.isfinite(f[0, n - 1]):
            raise PlanningError(
                "optimal: no set of levels meets the cusp limit within the depth limit "
                f"L = {self.L} mm on this candidate grid"
            )
        levels: list[Level] = []
        for a, c, b in cut_order(choice):
            lo = None if a == 0 else float(P[a])
            levels.append(self._level(len(levels) + 1, float(P[c]), lo, float(P[b])))
        heights = [lv.z_mm for lv in levels]
        return RoughPlan(
            "optimal",
            tuple(levels),
            self.bottom,
            self.top,
            self._max_cusp(heights),
            f"objective {r.objective}, {n - 2} candidates",
        )

    def _cost_fn(
        self,
        P: npt.NDArray[np.float64],
        path: npt.NDArray[np.float64],
        n_closed: npt.NDArray[np.float64],
        n_pass: npt.NDArray[np.float64],
        link: npt.NDArray[np.float64],
    ) -> LevelCost:
        """cost(a, cs, b): vector of level costs for lower a, heights cs, upper b (this part's
        :func:`planning.rough._optimal.level_cost_fn`)."""
        cut = self.part.config.cutting
        return level_cost_fn(self.rough, cut, self.top, P, path, n_closed, n_pass, link)

    def _optimal_candidates(
        self, extra_heights: list[float] | None, candidates_mm: list[float] | None
    ) -> npt.NDArray[np.float64]:
        """The optimal planner's heights, bottom and top included (see :meth:`plan_optimal`)."""
        if candidates_mm is not None:
            extra_heights = list(candidates_mm)
        elif extra_heights is None:
            extra_heights = []
            for m in ("bisection", "equal"):
                extra_heights += self.plan(m).heights_mm
            if self.geom2 is self.geom:
                extra_heights += self.plan_lee().heights_mm
        dh = self.rough.optimal_dh_mm
        grid = self.bottom + dh * np.arange(1, int((self.top - self.bottom) / dh) + 1)
        if candidates_mm is not None:
            grid = np.zeros(0)
        cands = np.unique(np.round(np.concatenate([grid, extra_heights]), 9))
        cands = cands[(cands > self.bottom + _EPS) & (cands < self.top - _EPS)]
        return np.concatenate([[self.bottom], cands, [self.top]])
