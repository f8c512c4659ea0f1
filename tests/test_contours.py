"""Contours at height z (seed 000 2.3) against closed forms: sphere, cone, islands, saddles."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from planning.surface import FergusonSurface
from planning.surface.contours import SectionMaker, section

R = 50.0


def height_field(f, half=30.0, n=13, lo=None):
    lo = -half if lo is None else lo
    x = np.linspace(lo, half, n)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    return FergusonSurface.from_height_field(x, x, f(gx, gy))


@pytest.fixture(scope="module")
def sphere():
    return height_field(lambda x, y: np.sqrt(R * R - x * x - y * y))


@pytest.fixture(scope="module")
def cone():
    # z = H - k rho, sampled on a fine grid; the apex (a kink) is away from the tested levels.
    return height_field(lambda x, y: 60.0 - 0.8 * np.hypot(x, y), half=40.0, n=41)


@pytest.mark.parametrize("z", [40.5, 42.0, 44.0, 47.0, 49.5])
def test_sphere_contour_radius_at_each_height(sphere, z):
    sec = SectionMaker(sphere, tolerance_mm=0.005).section(z)
    assert len(sec.loops) == 1  # one loop, joined across every patch it crosses
    rho = np.sqrt(R * R - z * z)
    # Densify the polygon: chords must stay within tolerance of the true circle too.
    ring = shapely.segmentize(sec.region.geoms[0].exterior, 0.05)
    r = np.hypot(*shapely.get_coordinates(ring).T)
    # 0.005 contour tolerance + the Ferguson fit's own error on this grid (~0.005 here)
    assert np.abs(r - rho).max() < 0.015
    assert sec.area_mm2 == pytest.approx(np.pi * rho * rho, rel=1e-3)
    assert sec.region.geoms[0].exterior.is_ccw


def test_points_lie_on_the_surface_level(sphere):
    maker = SectionMaker(sphere, 0.01)
    for z in (41.0, 45.5):
        xy = maker.section(z).loops[0]
        # The exact z of the fitted surface at those xy (grid is x = 5 s - 30, y = 5 t - 30).
        s, t = (xy[:, 0] + 30) / 5, (xy[:, 1] + 30) / 5
        p = sphere.evaluate(s, t)
        np.testing.assert_allclose(p[:, :2], xy, atol=1e-9)
        assert np.abs(p[:, 2] - z).max() < 1e-6


def test_sphere_contour_clipped_by_the_grid_edge(sphere):
    # At z = 35 the circle (r 35.7) leaves the 60 x 60 grid: the loop closes along its edge.
    sec = section(sphere, 35.0)
    x0, y0, x1, y1 = sec.region.bounds
    assert (x0, y0, x1, y1) == pytest.approx((-30, -30, 30, 30), abs=1e-9)
    rho = np.sqrt(R * R - 35.0**2)
    inside = shapely.get_coordinates(sec.region.boundary)
    inner = np.max(np.abs(inside), axis=1) < 30 - 1e-6
    assert np.abs(np.hypot(*inside[inner].T) - rho).max() < 0.02


@pytest.mark.parametrize("z", [30.0, 38.0, 45.0])
def test_cone_and_its_offset_against_closed_form(cone, z):
    H, k, d = 60.0, 0.8, 2.0
    r = np.hypot(*section(cone, z).loops[0].T)
    assert np.abs(r - (H - z) / k).max() < 0.01
    # The offset of a cone is a cone: rho'(z) = (H + d sqrt(1 + k^2) - z) / k.
    off = cone.offset(d)
    r2 = np.hypot(*section(off, z).loops[0].T)
    assert np.abs(r2 - (H + d * np.sqrt(1 + k * k) - z) / k).max() < 0.02


def test_two_bumps_make_two_islands_then_merge():
    def f(x, y):
        return 10 * np.exp(-((x - 15) ** 2 + y**2) / 80) + 10 * np.exp(-((x + 15) ** 2 + y**2) / 80)

    s = height_field(f, half=40, n=33)
    maker = SectionMaker(s, 0.01)
    assert len(maker.section(6.0).region.geoms) == 2
    assert len(maker.section(1.0).region.geoms) == 1
    assert maker.section(11.0).region.is_empty


def test_crater_gives_a_hole_oriented_clockwise():
    # A ring ridge z = 20 - 0.05 (rho - 20)^2: at z the section is an annulus with radii
    # 20 +- sqrt((20 - z) / 0.05).
    s = height_field(lambda x, y: 20 - 0.05 * (np.hypot(x, y) - 20) ** 2, half=40, n=41)
    z = 15.0
    sec = section(s, z)
    assert len(sec.region.geoms) == 1
    poly = sec.region.geoms[0]
    assert len(poly.interiors) == 1
    assert poly.exterior.is_ccw and not poly.interiors[0].is_ccw
    w = np.sqrt((20 - z) / 0.05)
    r_out = np.hypot(*np.asarray(poly.exterior.coords).T)
    r_in = np.hypot(*np.asarray(poly.interiors[0].coords).T)
    assert np.abs(r_out - (20 + w)).max() < 0.03
    assert np.abs(r_in - (20 - w)).max() < 0.03


@settings(max_examples=10, deadline=None)
@given(st.floats(-6.0, 6.0).filter(lambda v: abs(v) > 0.3))
def test_saddle_membership_matches_the_sign_of_z_minus_level(level):
    c = 20.0
    s = height_field(lambda x, y: (x * x - y * y) / c, half=20, n=21)
    sec = section(s, level)
    # Above the saddle the region is two wedges; below, one piece.
    assert len(sec.region.geoms) == (2 if level > 0 else 1)
    rng = np.random.default_rng(int(abs(level) * 100))
    p = rng.uniform(-19.5, 19.5, (4000, 2))
    f = (p[:, 0] ** 2 - p[:, 1] ** 2) / c
    clear = np.abs(f - level) > 0.05  # away from the contour itself
    inside = shapely.contains_xy(sec.region, p[:, 0], p[:, 1])
    np.testing.assert_array_equal(inside[clear], (f > level)[clear])


def test_level_above_everything_is_empty_and_below_is_everything(sphere):
    m = SectionMaker(sphere)
    assert m.section(60.0).region.is_empty
    assert m.section(10.0).area_mm2 == pytest.approx(3600.0)


@pytest.mark.parametrize("tol", [0.05, 0.005])
def test_polygon_is_within_the_stated_tolerance_of_the_true_contour(tol):
    # A wavy free-form surface: take every edge midpoint of the traced polygon, pull it onto the
    # exact contour of the Ferguson surface (Newton), and measure its distance to the polygon.
    from planning.surface.contours import _project

    def f(x, y):
        return 5 * np.sin(x / 7) * np.cos(y / 9) + 0.02 * x * y

    s = height_field(f, half=30, n=16)
    z = 1.3
    sec = SectionMaker(s, tolerance_mm=tol).section(z)
    worst = 0.0
    for loop in sec.loops:
        mid = 0.5 * (loop[:-1] + loop[1:])
        st_ = s.locate(mid[:, 0], mid[:, 1])
        inner = np.all(np.abs(mid) < 30 - 1e-6, axis=1)  # the edge of the grid is exact anyway
        ss, tt = st_[inner, 0], st_[inner, 1]
        free = np.zeros(len(ss), bool)
        ps, pt = _project(s, ss, tt, z, free, free)
        exact = s.evaluate(ps, pt)
        assert np.abs(exact[:, 2] - z).max() < 1e-6
        d = shapely.distance(shapely.points(exact[:, :2]), sec.region.boundary)
        worst = max(worst, float(d.max()))
    assert worst <= tol * 1.05, worst
    assert worst > tol / 20  # the measure sees the chords (it is not trivially 0)


@pytest.mark.parametrize("z", [17.0, 25.0, 35.0, 45.0])
def test_hemisphere_from_a_parametric_grid_and_its_offset(z):
    # A whole hemisphere (not a height field: the grid maps a square onto the disc), down to
    # 0.34 R where its wall is 71 deg steep; contour radius sqrt((R + d)^2 - z^2) for d = 0, 2.
    u = np.linspace(-0.95, 0.95, 25)
    gu, gv = np.meshgrid(u, u, indexing="ij")
    x = R * gu * np.sqrt(1 - gv**2 / 2)
    y = R * gv * np.sqrt(1 - gu**2 / 2)
    s = FergusonSurface.from_points(np.stack([x, y, np.sqrt(R * R - x * x - y * y)], 2))
    for d, surf in ((0.0, s), (2.0, s.offset(2.0))):
        loops = section(surf, z, tolerance_mm=0.005).loops
        assert len(loops) == 1
        r = np.hypot(*loops[0].T)
        # Fit error of a 25 x 25 net grows on the steep wall: 0.04 mm at 17 mm, 1e-4 at 45.
        assert np.abs(r - np.sqrt((R + d) ** 2 - z * z)).max() < 0.05
