"""End-mill linear edge-force model: closed forms, helix, up/down, runout, ball/bull, elements."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.config import EndMill, EndMillCoefficients, FaceMill
from analysis.errors import AnalysisError
from analysis.forces.endmill import (
    EndMillCut,
    coefficient_vector,
    element_forces,
    endmill_design,
    endmill_forces,
    immersion_angles,
    mean_force_design,
    peak_force,
)

COEF = EndMillCoefficients(
    Ktc_n_mm2=796, Krc_n_mm2=168, Kac_n_mm2=222, Kte_n_mm=27.7, Kre_n_mm=30.8, Kae_n_mm=1.8
)
FLAT = EndMill(kind="flat", diameter_mm=10, flute_length_mm=22, flutes=3, helix_deg=30)
STRAIGHT = FLAT.model_copy(update={"helix_deg": 0.0, "flutes": 1})
BALL = EndMill(kind="ball", diameter_mm=10, corner_radius_mm=5, flute_length_mm=20, flutes=2)
PHI = np.linspace(0, 2 * np.pi, 3600, endpoint=False)


def test_straight_tooth_slot_matches_hand_formula():
    """One straight tooth slotting at phi = 90 deg: F_r along +X on the workpiece, F_t along -Y."""
    a, fz = 2.0, 0.1
    cut = EndMillCut(fz, a, 0.0, 180.0)
    f = endmill_forces(np.array([np.pi / 2]), STRAIGHT, COEF, cut)[0]
    ft = (COEF.Ktc_n_mm2 * fz + COEF.Kte_n_mm) * a
    fr = (COEF.Krc_n_mm2 * fz + COEF.Kre_n_mm) * a
    fa = (COEF.Kac_n_mm2 * fz + COEF.Kae_n_mm) * a
    np.testing.assert_allclose(f, [fr, -ft, fa], rtol=1e-9)


@settings(max_examples=15, deadline=None)
@given(
    st.sampled_from(["up", "down", "slot"]),
    st.floats(0.5, 10.0),
    st.floats(0.01, 0.2),
    st.floats(0.5, 10.0),
    st.integers(1, 6),
    st.floats(0, 45),
)
def test_closed_form_mean_equals_the_revolution_average(mode, ae, fz, depth, flutes, helix):
    tool = FLAT.model_copy(update={"flutes": flutes, "helix_deg": helix})
    cut = EndMillCut.from_width(tool, fz, depth, ae, mode)
    closed = mean_force_design(tool, cut)
    numeric = endmill_design(PHI[:, None], tool, cut, n_discs=32).mean(axis=0)[0]
    # 0.1 deg sampling: one sample of a narrow immersion is ~0.4 % of its arc.
    np.testing.assert_allclose(closed, numeric, atol=1e-2 * np.abs(closed).max())


def test_up_and_down_milling_engage_the_right_side():
    up = immersion_angles(2.0, 10.0, "up")
    down = immersion_angles(2.0, 10.0, "down")
    span = math.acos(1 - 2 * 2.0 / 10.0)
    assert (float(up[0]), float(up[1])) == pytest.approx((0.0, span))
    assert (float(down[0]), float(down[1])) == pytest.approx((math.pi - span, math.pi))
    # Up milling: chip starts at zero thickness, force starts at the edge forces only.
    cut = EndMillCut.from_width(STRAIGHT, 0.1, 1.0, 2.0, "up")
    f = endmill_forces(np.array([1e-6, span / 2, span + 0.01]), STRAIGHT, COEF, cut)
    assert np.linalg.norm(f[0]) == pytest.approx(math.hypot(27.7, 30.8), rel=1e-3)
    assert np.all(f[2] == 0)


def test_helix_spreads_the_force_but_keeps_the_mean():
    straight = FLAT.model_copy(update={"helix_deg": 0.0})
    cut = EndMillCut(0.1, 10.0, 0.0, 180.0)
    f0 = endmill_forces(PHI, straight, COEF, cut)
    f30 = endmill_forces(PHI, FLAT, COEF, cut)
    np.testing.assert_allclose(f0.mean(axis=0), f30.mean(axis=0), rtol=2e-3, atol=0.05)
    assert np.ptp(np.linalg.norm(f30, axis=1)) < np.ptp(np.linalg.norm(f0, axis=1))


def test_runout_makes_teeth_unequal():
    cut = EndMillCut(0.05, 2.0, 0.0, 180.0, runout_mm=0.01)
    tool = FLAT.model_copy(update={"helix_deg": 0.0})
    f = np.linalg.norm(endmill_forces(PHI, tool, COEF, cut), axis=1)
    per_tooth = f.reshape(3, -1).max(axis=1)
    assert np.ptp(per_tooth) / per_tooth.mean() > 0.1
    f0 = np.linalg.norm(endmill_forces(PHI, tool, COEF, EndMillCut(0.05, 2.0, 0.0, 180.0)), axis=1)
    assert np.ptp(f0.reshape(3, -1).max(axis=1)) < 1e-6 * f0.max()


def test_ball_end_mill_chip_area_and_elements():
    """A ball's chip area at any depth a is f a sin(phi), as for a flat end mill (the chip is
    thinner near the tip by sin(kappa) but the edge is longer by 1/sin(kappa)); its edge is
    longer (rc * kappa_max > a), and the whole-cutter model equals the sum of element forces."""
    a, fz = 0.5, 0.1
    ball1 = BALL.model_copy(update={"flutes": 1, "helix_deg": 0.0})
    d_ball = endmill_design(np.array([np.pi / 2]), ball1, EndMillCut(fz, a), n_discs=400)[0]
    d_flat = endmill_design(np.array([np.pi / 2]), STRAIGHT, EndMillCut(fz, a))[0]
    # Cutting part: the Ktc column's tangential component is minus the chip area along -Y.
    assert -d_ball[1, 0] == pytest.approx(fz * a, rel=2e-3)
    assert -d_flat[1, 0] == pytest.approx(fz * a, rel=1e-9)
    assert -d_ball[1, 3] == pytest.approx(5.0 * math.acos(1 - a / 5.0), rel=1e-3)  # arc length
    # Rebuild the ball (no helix, one flute) from elements at the disc mid-heights.
    tool = BALL.model_copy(update={"flutes": 1, "helix_deg": 0.0})
    m, a, rc = 400, 3.0, 5.0
    z = (np.arange(m) + 0.5) * a / m
    kappa = np.arccos((rc - z) / rc)
    h = 0.1 * np.sin(kappa)
    # The whole-cutter model takes each disc's exact arc length; give the element that db.
    k_edges = np.arccos((rc - np.linspace(0, a, m + 1)) / rc)
    dz = rc * np.diff(k_edges) * np.sin(kappa)
    el = element_forces(np.pi / 2, h, dz, kappa, COEF).sum(axis=0)
    whole = endmill_forces(np.array([np.pi / 2]), tool, COEF, EndMillCut(0.1, a), n_discs=400)[0]
    np.testing.assert_allclose(el, whole, rtol=5e-3)


def test_feed_direction_rotates_the_force():
    cut0 = EndMillCut(0.1, 2.0, 0.0, 180.0)
    cut90 = EndMillCut(0.1, 2.0, 0.0, 180.0, feed_angle_deg=90.0)
    f0 = endmill_forces(PHI[:10], FLAT, COEF, cut0)
    f90 = endmill_forces(PHI[:10], FLAT, COEF, cut90)
    np.testing.assert_allclose(f90[:, 0], -f0[:, 1], atol=1e-9)
    np.testing.assert_allclose(f90[:, 1], f0[:, 0], atol=1e-9)
    np.testing.assert_allclose(f90[:, 2], f0[:, 2], atol=1e-9)


def test_vectorised_peak_force_grows_with_feed_and_depth():
    fz = np.array([0.05, 0.1, 0.2])
    p = peak_force(FLAT, COEF, EndMillCut(fz, 2.0, 0.0, 180.0))
    assert p.shape == (3,) and np.all(np.diff(p) > 0)
    p_depth = peak_force(FLAT, COEF, EndMillCut(0.1, np.array([1.0, 2.0, 4.0]), 0.0, 180.0))
    assert np.all(np.diff(p_depth) > 0)
    assert coefficient_vector(COEF).shape == (6,)


def test_bad_input():
    fm = FaceMill(kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15,
                  axial_rake_deg=7, radial_rake_deg=0, nose_radius_mm=0.4)  # fmt: skip
    with pytest.raises(AnalysisError, match="face mill"):
        endmill_forces(PHI, fm, COEF, EndMillCut(0.1, 1.0))
    with pytest.raises(AnalysisError, match="flute length"):
        endmill_forces(PHI, FLAT, COEF, EndMillCut(0.1, 30.0))
    with pytest.raises(AnalysisError, match="radial width"):
        immersion_angles(12.0, 10.0, "down")
    with pytest.raises(AnalysisError, match="mode"):
        immersion_angles(2.0, 10.0, "sideways")


def test_runout_thickens_the_chip_of_the_tooth_after_the_short_one():
    # Hand-worked: 3 straight flutes, runout e = 0.01 mm towards 0 deg, so the radii are
    # R + e cos(-k 120 deg): +e, -e/2, -e/2 for teeth 0, 1, 2. Tooth k sits at phi + k 120 deg, so
    # tooth k + 1 passes a point a tooth period before tooth k and cut the surface it meets:
    # h_k = fz sin(theta) + r_k - r_(k+1): h0 = fz + 1.5 e, h1 = fz, h2 = fz - 1.5 e at theta 90.
    # At theta = 90 deg the tangential force on the workpiece is -Y, the radial +X:
    # Fx = (Krc h + Kre) b, Fy = -(Ktc h + Kte) b, b = 2 mm (only that tooth is in the slot).
    tool = FLAT.model_copy(update={"helix_deg": 0.0, "runout_mm": 0.01})
    cut = EndMillCut(0.05, 2.0, 0.0, 180.0)
    phi = np.radians([90.0, 330.0, 210.0])  # tooth 0, 1, 2 at 90 deg
    f = endmill_forces(phi, tool, COEF, cut)
    expect_x = [168 * 0.065 * 2 + 30.8 * 2, 168 * 0.05 * 2 + 30.8 * 2, 168 * 0.035 * 2 + 30.8 * 2]
    expect_y = [-(796 * 0.065 * 2 + 27.7 * 2), -(796 * 0.05 * 2 + 27.7 * 2),
                -(796 * 0.035 * 2 + 27.7 * 2)]  # fmt: skip
    np.testing.assert_allclose(f[:, 0], expect_x, rtol=1e-9)
    np.testing.assert_allclose(f[:, 1], expect_y, rtol=1e-9)
