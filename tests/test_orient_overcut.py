"""planning.orient.overcut: exact overcut on the NURBS surface, where mesh vertices miss it."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.config import load_machine
from planning.orient.between import Scene, check_moves
from planning.orient.kinematics import inverse
from planning.orient.overcut import OvercutCheck
from planning.orient.tool import ToolSystem, cutter_position, meridian
from tests.test_orient_between import ROOT, TOOL, plane

BALL = ToolSystem(3.0, 3.0, 20.0, 8.0, 40.0, 40.0, 80.0)


@pytest.mark.parametrize("tilt_deg", [0.0, 10.0, 40.0])
@pytest.mark.parametrize("sink_mm", [0.0, 0.002, 0.006])
def test_depth_in_a_plane_is_how_far_the_cutter_sinks(tilt_deg, sink_mm):
    """A convex cutter touching the plane z = 0 and lowered by d has its lowest point d under
    the plane, so the deepest point of the plane inside it is d deep."""
    oc = OvercutCheck([plane()], TOOL, 0.5)
    t = np.radians(tilt_deg)
    u = np.array([np.sin(t), 0.0, np.cos(t)])
    tip, _ = cutter_position(np.array([0.1, 0.2, 0.0]), np.array([0.0, 0.0, 1.0]), u,
                             TOOL.R_mm, TOOL.r_mm)  # fmt: skip
    got = oc.depth(tip - [0.0, 0.0, sink_mm], u)
    assert got.depth_mm == pytest.approx(sink_mm, abs=2e-5)


def test_a_ball_between_mesh_vertices_is_seen():
    """A ball (r 3) sunk 0.004 mm at the middle of a 0.5 mm grid cell touches the plane in a
    circle of radius sqrt(2 r d) = 0.155 mm, inside the cell: no vertex is inside the ball."""
    oc = OvercutCheck([plane()], BALL, 0.5)
    g = oc.grids[0]
    p = np.array([0.5 * (g.u[0] + g.u[1]), 0.5 * (g.v[0] + g.v[1])])
    centre = np.append(plane().points(*p)[0][:2], 0.0)
    u = np.array([0.0, 0.0, 1.0])
    tip = centre - [0.0, 0.0, 0.004]
    rho, z = meridian(oc.vertices, tip, u)
    assert BALL.cutter_distance(rho, z).min() > 0  # the vertices see nothing
    assert oc.depth(tip, u).depth_mm == pytest.approx(0.004, abs=2e-5)


def test_a_move_that_sinks_is_flagged_by_its_overcut():
    m = load_machine(ROOT / "configs" / "machines" / "mill-5axis.toml")
    scene = Scene.build([plane()], TOOL, 0.5, 0.005)
    u = np.array([[0.0, 0.0, 1.0]] * 2)
    for sink_mm, flagged in ((0.003, False), (0.006, True)):
        tips = np.array([[-2.0, 0.0, -sink_mm], [2.0, 0.0, -sink_mm]])
        chk = check_moves(m, inverse(m, tips, u), tips, np.zeros(2, int), 0.0, scene)
        assert chk.overcut_mm[0] == pytest.approx(sink_mm, abs=2e-5)
        assert (chk.overcut_mm[0] > scene.gouge_limit_mm) == flagged
