"""The shipped seed-000 part: the paper's claims, and the program checked on a Z-map."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from analysis.config import REPO_ROOT
from planning.nc import interpret, segment_length_mm
from planning.rough import RoughPlanner, check_program, load_part
from planning.rough.gcode import MoveSettings, plan_motion, plan_program, plan_totals

PART = REPO_ROOT / "configs" / "parts" / "seed000-bump.toml"


@pytest.fixture(scope="module")
def shipped():
    part = load_part(PART)
    planner = RoughPlanner(part)
    return part, planner, planner.plan_all()


def _check(part, planner, plan, spacing=1.0):
    st = part.config.stock
    return check_program(
        plan_program(plan, part).text(),
        planner.offset_surface,
        (st.x_min_mm, st.x_max_mm, st.y_min_mm, st.y_max_mm, st.z_min_mm, st.z_max_mm),
        part.tool.radius_mm,
        part.config.rough.cusp_mm,
        MoveSettings.of(part).safe_z_mm,
        spacing_mm=spacing,
    )


@pytest.mark.long
def test_shipped_part_is_what_the_issue_asks(shipped):
    part, planner, _ = shipped
    cfg = part.config
    assert part.tool.kind == "flat" and part.tool.diameter_mm == 20.0
    assert cfg.rough.cusp_mm == 5.0
    assert (cfg.cutting.feed_mm_min, cfg.cutting.spindle_rpm) == (300.0, 1000.0)
    # A bump whose slope differs by direction: the steepest slope along rays from the crest.
    surf = part.surface
    p, _ = surf.sample(4)
    crest = p.reshape(-1, 3)[np.argmax(p[..., 2])]
    assert crest[2] > 75
    rho = np.linspace(0.5, 45, 90)
    steepest = []
    for th in np.radians(np.arange(0, 360, 45)):
        z = surf.height_at(crest[0] + rho * np.cos(th), crest[1] + rho * np.sin(th))
        steepest.append(np.nanmax(-np.diff(z) / np.diff(rho)))
    assert max(steepest) / min(steepest) > 1.2
    # Convex (cap-shaped) around its crest: the Hessian there is negative definite.
    h = 2.0
    zc = surf.height_at(np.array([crest[0]]), np.array([crest[1]]))[0]
    for dx, dy in ((h, 0), (0, h), (h, h), (h, -h)):
        pair = surf.height_at(crest[0] + np.array([dx, -dx]), crest[1] + np.array([dy, -dy]))
        assert pair.sum() - 2 * zc < 0


def test_bisection_beats_equal_and_lee_and_optimal_beats_bisection(shipped):
    _, planner, plans = shipped
    path = {m: p.path_mm for m, p in plans.items()}
    assert 1 - path["bisection"] / path["equal"] >= 0.30  # paper: 34.4 %
    assert 1 - path["bisection"] / path["lee"] >= 0.10  # paper: 11.0 %
    assert path["optimal"] <= path["bisection"] + 1e-6
    for p in plans.values():
        assert p.max_cusp_mm <= planner.rough.cusp_mm + 1e-9
        assert all(lv.height_mm <= planner.L + 1e-9 for lv in p.levels)


@pytest.mark.parametrize("method", ["bisection", "optimal"])
def test_program_cut_on_a_zmap_leaves_at_most_the_cusp_and_never_gouges(shipped, method):
    part, planner, plans = shipped
    res = _check(part, planner, plans[method])
    assert res.max_gouge_mm <= 0.05
    assert res.rapid_removed_mm3 == 0.0
    assert res.max_left_mm <= part.config.rough.cusp_mm + 0.05
    assert res.ok


def test_the_check_catches_a_missing_level(shipped):
    # Fault injected: drop one level of the bisection plan; the shoulder left is then thicker
    # than the cusp limit, and the check must say so.
    part, planner, plans = shipped
    plan = plans["bisection"]
    faulty = replace(plan, levels=plan.levels[:-1])
    res = _check(part, planner, faulty)
    assert not res.ok
    assert res.max_left_mm > part.config.rough.cusp_mm + 0.5


def test_program_interprets_back_to_the_planned_moves(shipped):
    part, _, plans = shipped
    plan = plans["bisection"]
    motion = plan_motion(plan, part)
    back = interpret(plan_program(plan, part, motion).text())
    feed = back.is_feed  # lines and the fitted G2/G3 arcs
    length = segment_length_mm(back)[feed].sum()
    totals = plan_totals(plan, part, motion)
    assert length == pytest.approx(totals["feed_length_mm"], abs=0.5)
    # Cutting at the level heights only, plus the entry ramps/plunges above them.
    seg = np.linalg.norm(back.end - back.start, axis=1)
    flat = feed & (back.start[:, 2] == back.end[:, 2]) & (seg > 0.05)  # not a ramp's sliver
    z_flat = back.end[flat, 2]
    assert set(np.round(z_flat, 3)) <= {round(lv.z_mm, 3) for lv in plan.levels}
    assert np.all(back.spindle_rpm[feed] == 1000.0)
    assert np.all(back.feed_mm_min[feed] <= 300.0)
