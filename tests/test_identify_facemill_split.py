"""Which face-mill coefficients a design identifies, from the design alone (issue 33): the cutting
and edge columns of each direction, their partial correlation and its inflation
(analysis.identify.facemill_split). The figures on independent data are in
tests/test_facemill_independent.py; here the decision on designs built to show each case."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.config import FaceMill
from analysis.forces.facemill import FaceMillCut, facemill_design
from analysis.identify.facemill_split import SPLIT_INFLATION_LIMIT, design_split, pair_inflation

TOOL = FaceMill(kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15, axial_rake_deg=7,
                radial_rake_deg=0, nose_radius_mm=0.4)  # fmt: skip
DEPTHS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
THETA = 2 * np.pi * np.arange(720) / 720


def _design(feeds, width_mm=50.0, offset_mm=0.0):
    return np.vstack([
        facemill_design(THETA, TOOL, FaceMillCut(fz_mm=f, depth_mm=d, width_mm=width_mm,
                                                 center_offset_mm=offset_mm)).reshape(-1, 6)
        for f in feeds for d in DEPTHS
    ])  # fmt: skip


def test_inflation_of_two_columns_at_a_known_angle():
    """Each pair at its own angle, orthogonal to the rest: the partial correlation is the
    cosine and the inflation 1 / sin of the angle (the cutting term's standard error with the
    edge term free over it with the edge term fixed)."""
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(200, 6)))
    X = np.empty((200, 6))
    for (c, e), deg in zip(((1, 0), (3, 2), (5, 4)), (10.0, 45.0, 80.0)):
        X[:, e] = q[:, e] * 3.0
        X[:, c] = np.cos(np.radians(deg)) * q[:, e] + np.sin(np.radians(deg)) * q[:, c]
    corr, infl = pair_inflation(X)
    for d, deg in zip("TRA", (10.0, 45.0, 80.0)):
        assert corr[d] == pytest.approx(np.cos(np.radians(deg)), abs=1e-9)
        assert infl[d] == pytest.approx(1 / np.sin(np.radians(deg)), rel=1e-9)
    # and as a ratio of standard errors, edge term free against fixed
    cov = np.linalg.inv(X.T @ X)
    keep = [0, 1, 3, 4, 5]
    fixed = np.linalg.inv(X[:, keep].T @ X[:, keep])
    assert np.sqrt(cov[3, 3] / fixed[2, 2]) == pytest.approx(infl["R"], rel=1e-9)


def test_seed003_one_feed_design_holds_force_per_depth_only():
    """Seed 003's design (0.236 mm/tooth, 0.5..3 mm, 50 mm wide): the arc spans 66-114 deg,
    where sin(theta) (the chip's shape) barely moves, so the cutting and edge columns correlate
    0.998 and the split is inflated ~15 x: K's are force per depth only, P's not identified."""
    s = design_split(_design((0.236,)), [0.236], edge_supported=False, lead_deg=15.0)
    assert all(v > SPLIT_INFLATION_LIMIT for v in s.inflation.values()), s.inflation
    for k in ("K_T_n_mm2", "K_R", "K_A"):
        assert s.status[k].startswith("identified as force per depth only (one feed)"), s.status
        assert "f = 0.236 mm/tooth" in s.status[k] and not s.identified[k]
    assert s.status["K_R"].startswith("identified as force per depth only (one feed): "
                                      "K_R K_T f + P_R / cos(15 deg)")  # fmt: skip
    for k in ("P_T_n_mm", "P_R_n_mm", "P_A_n_mm"):
        assert s.status[k].startswith("not identified: the design does not split"), s.status
    assert "K_T, K_R, K_A identified as force per depth only" in s.clause()


def test_one_feed_over_a_wide_block_splits_by_the_chips_shape():
    """The same feed over 120 mm of a 125 mm cutter: the arc spans 16-164 deg, the chip's
    shape along the pass tells the cutting force from the edge force, and the design splits them
    (inflation < 5): the K's are identified; the P's still wait for the feeds (size effect)."""
    s = design_split(_design((0.236,), width_mm=120.0), [0.236], edge_supported=False,
                     lead_deg=15.0)  # fmt: skip
    assert all(v < SPLIT_INFLATION_LIMIT for v in s.inflation.values()), s.inflation
    assert [s.status[k] for k in ("K_T_n_mm2", "K_R", "K_A")] == ["identified"] * 3
    assert s.status["P_T_n_mm"].startswith("not identified: the runs do not separate edge")
    assert s.clause() == ""


def test_three_feeds_split_every_direction():
    s = design_split(_design((0.1, 0.236, 0.345)), [0.1, 0.236, 0.345], edge_supported=True,
                     lead_deg=15.0)  # fmt: skip
    assert all(v < SPLIT_INFLATION_LIMIT for v in s.inflation.values()), s.inflation
    assert set(s.status.values()) == {"identified"} and all(s.identified.values())


def test_a_ratio_needs_its_own_direction_and_the_tangential_one():
    """K_R = (K_R K_T) / K_T: when only the radial pair is collinear, K_R and P_R are not
    identified (several feeds: not 'per depth') while K_T, K_A, P_T, P_A are."""
    X = _design((0.1, 0.236, 0.345))
    X[:, 2] = X[:, 3] * 0.4 + 1e-4 * np.abs(X[:, 3]).max() * np.sin(np.arange(len(X)))
    s = design_split(X, [0.1, 0.236, 0.345], edge_supported=True, lead_deg=15.0)
    assert s.inflation["R"] > 100 and s.inflation["T"] < SPLIT_INFLATION_LIMIT
    bad = {k for k, v in s.identified.items() if not v}
    assert bad == {"K_R", "P_R_n_mm"}, s.status
    assert s.status["K_R"].startswith("not identified: the design does not split")
    assert "R: cutting and edge columns correlate" in s.status["K_R"]
