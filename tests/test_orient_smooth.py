"""planning.orient.smooth: the smooth orientation field stays feasible and turns the axis less."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planning.orient import ToolSystem, load_orient, verify
from planning.orient.planner import axis_jumps_deg, build_context, cc_points, solve_all
from planning.orient.smooth import angles_of, smooth_result
from planning.orient.tool import local_frame, tool_axis

ROOT = Path(__file__).resolve().parent.parent


@settings(max_examples=100, deadline=None)
@given(st.floats(0, 1.5), st.floats(-1.5, 1.5), st.integers(0, 100))
def test_angles_of_inverts_tool_axis(alpha, beta, seed):
    rng = np.random.default_rng(seed)
    b, f, n = local_frame(rng.normal(size=(1, 3)), rng.normal(size=(1, 3)))
    u = tool_axis(np.array([alpha]), np.array([beta]), b, f, n)
    assert np.allclose(angles_of(u, b, f, n), [[alpha, beta]], atol=1e-9)


def test_smoothing_keeps_every_point_feasible_and_lowers_the_jumps():
    cfg, tool_cfg, _ = load_orient(ROOT / "configs" / "orient" / "fan.toml")
    surfaces = [s.build() for s in cfg.surfaces]
    cc = cc_points(surfaces[[s.role for s in cfg.surfaces].index("machined")], cfg)
    ctx = build_context(cfg, tool_cfg, surfaces)
    raw = solve_all(ctx, cc)
    res = smooth_result(ctx, raw)
    a0, a1 = cfg.limits.alpha_deg
    assert np.all((res.alpha_deg >= a0 - 1e-9) & (res.alpha_deg <= a1 + 1e-9))
    assert np.all(res.gap_per_mm >= cfg.planner.curvature_margin_per_mm - 1e-9)
    j0, j1 = axis_jumps_deg(raw.axis, cc.line), axis_jumps_deg(res.axis, cc.line)
    assert np.nanmax(j1) < np.nanmax(j0) and np.nanmean(j1) < np.nanmean(j0)
    tool = ToolSystem.from_endmill(tool_cfg)
    ver = verify(surfaces, tool, res.tip_mm, res.axis, 0.2, cfg.planner.gouge_tolerance_mm)
    assert ver.collisions == 0
