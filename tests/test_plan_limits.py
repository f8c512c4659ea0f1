"""planning.limits: closed forms, the per-block check, and the --limit fixes (issue 22)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis.config import get_material, get_tool
from planning.errors import PlanningError
from planning.limits import Limits, check_motion, feed_limiter, limits_for, load_lobes
from planning.limits.model import (
    cantilever_deflection_mm,
    second_moment_mm4,
    spindle_power_kw,
    spindle_torque_nm,
    tool_stiffness_n_mm,
)
from planning.nc import Program, interpret
from planning.stock import ZMap

AL = get_material("al6061-t6").endmill


def test_closed_forms_by_hand() -> None:
    # F_t = 500 N on a phi 20 cutter at 1000 rpm: v = pi 20 1000 / 60 = 1047.2 mm/s
    assert spindle_power_kw(500.0, 20.0, 1000.0) == pytest.approx(0.5236, rel=1e-4)  # kW
    assert spindle_torque_nm(500.0, 20.0) == pytest.approx(5.0)  # 500 N x 10 mm = 5 N m
    # I of d = 16 mm: pi 16^4 / 64 = 3216.99 mm^4; 1000 N on 60 mm of HSS (210 GPa):
    # 1000 x 216000 / (3 x 210000 x 3216.99) = 0.10658 mm
    i = second_moment_mm4(16.0)
    assert i == pytest.approx(3216.99, rel=1e-5)
    assert cantilever_deflection_mm(1000.0, 60.0, 210e3, i) == pytest.approx(0.10658, rel=1e-4)
    # phi20-flat: HSS, 60 mm stick-out, d_e = 0.8 x 20 = 16 mm -> 3 E I / L^3 = 9382.9 N/mm
    assert tool_stiffness_n_mm(get_tool("phi20-flat")) == pytest.approx(9382.9, rel=1e-4)


def _slot(depth_mm: float, feed: float, rpm: float = 3000.0) -> Program:
    return Program.parse(
        f"G21 G90 G17\nS{rpm:g} M3\nG0 X-10 Y0 Z5\nG1 Z{-depth_mm:g} F100\n"
        f"G1 X60 F{feed:g}\nG0 Z5\nM30\n"
    )


def _box() -> ZMap:
    return ZMap.box(-20, 80, -20, 20, -20, 0, 0.25)


def test_slot_power_and_torque_against_the_mean_force_closed_form() -> None:
    # phi10-flat (3 teeth) slotting 2 mm deep at 300 mm/min, 3000 rpm in al6061-t6:
    # cutting: Ktc Q = 796 x (2 x 10 x 300 / 60) = 79,600 N mm/s; edge: Kte a N / 2 (half the
    # turn in the cut) = 27.7 x 2 x 3 / 2 = 83.1 N at v = pi 10 3000 / 60 = 1570.8 mm/s
    # -> 130,533 N mm/s; P = 0.2101 kW, T = P / w = 210.1 / 314.16 = 0.6689 N m
    tool = get_tool("phi10-flat")
    limits = Limits(power_kw=1.0, torque_nm=1.0)
    prog = _slot(2.0, 300.0)
    res = check_motion(interpret(prog), tool, AL, limits, _box())
    row = res.blocks.set_index("block").loc[4]  # the slot (line 5)
    assert row["power"] == pytest.approx(0.2101, rel=0.03)
    assert row["torque"] == pytest.approx(0.6689, rel=0.03)
    assert res.violations == []


def test_violations_name_block_limit_value_and_margin() -> None:
    tool = get_tool("phi10-flat")
    limits = Limits(power_kw=0.1, chip_mm=0.02)  # fz = 300 / (3 x 3000) = 0.0333 mm in a slot
    res = check_motion(interpret(_slot(2.0, 300.0)), tool, AL, limits, _box())
    got = {(v["block"], v["limit"]): v for v in res.violations}
    # the slot breaks both; the plunge (100 mm/min, fz = 0.011 mm) only the power
    assert set(got) == {(3, "power"), (4, "power"), (4, "chip")}
    chip = got[(4, "chip")]
    assert chip["value"] == pytest.approx(1 / 30, rel=1e-4) and chip["allowed"] == 0.02
    assert chip["margin_pct"] == pytest.approx(100 * (1 - (1 / 30) / 0.02), abs=0.01)


def test_lobes_table_interpolates_and_refuses_bad_rows(tmp_path: Path) -> None:
    p = tmp_path / "lobes.csv"
    p.write_text("spindle_rpm,depth_limit_mm,chatter_hz\n1000,2.0,900\n3000,4.0,950\n5000,,\n")
    t = load_lobes(p)
    assert t.depth_mm(np.array([2000.0, 5000.0])).tolist() == [3.0, math.inf]
    p.write_text("spindle_rpm,depth_limit_mm\n1000,2.0\n2000,-1\n")
    with pytest.raises(PlanningError, match=r"lobes.csv:3: depth_limit_mm = -1"):
        load_lobes(p)


def test_stability_from_lobes_flags_deep_blocks(tmp_path: Path) -> None:
    p = tmp_path / "lobes.csv"
    p.write_text("spindle_rpm,depth_limit_mm\n1000,2.0\n5000,2.0\n")
    limits = limits_for(get_tool("phi10-flat"), None, lobes=p)  # margin 0.8 -> 1.6 mm
    res = check_motion(interpret(_slot(2.0, 300.0)), get_tool("phi10-flat"), AL, limits, _box())
    v = [v for v in res.violations if v["limit"] == "stability"]
    assert v and v[0]["allowed"] == pytest.approx(1.6) and v[0]["value"] == pytest.approx(2.0)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    depths=st.lists(st.floats(0.3, 6.0), min_size=1, max_size=4),
    feeds=st.lists(st.floats(200.0, 3000.0), min_size=4, max_size=4),
    power_kw=st.floats(0.05, 2.0),
    chip_mm=st.floats(0.01, 0.1),
    deflection_mm=st.floats(0.005, 0.1),
)
def test_limited_feeds_break_no_limit_and_keep_the_path(
    depths, feeds, power_kw, chip_mm, deflection_mm
) -> None:
    """Random programs and limits: the --limit step of plan feed leaves no block over a
    feed-driven limit (or at the machine's minimum feed) and moves exactly as before."""
    tool = get_tool("phi10-flat")
    lines = ["G21 G90 G17", "S4000 M3", "G0 X-10 Y0 Z5"]
    for k, d in enumerate(depths):
        y = -10 + 5 * k
        lines += [f"G0 X-10 Y{y}", f"G1 Z{-d:.3f} F200", f"G1 X60 F{feeds[k]:.0f}", "G0 Z5"]
    prog = Program.parse("\n".join(lines + ["M30"]) + "\n")
    stock = ZMap.box(-20, 80, -25, 20, -20, 0, 0.5)
    stiff = tool_stiffness_n_mm(tool)
    limits = Limits(power_kw=power_kw, chip_mm=chip_mm, deflection_mm=deflection_mm,
                    stiffness_n_mm=stiff)  # fmt: skip
    _, adjust = feed_limiter(tool, AL, limits, fix=True)
    out, report = adjust(prog, stock, None)
    before, after = interpret(prog), interpret(out)
    assert np.allclose(before.start, after.start) and np.allclose(before.end, after.end)
    for v in report["violations"]:  # only where even 1 mm/min is too fast
        assert after.feed_mm_min[after.block == v["block"]].min() == 1.0
    assert np.all(after.feed_mm_min[after.is_feed] <= before.feed_mm_min[before.is_feed] + 1e-9)


@pytest.mark.slow
@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    cx=st.floats(30, 50),
    cy=st.floats(30, 50),
    height=st.floats(15, 20),
    depth_limit_mm=st.floats(3.0, 8.0),
)
def test_rough_limit_leaves_the_other_levels_unchanged(cx, cy, height, depth_limit_mm) -> None:
    """Random bumps and a flat lobes table: the levels ``plan rough --limit`` does not split
    keep their height, shoulder and passes, in the plan and in the program's feed moves."""
    import tempfile
    import tomllib

    from test_rough_parts import bump_grid, part_toml

    from analysis.validation import validate
    from planning.limits import rough_limiter
    from planning.rough import RoughPlanner, plan_program
    from planning.rough.part import Part, PartConfig

    x, y, z = bump_grid(cx, cy, 20.0, 20.0, height)
    text = part_toml(x, y, z, top=13.0 + height, tool="phi10-flat", cusp_mm=3.0)
    pl = RoughPlanner(Part(validate(PartConfig, tomllib.loads(text))))
    plan = pl.plan("bisection")
    program = plan_program(plan, pl.part)
    with tempfile.TemporaryDirectory() as d:
        lobes = Path(d) / "lobes.csv"
        lobes.write_text(f"spindle_rpm,depth_limit_mm\n100,{depth_limit_mm}\n1e5,{depth_limit_mm}\n")
        new, new_program, report = rough_limiter(fix=True, material="al6061-t6", lobes=lobes)(
            pl, plan, program
        )
    split = {(s["z_mm"], s["height_mm"]) for s in report["levels_split"]}
    kept = [lv for lv in plan.levels if (round(lv.z_mm, 3), round(lv.height_mm, 3)) not in split]
    after = {(lv.z_mm, lv.hi_mm, lv.lo_mm): lv for lv in new.levels}
    m0, m1 = interpret(program), interpret(new_program)

    def flat_moves(m, z):  # the feed moves of one level: both ends at its height
        sel = m.is_feed & np.isclose(m.start[:, 2], z, atol=1e-3) & np.isclose(m.end[:, 2], z,
                                                                               atol=1e-3)
        return np.concatenate([m.start[sel], m.end[sel]], 1)

    for lv in kept:
        twin = after[(lv.z_mm, lv.hi_mm, lv.lo_mm)]
        assert len(twin.paths.passes) == len(lv.paths.passes)
        for a, b in zip(lv.paths.passes, twin.paths.passes):
            assert np.array_equal(a.xy_mm, b.xy_mm)
        # in order, in one run (sub-levels of a split one may share its height)
        a, b = flat_moves(m0, lv.z_mm), flat_moves(m1, lv.z_mm)
        runs = np.lib.stride_tricks.sliding_window_view(b, a.shape)[:, 0]
        assert np.any(np.all(np.abs(runs - a) < 1e-6, axis=(1, 2)))
