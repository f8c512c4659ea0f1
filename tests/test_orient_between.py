"""planning.orient.between: the fcl mesh check between CL points and the tip's deviation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from analysis.config import load_machine
from planning.orient.between import Scene, check_moves
from planning.orient.kinematics import inverse
from planning.orient.tool import ToolSystem, cutter_position
from planning.surface import NurbsSurface
from planning.surface.nurbs import clamped_uniform_knots

ROOT = Path(__file__).resolve().parent.parent
TOOL = ToolSystem(6.0, 2.0, 24.0, 12.0, 40.0, 40.0, 80.0)


def plane(z_mm=0.0, half_mm=30.0):
    cp = np.zeros((4, 4, 3))
    g = np.linspace(-half_mm, half_mm, 4)
    cp[..., 0], cp[..., 1], cp[..., 2] = g[:, None], g[None, :], z_mm
    k = clamped_uniform_knots(4, 3)
    return NurbsSurface((3, 3), k, k, cp, None, 1, "floor")


@pytest.fixture(scope="module")
def scene():
    box = ("clamp", (20.0, -5.0, 0.0), (30.0, 5.0, 30.0))
    return Scene.build([plane()], TOOL, 0.5, 0.005, fixtures=[box])


@pytest.mark.parametrize("tilt_deg", [0.0, 10.0, 40.0])
def test_touching_is_no_collision_and_sinking_is(scene, tilt_deg):
    t = np.radians(tilt_deg)
    u = np.array([-np.sin(t), 0.0, np.cos(t)])  # away from the clamp
    n = np.array([0.0, 0.0, 1.0])
    tip, _ = cutter_position(np.zeros(3), n, u, TOOL.R_mm, TOOL.r_mm)  # touches z = 0 at 0
    assert scene.hit(tip, u) == ""
    # Within the 0.005 mm tolerance less the polygon's excess (<= 0.0032 mm here).
    assert scene.hit(tip + [0, 0, -0.0015], u) == ""
    assert scene.hit(tip + [0, 0, -0.01], u) == "cutter hits part"


def test_holder_against_a_fixture_is_named(scene):
    u = np.array([0.0, 0.0, 1.0])
    # The cutter (R 6) clears the clamp's face at x = 20 by 1 mm; the holder (R 12) does not.
    assert scene.hit(np.array([13.0, 0.0, 5.0]), u) == "holder hits clamp"
    assert scene.hit(np.array([-13.0, 0.0, 5.0]), u) == ""


def test_tip_deviation_of_a_pure_a_move_is_the_chord_sag():
    """The tip stays at p while A turns by theta about the pivot: the control moves X Y Z along
    the chord of the circle p turns on, so half way the tip is r (1 - cos(theta / 2)) off p."""
    m = load_machine(ROOT / "configs" / "machines" / "mill-5axis.toml")
    p = np.array([[5.0, 30.0, 40.0]] * 2)
    r = np.hypot(30.0, 40.0)  # distance of p from the A axis (machine X through the pivot 0)
    theta = np.radians(8.0)
    axes = np.array([[0.0, 0.0, 1.0], [0.0, np.sin(theta), np.cos(theta)]])
    mv = inverse(m, p, axes)
    assert mv.a_deg[1] == pytest.approx(8.0) and mv.c_deg[1] == pytest.approx(0.0, abs=1e-9)
    far = Scene.build([plane(-200.0)], TOOL, 5.0, 0.005)
    chk = check_moves(m, mv, p, np.zeros(2, int), 0.0, far, step_mm=0.01, step_deg=0.01)
    assert chk.collisions == 0
    assert chk.deviation_mm[0] == pytest.approx(r * (1 - np.cos(theta / 2)), rel=1e-4)
