"""planning.surface.nurbs: NURBS evaluation (splipy + quotient rule), normals, curvature."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from splipy import surface_factory as sf

from planning.errors import PlanningError
from planning.surface.nurbs import NurbsSurface, clamped_uniform_knots


def from_splipy(s, name="s") -> NurbsSurface:
    """A splipy rational surface as a NurbsSurface (weights split out of the homogeneous net)."""
    s = s.clone()
    for d, b in enumerate(s.bases):
        if b.periodic >= 0:  # open up splipy's periodic bases into plain clamped ones
            s.lower_periodic(-1, d)
    cp = np.asarray(s.controlpoints)  # (n1, n2, 4): w x, w y, w z, w
    w = cp[..., 3]
    return NurbsSurface(
        (s.order(0) - 1, s.order(1) - 1),
        s.knots(0, with_multiplicities=True),
        s.knots(1, with_multiplicities=True),
        cp[..., :3] / w[..., None],
        w,
        name=name,
    )


def rand_params(surf, n, seed=0, margin=0.02):
    rng = np.random.default_rng(seed)
    (u0, u1), (v0, v1) = surf.u_range, surf.v_range
    du, dv = margin * (u1 - u0), margin * (v1 - v0)
    return rng.uniform(u0 + du, u1 - du, n), rng.uniform(v0 + dv, v1 - dv, n)


def test_sphere_points_normals_and_curvature_in_any_direction():
    R = 12.5
    s = from_splipy(sf.sphere(r=R))
    assert s.rational
    u, v = rand_params(s, 300, margin=0.1)
    sp = s.evaluate(u, v)
    assert np.allclose(np.linalg.norm(sp.point, axis=1), R, atol=1e-9)
    radial = sp.point / R
    # Normal is radial (either orientation) and kappa = -1/R measured against the outward normal.
    out = np.sign((sp.normal * radial).sum(1))
    assert np.allclose(np.abs((sp.normal * radial).sum(1)), 1.0, atol=1e-9)
    rng = np.random.default_rng(3)
    d = rng.normal(size=(len(u), 3))
    kappa = NurbsSurface.normal_curvature(sp, d)
    assert np.allclose(kappa * out, -1.0 / R, rtol=1e-7)


def test_cylinder_curvature_follows_euler():
    R, H = 8.0, 30.0
    s = from_splipy(sf.cylinder(r=R, h=H))
    u, v = rand_params(s, 200, seed=1)
    sp = s.evaluate(u, v)
    axis = np.array([0.0, 0.0, 1.0])
    radial = sp.point * [1, 1, 0] / R
    out = np.sign((sp.normal * radial).sum(1))
    around = np.cross(axis, radial)
    k_around = NurbsSurface.normal_curvature(sp, around) * out
    k_along = NurbsSurface.normal_curvature(sp, np.broadcast_to(axis, around.shape)) * out
    k_45 = NurbsSurface.normal_curvature(sp, around + axis) * out
    assert np.allclose(k_around, -1 / R, rtol=1e-7)
    assert np.allclose(k_along, 0.0, atol=1e-9)
    assert np.allclose(k_45, -0.5 / R, rtol=1e-7)  # Euler: k1 cos^2 + k2 sin^2


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000))
def test_rational_derivatives_match_finite_differences(seed):
    rng = np.random.default_rng(seed)
    cp = (
        rng.normal(size=(5, 4, 3)) * 10
        + np.stack(np.meshgrid(np.arange(5) * 10.0, np.arange(4) * 10.0, [0.0], indexing="ij"), -1)[
            ..., :3
        ].squeeze()
    )
    w = rng.uniform(0.5, 2.0, size=(5, 4))
    s = NurbsSurface((3, 2), clamped_uniform_knots(5, 3), clamped_uniform_knots(4, 2), cp, w)
    u, v = rand_params(s, 5, seed=seed, margin=0.05)
    h = 1e-5
    sp = s.evaluate(u, v, normals=False)
    num_u = (s.points(u + h, v) - s.points(u - h, v)) / (2 * h)
    num_v = (s.points(u, v + h) - s.points(u, v - h)) / (2 * h)
    num_uv = (s.evaluate(u, v + h, False).su - s.evaluate(u, v - h, False).su) / (2 * h)
    num_uu = (s.evaluate(u + h, v, False).su - s.evaluate(u - h, v, False).su) / (2 * h)
    scale = 1 + np.abs(sp.suu).max()
    assert np.allclose(sp.su, num_u, atol=1e-5 * scale)
    assert np.allclose(sp.sv, num_v, atol=1e-5 * scale)
    assert np.allclose(sp.suv, num_uv, atol=1e-4 * scale)
    assert np.allclose(sp.suu, num_uu, atol=1e-4 * scale)


def test_degenerate_normal_is_reported_with_its_point():
    cp = np.zeros((4, 4, 3))
    cp[..., 0], cp[..., 1] = np.meshgrid(np.arange(4.0), np.arange(4.0), indexing="ij")
    cp[0, :, :] = [0.0, 0.0, 0.0]  # first row collapsed to one point: S_v = 0 along u = 0
    s = NurbsSurface(
        (3, 3), clamped_uniform_knots(4, 3), clamped_uniform_knots(4, 3), cp, name="collapsed"
    )
    with pytest.raises(PlanningError, match=r"collapsed: degenerate normal at u = 0, v = 0\.5"):
        s.evaluate(np.array([0.0]), np.array([0.5]))
    s.evaluate(np.array([0.5]), np.array([0.5]))  # inside is fine


def test_bad_knots_and_weights_are_refused():
    cp = np.zeros((4, 4, 3))
    with pytest.raises(PlanningError, match="knots_u has 7 knots"):
        NurbsSurface((3, 3), np.zeros(7), clamped_uniform_knots(4, 3), cp)
    with pytest.raises(PlanningError, match="weights must be > 0"):
        NurbsSurface(
            (3, 3), clamped_uniform_knots(4, 3), clamped_uniform_knots(4, 3), cp, -np.ones((4, 4))
        )


def test_triangulation_vertices_lie_on_surface_and_iso_paths_follow_parameters():
    s = from_splipy(sf.cylinder(r=5.0, h=20.0))
    V, F = s.triangulate(1.0)
    assert F.max() < len(V) and F.shape[1] == 3
    assert np.allclose(np.hypot(V[:, 0], V[:, 1]), 5.0, atol=1e-9)
    edges = np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1)
    assert edges.max() < 1.5
    u, v = s.iso_path("u", 0.25, 7, (0.0, 1.0))
    assert np.allclose(v, s.v_range[0] + 0.25 * np.ptp(s.v_range)) and len(u) == 7
    assert np.all(np.diff(u) > 0)
