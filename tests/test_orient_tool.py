"""planning.orient.tool: frame, angles, Szende's K (eq 8) vs closed forms and silhouettes, solid."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from analysis.config import EndMill
from analysis.errors import ConfigError
from analysis.validation import validate
from planning.errors import PlanningError
from planning.orient.tool import (
    ToolSystem,
    cutter_position,
    local_frame,
    meridian,
    szende_K,
    tool_axis,
)

FRAME = local_frame(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))

angles = st.tuples(st.floats(0.0, 15.0), st.floats(-90.0, 90.0)).map(np.radians)


@settings(max_examples=200, deadline=None)
@given(angles, st.floats(1.0, 30.0))
def test_ball_K_is_one_over_R_for_any_angles(ab, R):
    assert szende_K(ab[0], ab[1], R, R) == pytest.approx(1.0 / R, rel=1e-12)


def test_flat_K_closed_forms_at_known_angles():
    R = 5.0
    a = np.radians([1.0, 5.0, 10.0, 15.0])
    assert np.allclose(szende_K(a, 0.0, R, 0.0), np.sin(a) / R)  # tilted ellipse, minor axis end
    assert np.allclose(szende_K(a, np.pi / 2, R, 0.0), 1 / (R * np.sin(a) ** 2))  # major axis end
    assert szende_K(0.0, 0.0, R, 0.0) == 0.0  # flat bottom parallel: sweeps a plane
    assert np.isinf(szende_K(0.0, 0.3, R, 0.0))  # bottom edge seen edge-on: a sharp corner
    # A fillet tilted sideways only shows its corner radius.
    assert szende_K(0.0, 0.4, 6.0, 2.0) == pytest.approx(0.5)


def _silhouette_curvature(alpha, beta, R, r):
    """Curvature at the lowest point of the tool's silhouette seen along f, by sampling."""
    b, f, n = FRAME
    u = tool_axis(np.asarray(alpha), np.asarray(beta), b, f, n)
    e1 = np.cross(u, b if abs(u @ b) < 0.9 else f)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    t = np.linspace(0, 2 * np.pi, 400_001)
    ring = (R - r) * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)  # corner-centre circle
    x, y = ring @ b, ring @ n  # projected along f
    k = int(np.argmin(y))
    # Curvature of the projected closed curve at its lowest point (parametric formula).
    h = t[1] - t[0]
    xd, yd = (x[k + 1] - x[k - 1]) / (2 * h), (y[k + 1] - y[k - 1]) / (2 * h)
    xdd, ydd = (x[k + 1] - 2 * x[k] + x[k - 1]) / h**2, (y[k + 1] - 2 * y[k] + y[k - 1]) / h**2
    kc = abs(xd * ydd - yd * xdd) / (xd * xd + yd * yd) ** 1.5
    return 1.0 / (1.0 / kc + r)  # the tool outline is the ring's outline offset by r


@pytest.mark.parametrize("R,r", [(5.0, 0.0), (6.0, 2.0), (10.0, 4.0)])
@pytest.mark.parametrize("a_deg,b_deg", [(5, 0), (10, 30), (15, -60), (3, 80), (12, 10)])
def test_K_matches_the_projected_silhouette(R, r, a_deg, b_deg):
    a, b = np.radians(a_deg), np.radians(b_deg)
    assert szende_K(a, b, R, r) == pytest.approx(_silhouette_curvature(a, b, R, r), rel=2e-4)


@settings(max_examples=200, deadline=None)
@given(angles)
def test_tool_axis_is_unit_and_recovers_its_angles(ab):
    """The tool axis stays a unit vector and within its limits (angles read back from u)."""
    b, f, n = FRAME
    u = tool_axis(np.asarray(ab[0]), np.asarray(ab[1]), b, f, n)
    assert np.linalg.norm(u) == pytest.approx(1.0, abs=1e-12)
    assert u @ n == pytest.approx(np.cos(ab[0]) * np.cos(ab[1]), abs=1e-12)
    alpha = np.arcsin(np.clip(u @ f, -1, 1))
    assert 0.0 - 1e-12 <= alpha <= np.radians(15) + 1e-12
    assert alpha == pytest.approx(ab[0], abs=1e-9)
    if np.cos(ab[0]) > 1e-9:
        assert np.arctan2(-(u @ b), u @ n) == pytest.approx(ab[1], abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(angles, st.sampled_from([(5.0, 0.0), (6.0, 2.0), (5.0, 5.0)]))
def test_cutter_touches_the_cc_point_from_outside(ab, Rr):
    """The CC point lies on the tool surface, with the material side (-n) outside the tool."""
    R, r = Rr
    tool = ToolSystem(R, r, 40.0, 12.0, 40.0, 40.0, 80.0)
    b, f, n = FRAME
    p = np.array([1.0, 2.0, 3.0])
    u = tool_axis(np.asarray(ab[0]), np.asarray(ab[1]), b, f, n)
    tip, centre = cutter_position(p, n, u, R, r)
    assert np.allclose(centre, tip + r * u)
    pts = np.stack([p, p + 1e-3 * n, p - 1e-3 * n])
    sd, which = tool.signed_distance(*meridian(pts, tip, u))
    assert abs(sd[0]) < 1e-7 and which[0] == 0
    assert sd[2] > 0  # the material side is outside the tool
    if r > 0:  # a flat end mill touches with its sharp edge, along which n may run
        assert sd[1] < 0


def test_signed_distance_is_exact_against_a_dense_outline():
    tool = ToolSystem(6.0, 2.0, 50.0, 12.0, 40.0, 40.0, 80.0)
    prof = tool.profile(n_arc=400)
    # Densify the outline polyline (every 0.01 mm) and compare outside distances.
    seg = np.concatenate(
        [
            np.linspace(a, b, max(2, int(np.linalg.norm(b - a) / 0.01)))
            for a, b in zip(prof[:-1], prof[1:])
        ]
    )
    rng = np.random.default_rng(5)
    q = np.stack([rng.uniform(0, 60, 3000), rng.uniform(-20, 200, 3000)], 1)
    sd, _ = tool.signed_distance(q[:, 0], q[:, 1])
    brute, _ = cKDTree(seg).query(q)
    out = sd > 0
    assert out.sum() > 1000
    assert np.allclose(sd[out], brute[out], atol=0.02)
    assert np.all(sd[~out] <= 0)


def test_bad_tools_give_clear_messages():
    with pytest.raises(
        PlanningError, match=r"corner radius r = 7.0 mm with tool radius R = 5.0 mm"
    ):
        ToolSystem(5.0, 7.0, 40.0, 12.0, 40.0, 40.0, 80.0, name="bad")
    with pytest.raises(ConfigError, match=r"corner_radius_mm = 8.0: a bull end mill needs 0 <"):
        validate(
            EndMill,
            {
                "kind": "bull",
                "diameter_mm": 10.0,
                "corner_radius_mm": 8.0,
                "flute_length_mm": 20.0,
                "flutes": 2,
            },
            "tools.toml",
        )
