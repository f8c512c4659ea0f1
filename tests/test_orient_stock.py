"""planning.orient.stock5: dexels along the design normals, cut by ball, bull and flat cutters;
expected heights from the closed forms of the cutter's profile, and the fan example's gouge."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planning.orient.stock5 import NormalDexels, figures
from planning.surface import NurbsSurface
from planning.surface.nurbs import clamped_uniform_knots

ROOT = Path(__file__).resolve().parent.parent
ALLOW, BELOW = 1.0, 0.5


def plane() -> NurbsSurface:
    """z = 0 for 0 <= x <= 40, -10 <= y <= 10, normal +Z."""
    cp = np.array([[[0, -10, 0], [0, 10, 0]], [[40, -10, 0], [40, 10, 0]]], float)
    k = clamped_uniform_knots(2, 1)
    return NurbsSurface((1, 1), k, k, cp, None, 1, "plane")


def sweep(y_mm, z_mm, x_mm=(5.0, 35.0), step_mm=0.1) -> tuple[np.ndarray, np.ndarray]:
    x = np.arange(x_mm[0], x_mm[1] + 1e-9, step_mm)
    tips = np.stack([x, np.full_like(x, y_mm), np.full_like(x, z_mm)], 1)
    return tips, np.tile([0.0, 0.0, 1.0], (len(x), 1))


def profile(y, R, r):
    """Height of a vertical cutter's underside (tip at 0) at distance |y| from its axis."""
    y = np.abs(y)
    h = np.where(y <= R - r, 0.0, r - np.sqrt(np.maximum(r**2 - (y - (R - r)) ** 2, 0.0)))
    return np.where(y < R, h, np.inf)


@pytest.mark.parametrize("R, r", [(4.9, 4.9), (4.9, 1.9), (4.9, 0.0)])
def test_one_pass_leaves_the_cutter_profile_and_gouges_by_its_depth(R, r):
    dex = NormalDexels.on_surface(plane(), (0, 1), (0, 1), 0.25, ALLOW, BELOW)
    depth = 0.2
    dex.cut(*sweep(0.0, -depth), R, r, 20.0)
    mid = dex.top_mm.shape[0] // 2  # x = 20, far from the ends of the pass
    y = dex.point[mid, :, 1]
    expected = np.clip(profile(y, R, r) - depth, -BELOW, ALLOW)
    assert np.abs(dex.top_mm[mid] - expected).max() < 1e-6
    fig = figures(dex, ALLOW, 0.1)
    assert fig.gouge_max_mm == pytest.approx(depth, abs=1e-6)
    assert fig.leftover_max_mm == ALLOW  # beyond the pass, the stock is untouched


@pytest.mark.long
def test_two_ball_passes_leave_the_scallop_of_their_stepover():
    R, step = 5.0, 2.2  # the cusp, y = 0, is a grid point
    dex = NormalDexels.on_surface(plane(), (0, 1), (0, 1), 0.05, ALLOW, BELOW)
    for y in (-step / 2, step / 2):
        dex.cut(*sweep(y, 0.0, (15.0, 25.0)), R, R, 20.0)
    mid = dex.top_mm.shape[0] // 2
    y = dex.point[mid, :, 1]
    between = np.abs(y) <= step / 2
    cusp = R - np.sqrt(R**2 - (step / 2) ** 2)  # scallop height, closed form
    assert dex.top_mm[mid, between].max() == pytest.approx(cusp, abs=1e-9)
    assert dex.top_mm[mid, between].min() == pytest.approx(0.0, abs=1e-9)
    assert (dex.top_mm[mid] >= -1e-9).all()  # touching the design surface is no gouge


@pytest.mark.long
def test_a_tilted_flat_cutter_touches_with_its_rim():
    """A flat end mill leaning 10 deg back along the feed, its lowest rim point on the surface:
    the heel cuts nothing below z = 0, the mark is as wide as the cutter. The sharp heel leaves
    a sawtooth of the sample step times tan(lead) between samples: 0.005 mm steps here."""
    R, a = 5.0, np.radians(10.0)
    step = 0.005
    tips, _ = sweep(0.0, R * np.sin(a), (15.0, 25.0), step)
    axes = np.tile([-np.sin(a), 0.0, np.cos(a)], (len(tips), 1))
    dex = NormalDexels.on_surface(plane(), (0, 1), (0, 1), 0.25, ALLOW, BELOW)
    dex.cut(tips, axes, R, 0.0, 20.0)
    mid = dex.top_mm.shape[0] // 2
    y = dex.point[mid, :, 1]
    # The tilted bottom disc seen along the feed is an ellipse: at lateral offset y its lowest
    # point is at z = R sin(a) (1 - sqrt(1 - (y / R)^2)).
    rim = R * np.sin(a) * (1 - np.sqrt(np.clip(1 - (y / R) ** 2, 0, None)))
    inner = np.abs(y) < R - 0.25  # at the side the rim runs along the feed: no sawtooth bound
    err = dex.top_mm[mid, inner] - rim[inner]
    assert err.min() > -1e-9 and err.max() <= step * np.tan(a) + 1e-9
    assert (dex.top_mm[mid, np.abs(y) > R] == ALLOW).all()


@pytest.mark.long
def test_fan_example_gouges_less_than_its_tolerance(tmp_path):
    from planning.orient import load_orient, run_orient

    cfg_path = ROOT / "configs" / "orient" / "fan.toml"
    summary = run_orient(cfg_path, tmp_path / "fan", plot=False)
    cfg, _, _ = load_orient(cfg_path)
    assert summary["gouge_max_mm"] <= cfg.planner.gouge_tolerance_mm
    assert summary["stock_resolution_mm"] == 0.25
    assert 0 < summary["leftover_max_mm"] <= summary["stock_allowance_mm"]
