"""Seed 003 geometry: projected angles, [M]^-1, chip thickness, chip area S and edge length l."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.config import FaceMill
from analysis.errors import AnalysisError
from analysis.forces import chip_section, edge_table
from analysis.forces.facemill import (
    DYNO_FROM_TOOL,
    chip_thickness,
    projected_angles,
    rotation_inverse,
    tool_from_insert_axes,
)

deg = st.floats(-25, 25, allow_nan=False)
lead = st.floats(0, 45, allow_nan=False)


def _rot(axis: int, a: float) -> np.ndarray:
    """The plain rotation by the one tool angle (columns: T', R', A' in T, R, A)."""
    c, s = math.cos(a), math.sin(a)
    if axis == 0:  # lead: A' leans from A towards +R, about T
        return np.array([[1, 0, 0], [0, c, s], [0, -s, c]])
    if axis == 2:  # radial rake: R' leans from R towards +T, about A
        return np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
    return np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])  # axial rake: T' towards +A, about R


@settings(max_examples=200, deadline=None)
@given(lead, deg, deg)
def test_rotation_is_orthonormal_for_any_tool_angles(gl, gr, ga):
    m = rotation_inverse(*np.radians([gl, gr, ga]))
    np.testing.assert_allclose(m.T @ m, np.eye(3), atol=1e-12)
    assert np.linalg.det(m) == pytest.approx(1.0, abs=1e-12)


@settings(max_examples=100, deadline=None)
@given(lead, deg, deg)
def test_projections_of_rotated_axes_are_the_tool_angles(gl, gr, ga):
    """The definition of seed 003 2.2.2: A' seen in the RA plane leans gamma_L from A, R' in the
    TR plane gamma_R from R, T' in the TA plane gamma_A from T."""
    m = rotation_inverse(*np.radians([gl, gr, ga]))
    t_, r_, a_ = m[:, 0], m[:, 1], m[:, 2]
    assert math.degrees(math.atan2(a_[1], a_[2])) == pytest.approx(gl, abs=1e-9)
    assert math.degrees(math.atan2(r_[0], r_[1])) == pytest.approx(gr, abs=1e-9)
    assert math.degrees(math.atan2(t_[2], t_[0])) == pytest.approx(ga, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.floats(-40, 40, allow_nan=False).filter(lambda x: abs(x) > 1e-3))
