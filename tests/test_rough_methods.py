"""Method options: Lee's second tool, the time objective, STL parts, the exact cusp model."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from test_rough_parts import bump_grid, load_toml, part_toml

from planning.nc import RAPID, motion_stats
from planning.rough import RoughPlan, RoughPlanner
from planning.rough.gcode import MoveSettings, plan_motion


@pytest.fixture(scope="module")
def bump_text():
    x, y, z = bump_grid(38, 42, 16, 24, 30)
    return x, y, z


def test_lee_with_a_smaller_second_tool(tmp_path, bump_text):
    x, y, z = bump_text
    same = RoughPlanner(load_toml(tmp_path, part_toml(x, y, z, top=43.0)))
    two = RoughPlanner(
        load_toml(tmp_path, part_toml(x, y, z, top=43.0, lee_second_tool="phi10-flat"), "b.toml")
    )
    a, b = same.plan_lee(), two.plan_lee()
    assert [lv.z_mm for lv in a.levels] == pytest.approx([lv.z_mm for lv in b.levels])
    second = [lv for lv in b.levels if lv.tool == 2]
    assert second and all(lv.paths.passes for lv in second)
    # A phi 10 tool steps over 7.5 mm instead of 15 mm: its levels need longer paths.
    assert sum(lv.path_mm for lv in second) > sum(lv.path_mm for lv in a.levels if lv.tool == 2)
    motion = plan_motion(b, two.part)
    assert set(np.unique(motion.tool)) == {1, 2}


def test_time_objective_cost_matches_the_moves(tmp_path, bump_text):
    x, y, z = bump_text
    pl = RoughPlanner(load_toml(tmp_path, part_toml(x, y, z, top=43.0, objective="time")))
    P = np.array([pl.bottom, 25.0, pl.top])
    lp = pl.geom.level(25.0, None)
    path = np.full((3, 3), np.inf)
    path[0, 1] = lp.path_mm
    n_closed = np.zeros((3, 3))
    n_closed[0, 1] = lp.n_closed
    n_pass = np.zeros((3, 3))
    n_pass[0, 1] = len(lp.passes)
    link = np.zeros((3, 3))
    link[0, 1] = lp.link_xy_mm
    cost_min = pl._cost_fn(P, path, n_closed, n_pass, link)(0, np.array([1]), 2)[0]
    # The same level as moves: drop the two moves from the interpreter's origin to the start.
    plan = RoughPlan("one", (pl._level(1, 25.0, None, pl.top),), pl.bottom, pl.top, 0.0)
    m = plan_motion(plan, pl.part)
    m = m[np.arange(2, len(m))]
    st = motion_stats(m, rapid_mm_min=pl.part.config.cutting.rapid_mm_min)
    # Rapids are timed by the longest axis in motion_stats and by xy distance in the cost.
    assert cost_min == pytest.approx(st.time_s / 60.0, rel=0.03)
    safe = MoveSettings.of(pl.part).safe_z_mm
    travel = (m.start[:, 2] >= safe - 1e-9) & (m.end[:, 2] >= safe - 1e-9)
    assert travel.any() and np.all(m.kind[travel] == RAPID)  # links only at the safe height


def test_time_objective_plan_is_no_slower_than_the_path_one(tmp_path, bump_text):
    x, y, z = bump_text
    kw = {"top": 43.0, "optimal_dh_mm": 2.0}
    t = RoughPlanner(load_toml(tmp_path, part_toml(x, y, z, objective="time", **kw)))
    p = RoughPlanner(load_toml(tmp_path, part_toml(x, y, z, **kw), "p.toml"))
    plan_t, plan_p = t.plan_optimal(), p.plan_optimal()
    rapid = t.part.config.cutting.rapid_mm_min

    def minutes(plan, pl):
        return motion_stats(plan_motion(plan, pl.part), rapid_mm_min=rapid).time_s / 60

    # Inter-level links are left out of the DP's cost: allow them as slack.
    assert minutes(plan_t, t) <= minutes(plan_p, p) * 1.02
    assert plan_p.path_mm <= plan_t.path_mm + 1e-6


@pytest.mark.long
def test_stl_part_plans(tmp_path):
    mesh = trimesh.creation.box(extents=(80, 80, 10))
    mesh.apply_translation((40, 40, 5))
    cap = trimesh.creation.icosphere(subdivisions=3, radius=30)
    cap.apply_translation((40, 40, 0))
    part_mesh = trimesh.util.concatenate([mesh, cap])
    part_mesh.export(tmp_path / "part.stl")
    x, y, z = bump_grid(40, 40, 20, 20, 10)
    text = part_toml(x, y, z, top=34.0, tool="phi10-flat")
    head, tail = text.split("[stock]")
    head = head.split("x_mm")[0].replace('kind = "height_field"', 'kind = "stl"')
    text = head + 'file = "part.stl"\nspacing_mm = 2.0\n[stock]' + tail
    pl = RoughPlanner(load_toml(tmp_path, text))
    assert pl.cusps.z_top_mm == pytest.approx(31.0, abs=0.1)  # sphere top 30 + allowance 1
    plan = pl.plan_bisection()
    assert plan.levels and plan.max_cusp_mm <= 5.0 + 1e-9


def test_exact_cusp_model_is_at_least_the_papers_on_a_dome(tmp_path, bump_text):
    x, y, z = bump_text
    paper = RoughPlanner(load_toml(tmp_path, part_toml(x, y, z, top=43.0)))
    exact = RoughPlanner(
        load_toml(tmp_path, part_toml(x, y, z, top=43.0, cusp_model="exact"), "e.toml")
    )
    # On the convex top the surface falls away from its tangent plane: the measured leftover
    # exceeds the tangent-plane estimate (h1 - h2) cos(beta).
    top = paper.cusps.z_top_mm
    lo, hi = top - 8, top - 2
    assert exact.cusp(lo, hi) >= paper.cusp(lo, hi) - 1e-6
    assert math.isfinite(exact.plan_bisection().max_cusp_mm)
