"""Ferguson composite surfaces (seed 000 2.1-2.2) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from planning.errors import PlanningError
from planning.surface import FergusonSurface


def cap(R=50.0, half=30.0, n=13):
    """Sphere cap z = sqrt(R^2 - x^2 - y^2) sampled on a square grid."""
    x = np.linspace(-half, half, n)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    return FergusonSurface.from_height_field(x, x, np.sqrt(R * R - gx**2 - gy**2))


def test_interpolates_every_grid_point():
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.uniform(2, 6, 9))
    y = np.cumsum(rng.uniform(2, 6, 7))
    z = rng.normal(0, 3, (9, 7))
    s = FergusonSurface.from_height_field(x, y, z)
    i, j = np.meshgrid(np.arange(9.0), np.arange(7.0), indexing="ij")
    p = s.evaluate(i.ravel(), j.ravel())
    np.testing.assert_allclose(p[:, 2], z.ravel(), atol=1e-12)
    np.testing.assert_allclose(p[:, 0], np.repeat(x, 7), atol=1e-12)


def test_reproduces_a_bicubic_polynomial_exactly():
    # Not-a-knot spline tangents and twists are exact for cubics, so the composite Hermite
    # surface is exactly z = p(x) q(y) for cubic p, q, between the grid points too.
    def f(x, y):
        return (0.01 * x**3 - 0.2 * x**2 + x + 2) * (0.002 * y**3 + 0.05 * y - 1)

    x = np.linspace(0, 40, 6)
    y = np.linspace(-10, 30, 5)
    gx, gy = np.meshgrid(x, y, indexing="ij")
    s = FergusonSurface.from_height_field(x, y, f(gx, gy))
    rng = np.random.default_rng(0)
    su, tv = rng.uniform(0, 5, 500), rng.uniform(0, 4, 500)
    p = s.evaluate(su, tv)
    np.testing.assert_allclose(p[:, 2], f(p[:, 0], p[:, 1]), atol=1e-9)


def test_sphere_cap_points_normals_and_offset_against_closed_form():
    R, d = 50.0, 2.0
    s = cap(R)
    p, n = s.sample(8)
    assert np.abs(np.linalg.norm(p, axis=2) - R).max() < 0.02
    radial = p / np.linalg.norm(p, axis=2, keepdims=True)
    assert np.abs(n - radial).max() < 0.01  # unit normals, pointing up and out
    off = s.offset(d)  # seed 000 2.2: grid points moved by d along n, re-fitted
    q, _ = off.sample(8)
    assert np.abs(np.linalg.norm(q, axis=2) - (R + d)).max() < 0.02


def test_composite_is_c1_across_patch_edges():
    s = cap()
    t = np.linspace(0.1, 11.9, 50)
    for edge in (3.0, 7.0):
        _, a_s, a_t = s.derivatives(np.full_like(t, edge - 1e-9), t)
        _, b_s, b_t = s.derivatives(np.full_like(t, edge + 1e-9), t)
        np.testing.assert_allclose(a_s, b_s, atol=1e-6)
        np.testing.assert_allclose(a_t, b_t, atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(
    st.floats(-30, 30),
    st.floats(-30, 30),
    st.floats(5, 60),
)
def test_plane_is_reproduced_and_offset_exactly(a, b, c):
    x = np.linspace(0, 50, 6)
    y = np.linspace(0, 40, 5)
    gx, gy = np.meshgrid(x, y, indexing="ij")
    z = 0.02 * a * gx + 0.02 * b * gy + c
    s = FergusonSurface.from_height_field(x, y, z)
    d = 1.5
    off = s.offset(d)
    nz = 1 / np.sqrt(1 + (0.02 * a) ** 2 + (0.02 * b) ** 2)
    q, n = off.sample(3)
    # An offset plane is the same plane raised by d / cos(beta).
    plane = 0.02 * a * q[..., 0] + 0.02 * b * q[..., 1] + c + d / nz
    np.testing.assert_allclose(q[..., 2], plane, atol=1e-9)
    np.testing.assert_allclose(n[..., 2], nz, atol=1e-12)


def test_stl_part_is_sampled_through_trimesh(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=50.0)
    path = tmp_path / "sphere.stl"
    mesh.export(path)
    s = FergusonSurface.from_stl(path, 2.0)
    p, _ = s.sample(2)
    p = p.reshape(-1, 3)
    inner = np.hypot(p[:, 0], p[:, 1]) < 35
    # Facet chord error of the icosphere (edges ~3 mm on R 50) bounds the deviation.
    assert np.abs(np.linalg.norm(p[inner], axis=1) - 50).max() < 0.15
    assert s.bounds_xy() == pytest.approx((-50, 50, -50, 50), abs=1e-6)


def test_nan_in_grid_is_refused_with_its_index():
    x = np.linspace(0, 10, 4)
    z = np.zeros((4, 4))
    z[2, 1] = np.nan
    with pytest.raises(PlanningError, match=r"point \[2, 1\] z = nan.*finite"):
        FergusonSurface.from_height_field(x, x, z)


def test_folded_grid_is_refused():
    x = np.linspace(0, 30, 4)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    pts = np.stack([gx, gy, np.zeros_like(gx)], 2)
    pts[2, :, 0] = 5.0  # row 2 folds back behind row 1 (x = 10)
    with pytest.raises(PlanningError, match=r"folds over itself in xy at patch \[1, "):
        FergusonSurface.from_points(pts)


def test_bad_shapes_and_offsets_are_refused():
    with pytest.raises(PlanningError, match="expected"):
        FergusonSurface.from_points(np.zeros((1, 5, 3)))
    with pytest.raises(PlanningError, match="increasing"):
        FergusonSurface.from_height_field([0, 1, 1], [0, 1], np.zeros((3, 2)))
    with pytest.raises(PlanningError, match=">= 0"):
        cap().offset(-1.0)
