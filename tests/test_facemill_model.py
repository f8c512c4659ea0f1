"""Seed 003 face-milling forces: engagement, inserts, tilt, depth behaviour, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.config import EndMill, FaceMill, FaceMillCoefficients
from analysis.errors import AnalysisError
from analysis.forces.facemill import (
    FaceMillCut,
    coefficient_vector,
    coefficients_from_vector,
    engagement_angles,
    facemill_forces,
    insert_loads,
    rotation_inverse,
)

TOOL = FaceMill(
    kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15, axial_rake_deg=7,
    radial_rake_deg=0, nose_radius_mm=0.4,
)  # fmt: skip
COEF = FaceMillCoefficients(
    K_T_n_mm2=405.4, K_R=1.1, P_T_n_mm=39.7, P_R_n_mm=19.6, K_A=0.35, P_A_n_mm=8.0
)
TH = np.linspace(0, 2 * np.pi, 720, endpoint=False)  # 0.5 deg steps


def test_no_force_outside_the_workpiece():
    """Each height of the chip enters on its own ray (issue 33): nothing before the chip's
    innermost point (the earlier pass's surface, f inside the nose's radius) reaches the block's
    edge, the whole insert in within a degree after the nose's acos(50 / 62.5)."""
    cut = FaceMillCut(fz_mm=0.236, depth_mm=2.0, width_mm=100.0)
    f = facemill_forces(TH, TOOL, COEF, cut)
    st, ex = engagement_angles(100.0, 62.5)
    first, last = engagement_angles(100.0, 62.5 - 0.236)
    assert np.all(f[(TH < first) | (TH > last)] == 0)
    inside = (TH >= st + np.radians(1.0)) & (TH <= ex - np.radians(1.0))
    assert np.all(np.linalg.norm(f[inside], axis=1) > 50)
    assert math.degrees(st) == pytest.approx(math.degrees(math.acos(50 / 62.5)))


def test_insert_forces_follow_eqs_3_4_through_m_inverse():
    """At theta = 90 deg the insert sits on +X' and cuts towards -Y': rebuild the dynamometer force
    by hand from S, l, eqs 3-4 and [M]^-1."""
    cut = FaceMillCut(fz_mm=0.236, depth_mm=2.0, width_mm=100.0)
    th = np.array([np.pi / 2])
    loads = insert_loads(th, TOOL, cut)
    S, l = loads.S_mm2[0, 0], loads.l_mm[0, 0]
    f_ins = np.array(
        [
            COEF.P_T_n_mm * l + COEF.K_T_n_mm2 * S,
            COEF.P_R_n_mm * l + COEF.K_R * COEF.K_T_n_mm2 * S,
            COEF.P_A_n_mm * l + COEF.K_A * COEF.K_T_n_mm2 * S,
        ]
    )
    f_tra = rotation_inverse(*np.radians([15, 0, 7])) @ f_ins
    # T = -Y', R = +X', A = +Z' at theta = 90 deg.
    expected = np.array([f_tra[1], -f_tra[0], f_tra[2]])
    np.testing.assert_allclose(facemill_forces(th, TOOL, COEF, cut)[0], expected, rtol=1e-12)


def test_several_inserts_superpose_and_eccentricity_moves_chip_between_them():
    tool4 = TOOL.model_copy(update={"inserts": 4})
    cut = FaceMillCut(fz_mm=0.2, depth_mm=1.5, width_mm=120.0)
    f4 = facemill_forces(TH, tool4, COEF, cut)
    f1 = sum(facemill_forces(TH + k * np.pi / 2, TOOL, COEF, cut) for k in range(4))
    np.testing.assert_allclose(f4, f1, atol=1e-9)
    # With eccentricity the mean chip is the same but the inserts cut unequal chips.
    ecc = tool4.model_copy(update={"runout_mm": 0.03})
    spot = 1.2  # each insert in turn passes this angle; their radius changes telescope
    rot = spot - np.arange(4) * np.pi / 2
    h = insert_loads(rot, ecc, cut).h_mm[np.arange(4), np.arange(4)]
    assert h.max() - h.min() > 0.05
    assert h.sum() == pytest.approx(4 * float(insert_loads(np.array([spot]), TOOL, cut).h_mm[0, 0]))


