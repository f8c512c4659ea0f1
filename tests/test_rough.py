"""Z-level roughing (seed 000 2.4-2.5): passes, MRR, bisection, baselines, optimal planner."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import MultiLineString
from test_rough_parts import load_toml, part_toml

from planning.rough.planner import RoughPlanner, mrr_mm3_min

CONE_H, CONE_K = 70.0, 0.5


def cone_part(tmp_path: Path, **rough) -> RoughPlanner:
    """A cone z = 70 - 0.5 rho centred on a 100 x 100 stock, 72 mm high."""
    x = np.linspace(0, 100, 21)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    z = CONE_H - CONE_K * np.hypot(gx - 50, gy - 50)
    return RoughPlanner(load_toml(tmp_path, part_toml(x, x, z, top=72.0, **rough)))


@pytest.fixture(scope="module")
def cone(tmp_path_factory) -> RoughPlanner:
    return cone_part(tmp_path_factory.mktemp("cone"))


def offset_rho(planner: RoughPlanner, z: float) -> float:
    """Radius of the offset cone's section at z (closed form, see test_contours)."""
    d = planner.rough.finish_allowance_mm
    return (CONE_H + d * math.sqrt(1 + CONE_K**2) - z) / CONE_K


def test_mrr_is_area_feed_height_over_path():
    assert mrr_mm3_min(7039.85, 300.0, 25.5, 632.99) == pytest.approx(
        7039.85 * 300.0 * 25.5 / 632.99
    )
    assert mrr_mm3_min(100.0, 300.0, 5.0, 0.0) == 0.0


def test_level_area_and_passes_against_the_cone(cone):
    z = 50.0
    lv = cone._level(1, z, None, cone.top)
    rho = offset_rho(cone, z)
    assert lv.area_mm2 == pytest.approx(100 * 100 - math.pi * rho**2, rel=2e-3)
    assert lv.mrr_mm3_min == pytest.approx(lv.area_mm2 * 300.0 * (72.0 - z) / lv.path_mm)
    r = cone.geom.r
    rings = [p.ring for p in lv.paths.passes]
    assert rings == sorted(rings, reverse=True)  # outside in
    for p in lv.paths.passes:
        # Every pass lies on the reference contour offset by r + 1.5 r k.
        radius = np.hypot(p.xy_mm[:, 0] - 50, p.xy_mm[:, 1] - 50)
        assert np.abs(radius - (rho + r + 1.5 * r * p.ring)).max() < 0.03
        if p.closed:  # climb with M3: the part on the right, so clockwise round it
            area2 = np.sum(p.xy_mm[:-1, 0] * p.xy_mm[1:, 1] - p.xy_mm[1:, 0] * p.xy_mm[:-1, 1])
            assert area2 < 0
    swept = MultiLineString([p.xy_mm for p in lv.paths.passes]).buffer(r)
    region = cone.geom.region(z, None)
    assert region.difference(swept).area < 1e-3 * region.area  # the passes clear the region


def test_region_between_two_levels_is_the_annulus(cone):
    lo, z = 50.0, 58.0
    area = cone.geom.region(z, lo).area
    assert area == pytest.approx(math.pi * (offset_rho(cone, lo) ** 2 - offset_rho(cone, z) ** 2),
                                 rel=2e-3)  # fmt: skip


def test_paper_cusp_on_a_cone_is_height_times_cos_beta(cone):
    cos_b = 1 / math.sqrt(1 + CONE_K**2)
    assert cone.cusp(40.0, 50.0) == pytest.approx(10 * cos_b, abs=2e-3)
    assert cone.cusp(60.0, 61.5) == pytest.approx(1.5 * cos_b, abs=2e-3)


