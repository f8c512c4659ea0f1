"""planning.orient._energy: eq 7 is zero exactly when nothing collides; gradient; descent."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planning.orient import Charges, SearchContext, Site, descend, energy, solve_point
from planning.orient.check import CheckMesh, check
from planning.orient.tool import ToolSystem, cutter_position, local_frame, szende_K, tool_axis
from planning.surface.nurbs import NurbsSurface, clamped_uniform_knots

TOOL = ToolSystem(6.0, 2.0, 50.0, 12.0, 40.0, 40.0, 80.0, name="phi12-bull")


def bilinear(corners, name, n=4):
    """A flat patch through four corners (p00, p10, p01, p11) as a cubic B-spline."""
    p00, p10, p01, p11 = (np.asarray(c, float) for c in corners)
    s = np.linspace(0, 1, n)[:, None, None]
    t = np.linspace(0, 1, n)[None, :, None]
    cp = (1 - s) * (1 - t) * p00 + s * (1 - t) * p10 + (1 - s) * t * p01 + s * t * p11
    k = clamped_uniform_knots(n, 3)
    return NurbsSurface((3, 3), k, k, cp, name=name)


@pytest.fixture(scope="module")
def scene():
    floor = bilinear([(-40, -40, 0), (40, -40, 0), (-40, 40, 0), (40, 40, 0)], "floor")
    # Wall x = 14 (just clear of the 12 mm holder radius + 1 mm clearance), 60 mm tall.
    wall = bilinear([(14, -40, 0), (14, -40, 60), (14, 40, 0), (14, 40, 60)], "wall")
    surfaces = [floor, wall]
    pts, sid = [], []
    for i, s in enumerate(surfaces):
        v, _ = s.triangulate(0.5)
        pts.append(v)
        sid.append(np.full(len(v), i))
    P = np.concatenate(pts)
    charges = Charges.from_points(P, np.full(len(P), 0.25), np.concatenate(sid))
    b, f, n = local_frame(np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0]))
    site = Site(np.zeros(3), n, b, f)
    mesh = CheckMesh.build(surfaces, 0.3)
    bounds = np.radians([[0, 15], [-90, 90]])
    ctx = SearchContext(TOOL, charges, mesh, bounds, 0.0025, 1.0, 0.5, 0.0)
    return ctx, site, surfaces


def test_frame_orientation(scene):
    _, site, _ = scene
    assert np.allclose(site.b, [-1, 0, 0])  # b = n x f: tilting by +beta leans the tool to +x
    u = tool_axis(np.asarray(0.0), np.radians(30.0), site.b, site.f, site.n)
    assert u[0] > 0.49


def test_energy_is_zero_exactly_when_the_check_finds_no_collision(scene):
    ctx, site, _ = scene
    agree, total, strong_misses = 0, 0, 0
    for a in np.radians([0, 5, 10, 15]):
        for b in np.radians(np.linspace(-90, 90, 37)):
            U, _ = ctx.U(site, np.array([a, b]))
            u = tool_axis(np.asarray(a), np.asarray(b), site.b, site.f, site.n)
            tip, _ = cutter_position(site.p, site.n, u, TOOL.R_mm, TOOL.r_mm)
            c = check(ctx.mesh, TOOL, tip, u, ctx.tol_mm)
            total += 1
            agree += (U == 0.0) == c.ok
            strong_misses += (U == 0.0) and c.min_mm < -0.3  # a real collision the energy misses
    assert strong_misses == 0
    assert agree / total > 0.95
    # The upright tool on the plane touches with its flat bottom: no energy, no collision.
    assert ctx.U(site, np.zeros(2))[0] == 0.0
    # Leaning 60 deg towards the wall drives the holder into it.
    assert ctx.U(site, np.radians([0.0, 60.0]))[0] > 0.0


def test_gradient_matches_finite_differences(scene):
    ctx, site, _ = scene
    th = np.radians([6.0, 12.0])
    U, g = energy(TOOL, ctx.charges, site, *th, ctx.tol_mm, ctx.clearance_mm, grad=True)
    assert U > 0
    h = 1e-7
    num = []
    for k in range(2):
        d = np.zeros(2)
        d[k] = h
        Up, _ = energy(TOOL, ctx.charges, site, *(th + d), ctx.tol_mm, ctx.clearance_mm)
        Um, _ = energy(TOOL, ctx.charges, site, *(th - d), ctx.tol_mm, ctx.clearance_mm)
        num.append((Up - Um) / (2 * h))
    assert np.allclose(g, num, rtol=1e-3, atol=1e-6 * abs(U))
    # The holder is in the wall: the energy pushes the tool away from it (beta comes down).
    assert g[1] > 0


def test_descent_reaches_zero_energy_from_a_collision(scene):
    ctx, site, _ = scene
    start = np.radians([5.0, 15.0])
    assert ctx.U(site, start)[0] > 0
    path = []
    th, U = descend(ctx, site, start, path=path)
    assert U == 0.0
    assert th[1] < start[1] and len(path) >= 1


@settings(max_examples=20, deadline=None)
@given(
    st.tuples(st.floats(0.0, 20.0), st.floats(0.0, 20.0)).map(sorted),
    st.tuples(st.floats(-90.0, 90.0), st.floats(-90.0, 90.0)).map(sorted),
    st.floats(-0.05, 0.05),
)
def test_planner_answer_is_unit_axis_inside_limits_and_free(scene, alpha_lim, beta_lim, kappa):
    """Whatever the limits: a unit axis inside them with U = 0 that passes the check, or None
    with a reason -- never an orientation outside the limits or colliding."""
    ctx, site, _ = scene
    box = np.radians([alpha_lim, beta_lim])
    c = SearchContext(ctx.tool, ctx.charges, ctx.mesh, box, ctx.tol_mm, ctx.clearance_mm, 5.0, 0.0)
    th, why, U, gate = solve_point(c, site, kappa, box.mean(axis=1))
    if th is None:
        assert why.startswith("no collision-free orientation within alpha") or "check" in why
        return
    assert np.all(th >= box[:, 0] - 1e-12) and np.all(th <= box[:, 1] + 1e-12)
    u = tool_axis(np.asarray(th[0]), np.asarray(th[1]), site.b, site.f, site.n)
    assert np.linalg.norm(u) == pytest.approx(1.0, abs=1e-12)
    assert U == 0.0 and gate.ok
    assert c.U(site, th)[0] == 0.0
    assert float(szende_K(th[0], th[1], TOOL.R_mm, TOOL.r_mm)) >= kappa - 1e-9