def test_uneven_pitch_shares_the_feed_by_gap():
    """Inserts at 0 and 120 deg: at a given spot insert 0 follows insert 1 after 120 deg of
    rotation (chip 2/3 of 2 fz... i.e. f_rev / 3), insert 1 follows insert 0 after 240 deg."""
    tool = TOOL.model_copy(update={"inserts": 2, "insert_angles_deg": (0.0, 120.0)})
    cut = FaceMillCut(0.2, 1.0, entry_deg=0, exit_deg=180)
    rot = np.array([np.pi / 2, np.pi / 2 - np.radians(120.0)])  # each insert on the spot
    h = insert_loads(rot, tool, cut).h_mm[[0, 1], [0, 1]]
    f_rev = 2 * 0.2
    assert h[0] == pytest.approx(f_rev / 3, rel=1e-9)
    assert h[1] == pytest.approx(2 * f_rev / 3, rel=1e-9)


def test_force_grows_linearly_with_depth_above_the_nose():
    f = [
        facemill_forces(TH, TOOL, COEF, FaceMillCut(0.236, d, 100.0)).mean(axis=0)
        for d in (1.0, 1.5, 2.0, 2.5)
    ]
    second = np.diff(np.array(f), 2, axis=0)
    # the entry and exit take each height in on its own ray: on 0.5 deg steps a sample inside
    # the entry band is not linear in the depth (7.5e-4 of the mean here; 1e-6 away from it)
    assert np.abs(second).max() < 1e-3 * np.abs(f).max()


def test_spindle_tilt_lowers_the_depth_away_from_the_low_point():
    cut0 = FaceMillCut(0.236, 1.0, 100.0)
    cut = FaceMillCut(0.236, 1.0, 100.0, tilt_deg=0.56, tilt_low_deg=90.0)
    d = insert_loads(TH, TOOL, cut).depth_mm[:, 0]
    assert d[180] == pytest.approx(1.0)  # theta = 90 deg, the low point
    drop = 62.5 * math.sin(math.radians(0.56)) * (1 - math.cos(math.radians(30)))  # theta 60 deg
    assert d[120] == pytest.approx(1.0 - drop)
    f0 = np.linalg.norm(facemill_forces(TH, TOOL, COEF, cut0), axis=1)
    f = np.linalg.norm(facemill_forces(TH, TOOL, COEF, cut), axis=1)
    assert np.all(f <= f0 + 1e-9) and f[120] < f0[120]


def test_vectorised_over_conditions():
    depth = np.linspace(0.5, 3.0, len(TH))
    f = facemill_forces(TH, TOOL, COEF, FaceMillCut(0.236, depth, 100.0))
    one = facemill_forces(TH[200:201], TOOL, COEF, FaceMillCut(0.236, depth[200], 100.0))
    np.testing.assert_allclose(f[200], one[0])


def test_coefficient_vector_round_trip():
    np.testing.assert_allclose(
        coefficient_vector(coefficients_from_vector(coefficient_vector(COEF))),
        coefficient_vector(COEF),
    )


def test_bad_input():
    em = EndMill(kind="flat", diameter_mm=10, flute_length_mm=20, flutes=3)
    with pytest.raises(AnalysisError, match="face mill|facemill"):
        facemill_forces(TH, em, COEF, FaceMillCut(0.2, 1.0))
    with pytest.raises(AnalysisError, match="deeper"):
        facemill_forces(TH, TOOL, COEF, FaceMillCut(0.2, 15.0))
    with pytest.raises(AnalysisError, match=">= 0"):
        facemill_forces(TH, TOOL, COEF, FaceMillCut(-0.2, 1.0))
    undercut = TOOL.model_copy(update={"lead_angle_deg": -5.0})
    with pytest.raises(AnalysisError, match="undercut"):
        facemill_forces(TH, undercut, COEF, FaceMillCut(0.2, 1.0))