def test_bisection_follows_the_paper_rules(cone):
    plan = cone.plan_bisection()
    h_c, dh, L = cone.rough.cusp_mm, cone.rough.dh_mm, cone.L
    assert plan.max_cusp_mm <= h_c + 1e-9
    cut: list[float] = []
    for lv in plan.levels:
        lo = cone.bottom if lv.lo_mm is None else lv.lo_mm
        # The shoulder a level splits is bounded by levels cut before it (or bottom / top).
        assert lv.lo_mm is None or lv.lo_mm in cut
        assert lv.hi_mm == cone.top or lv.hi_mm in cut
        assert not any(lo < c < lv.hi_mm for c in cut)
        assert lv.height_mm <= L + 1e-9
        c = cone.cusp(lv.lo_mm, lv.hi_mm)
        assert c > h_c
        if c < 2 * h_c:  # halved
            assert lv.z_mm == pytest.approx(max((lo + lv.hi_mm) / 2, lv.hi_mm - L))
        else:  # on the candidate grid, with the highest MRR of all candidates
            k = (lv.z_mm - lo - h_c) / dh
            assert k == pytest.approx(round(k), abs=1e-6) and k >= -1e-9
            cands = lo + h_c + dh * np.arange(int((lv.hi_mm - h_c - lo - h_c) / dh + 1e-9) + 1)
            cands = cands[lv.hi_mm - cands <= L + 1e-9]
            mrr = []
            for zc in cands:
                p = cone.geom.level(float(zc), lv.lo_mm)
                mrr.append(mrr_mm3_min(p.area_mm2, 300.0, lv.hi_mm - zc, p.path_mm))
            assert lv.mrr_mm3_min == pytest.approx(max(mrr))
        cut.append(lv.z_mm)


def test_optimal_equals_brute_force_over_every_plan(tmp_path):
    planner = cone_part(tmp_path, cusp_mm=8.0)
    cands = [40.0, 47.0, 52.0, 58.0, 64.0]
    best = planner.plan_optimal(candidates_mm=cands)
    bottom, top, h_c, L = planner.bottom, planner.top, 8.0, planner.L

    def cost_of(order):
        cut, total = [], 0.0
        for z in order:
            lo = max([c for c in cut if c < z], default=None)
            hi = min([c for c in cut if c > z], default=top)
            if hi - z > L:
                return math.inf
            total += planner.geom.level(z, lo).path_mm
            cut.append(z)
        edges = [bottom, *sorted(cut), top]
        if any(planner.cusps.cusp(a, b) > h_c + 1e-9 for a, b in zip(edges[:-1], edges[1:])):
            return math.inf
        return total

    brute = min(
        cost_of(order)
        for n in range(len(cands) + 1)
        for subset in itertools.combinations(cands, n)
        for order in itertools.permutations(subset)
    )
    assert math.isfinite(brute)
    assert best.path_mm == pytest.approx(brute, rel=1e-9)


def test_equal_and_lee_baselines(cone):
    eq = cone.plan_equal()
    heights = [lv.z_mm for lv in eq.levels]
    assert np.allclose(np.diff(heights), -cone.rough.cusp_mm)
    assert all(lv.lo_mm is None for lv in eq.levels)  # the whole stock section each time
    assert eq.max_cusp_mm <= cone.rough.cusp_mm + 1e-9
    lee = cone.plan_lee()
    first = [lv for lv in lee.levels if lv.lo_mm is None and lv.height_mm == pytest.approx(15.0)]
    assert first, "Lee's first tool cuts 3 x cusp steps"
    assert lee.max_cusp_mm <= cone.rough.cusp_mm + 1e-9


def test_cusp_polygon_paths_stay_inside_the_stock_reach(cone):
    for lv in cone.plan_bisection().levels:
        reach = cone.geom.above(lv.lo_mm).buffer(cone.geom.r + 1e-6)
        for p in lv.paths.passes:
            assert shapely.contains_xy(reach, p.xy_mm[:, 0], p.xy_mm[:, 1]).all()


def test_check_cuts_arcs_along_the_arc_not_the_chord():
    """The independent Z-map check follows G2/G3 (a half turn of radius 20 at 2 mm depth with a
    phi 6 flat end mill removes the half annulus plus the two end half discs)."""
    from planning.nc import interpret
    from planning.rough.check import simulate

    text = "G21 G90 G17\nG0 Z5\nG0 X70 Y50\nG1 Z-2 F200\nG2 X30 Y50 I-20 J0\nG0 Z5\nM30\n"
    zm, removed, rapid = simulate(interpret(text), (0, 100, 0, 100, -10, 0), 3.0, 0.1, 5.0)
    R, r, d = 20.0, 3.0, 2.0
    closed = (0.5 * math.pi * ((R + r) ** 2 - (R - r) ** 2) + math.pi * r * r) * d
    assert removed == pytest.approx(closed, rel=0.01)
    assert rapid == 0.0
    assert zm.height_at(50.0, 30.0) == pytest.approx(-2.0)  # on the arc, far from its chord
    assert zm.height_at(50.0, 50.0) == pytest.approx(0.0)