def test_each_angle_alone_is_the_plain_rotation(a):
    r = math.radians(a)
    # Lead alone: rotation about T; theta_2 = gamma_L.
    t = projected_angles(r, 0.0, 0.0)
    np.testing.assert_allclose([float(x) for x in t], [0, r, 0], atol=1e-12)
    np.testing.assert_allclose(rotation_inverse(r, 0.0, 0.0), _rot(0, r), atol=1e-12)
    # Radial rake alone: rotation about A (T' leans towards -R); theta_1 = gamma_R.
    t = projected_angles(0.0, r, 0.0)
    np.testing.assert_allclose([float(x) for x in t], [r, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rotation_inverse(0.0, r, 0.0), _rot(2, r), atol=1e-12)
    # Axial rake alone: rotation about R; theta_3 = gamma_A.
    t = projected_angles(0.0, 0.0, r)
    np.testing.assert_allclose([float(x) for x in t], [0, 0, r], atol=1e-12)
    np.testing.assert_allclose(rotation_inverse(0.0, 0.0, r), _rot(1, r), atol=1e-12)


def test_printed_eqs_6_and_7_are_a_slip():
    """As printed, eqs 6-7 give a non-orthonormal [M]^-1 for the seed's own tool (15/0/7 deg):
    the reason analysis.forces.facemill uses the cyclic forms that follow eq 5."""
    gl, gr, ga = np.radians([15.0, 0.0, 7.0])
    tl, tr, ta = np.tan([gl, gr, ga])
    den = 1 + tl * tr * ta
    t1 = np.arctan((np.cos(ga) * tr - np.sin(ga) * tl + np.sin(ga) * tr * ta) / den)
    t2 = np.arctan((np.cos(gr) * tl - np.sin(gr) * ta + np.sin(gr) * tl * ta) / den)
    t3 = np.arctan((np.cos(gl) * ta - np.sin(gl) * tr + np.sin(gl) * ta * tr) / den)
    printed = np.array(
        [
            [np.cos(ga) * np.cos(t1), np.sin(gr) * np.cos(t2), -np.sin(t3)],
            [-np.sin(t1), np.cos(gr) * np.cos(t2), np.sin(gl) * np.cos(t3)],
            [np.sin(ga) * np.cos(t1), -np.sin(t2), np.cos(gl) * np.cos(t3)],
        ]
    )
    assert np.abs(printed.T @ printed - np.eye(3)).max() > 5e-3
    ours = projected_angles(gl, gr, ga)
    assert float(ours[0]) == pytest.approx(float(t1))  # eq 5 is right as printed
    assert math.degrees(float(ours[2])) == pytest.approx(7.244, abs=1e-3)


def test_eq14_and_eq2_make_a_rotation_about_z():
    th = np.linspace(0, 2 * np.pi, 13)
    e = tool_from_insert_axes(th)
    np.testing.assert_allclose(e @ e, np.broadcast_to(np.eye(3), e.shape), atol=1e-12)
    de = DYNO_FROM_TOOL @ e
    np.testing.assert_allclose(de[..., 2, 2], 1.0)
    np.testing.assert_allclose(np.linalg.det(de), 1.0)


def test_exact_chip_thickness_is_the_distance_to_the_previous_path():
    R, f = 62.5, 0.3
    th = np.linspace(0.05, np.pi - 0.05, 50)
    h = chip_thickness(th, f, R, exact=True)
    # The radial ray at theta meets the previous tooth path (circle centred f back) at R - h.
    p = (R - h)[:, None] * np.column_stack([np.sin(th), np.cos(th)])
    np.testing.assert_allclose(np.linalg.norm(p + [f, 0.0], axis=1), R, rtol=1e-12)
    assert chip_thickness(np.pi / 2, f, R) == pytest.approx(f)
    approx = chip_thickness(th, f, R, exact=False)
    assert np.abs(h - approx).max() < f**2 / R


# -- chip area S and edge length l against hand-worked cases ------------------------------------


def test_sharp_corner_with_lead():
    """r = 0, lead 15: parallelogram h d minus the triangular cusp h e / 2, e = h sin cos."""
    g = math.radians(15)
    tb = edge_table(15.0, 0.0, 0.0, 0.0, 12.7)
    h, d = 0.2, 2.0
    S, l = chip_section(tb, h, d)
    e = h * math.sin(g) * math.cos(g)
    assert float(S) == pytest.approx(h * d - h * e / 2, rel=1e-6)
    assert float(l) == pytest.approx(d / math.cos(g) + e / math.sin(g), rel=1e-6)


def test_nose_radius_with_cusp_on_the_arc():
    """r = 0.4, lead 15, h = 0.15 (cusp on the nose): S = h d - scallop area, l = straight part
    (d - c) / cos(lead) + arc r (pi/2 - lead + asin(h / 2r)), c = r (1 - sin(lead))."""
    g, r, h, d = math.radians(15), 0.4, 0.15, 2.0
    tb = edge_table(15.0, 0.0, 0.0, r, 12.7)
    S, l = chip_section(tb, h, d)
    scallop = h * r - h / 2 * math.sqrt(r * r - h * h / 4) - r * r * math.asin(h / (2 * r))
    assert float(S) == pytest.approx(h * d - scallop, rel=1e-5)
    c = r * (1 - math.sin(g))
    assert tb.tangent_height_mm == pytest.approx(c, rel=1e-4)
    expected_l = (d - c) / math.cos(g) + r * (math.pi / 2 - g + math.asin(h / (2 * r)))
    assert float(l) == pytest.approx(expected_l, rel=1e-5)


def test_depth_inside_the_nose():
    """d below the cusp height: the chip is the cup under d, S = W(d) = the circle segment."""
    r, h = 0.4, 0.3
    tb = edge_table(15.0, 0.0, 0.0, r, 12.7)
    d = 0.01  # cusp height for h = 0.3 is 0.4 - sqrt(0.16 - 0.0225) = 0.0292
    S, _ = chip_section(tb, h, d)
    half = math.acos((r - d) / r)
    segment = r * r * (half - math.sin(half) * math.cos(half))
    assert float(S) == pytest.approx(segment, rel=1e-3)


def test_zero_lead_wiper_and_axial_rake_projection():
    # Zero lead: the minor edge is a wiper on the floor, no scallop; l = (d - r) + r pi / 2.
    tb = edge_table(0.0, 0.0, 0.0, 0.4, 12.7)
    S, l = chip_section(tb, 0.15, 2.0)
    assert float(S) == pytest.approx(0.3, rel=1e-9)
    assert float(l) == pytest.approx(1.6 + 0.4 * math.pi / 2, rel=1e-5)
    # Axial rake alone, sharp corner: the rake face is tilted, S = h d / cos(nu), l = d / cos(nu).
    ga = math.radians(7)
    tb = edge_table(0.0, 0.0, 7.0, 0.0, 12.7)
    assert tb.cos_nu == pytest.approx(math.cos(ga))
    S, l = chip_section(tb, 0.15, 2.0)
    assert float(S) == pytest.approx(0.3 / math.cos(ga), rel=1e-9)
    assert float(l) == pytest.approx(2.0 / math.cos(ga), rel=1e-6)


@settings(max_examples=50, deadline=None)
@given(
    st.floats(5, 30),
    st.floats(-10, 10),
    st.floats(-10, 10),
    st.floats(0.0, 1.2),
    st.floats(0.01, 0.4),
    st.floats(0.5, 4.0),
)
def test_area_is_linear_in_depth_above_the_cusp_and_conserves_volume(gl, gr, ga, r, h, d):
    """Above the cusp, each extra mm of depth adds exactly h of section (volume conservation)."""
    tb = edge_table(gl, gr, ga, r, 12.7)
    s1, l1 = chip_section(tb, h, d)
    s2, l2 = chip_section(tb, h, d + 0.5)
    assert float(s2 - s1) * tb.cos_nu == pytest.approx(0.5 * h, rel=1e-6)
    assert float(l2) > float(l1)
    assert float(chip_section(tb, h * 1.1, d)[0]) > float(s1)


def test_insert_the_model_cannot_describe():
    with pytest.raises(AnalysisError, match="undercut"):
        edge_table(-5.0, 0.0, 0.0, 0.4, 12.7)
    tool = FaceMill(
        kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15, axial_rake_deg=7,
        radial_rake_deg=0, nose_radius_mm=0.4,
    )  # fmt: skip
    with pytest.raises(AnalysisError, match="exceeds"):
        chip_section(edge_table(15.0, 0.0, 7.0, 0.4, 12.7), 0.2, 20.0)
    assert tool.depth_limit_mm < 12.7
