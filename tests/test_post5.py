"""planning.orient.kinematics as a post: forward kinematics of every posted block back to the
planned pose, the singular pose (C held), G93 feeds within every axis' speed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.config import load_machine
from planning.errors import PlanningError
from planning.orient.kinematics import (
    axis_speeds,
    check_forward,
    hold_c,
    inverse,
    inverse_time_feeds,
)

ROOT = Path(__file__).resolve().parent.parent
KINDS = ["table-table-AC", "head-head-BC", "head-table-AC"]


def machine(kind="table-table-AC", **five):
    m = load_machine(ROOT / "configs" / "machines" / "mill-5axis.toml")
    fa = m.five_axis.model_copy(update={"kind": kind, **five})
    return m.model_copy(update={"five_axis": fa})


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


poses = st.lists(
    st.tuples(
        st.floats(-1, 1),
        st.floats(-1, 1),
        st.floats(0.2, 1),  # axis, upper half
        st.floats(-80, 80),
        st.floats(-80, 80),
        st.floats(-80, 80),  # tip, mm
    ),
    min_size=1,
    max_size=8,
)


@settings(max_examples=200, deadline=None)
@given(poses, st.sampled_from(KINDS), st.floats(0, 200))
def test_every_posted_block_goes_back_to_its_pose(rows, kind, gauge_mm):
    m = machine(kind, pivot_mm=(15.0, -10.0, -120.0), head_pivot_length_mm=150.0)
    rows = np.asarray(rows)
    axes, tips = unit(rows[:, :3]), rows[:, 3:]
    mv = inverse(m, tips, axes, gauge_length_mm=gauge_mm, check_limits=False)
    e_mm, e_rad = check_forward(m, mv, tips, axes, gauge_mm)  # raises past 1e-6 mm / 1e-6 rad
    assert e_mm < 1e-6 and e_rad < 1e-6
    # Independently of forward(): the axis the machine points, written out per kinematics.
    A, C = np.radians(mv.a_deg), np.radians(mv.c_deg)
    sA, cA, sC, cC = np.sin(A), np.cos(A), np.sin(C), np.cos(C)
    if kind == "table-table-AC":  # Rz(-C) Rx(-A) z
        u = np.stack([sA * sC, sA * cC, cA], 1)
    elif kind == "head-table-AC":  # Rz(-C) Rx(A) z
        u = np.stack([-sA * sC, -sA * cC, cA], 1)
    else:  # Rz(C) Ry(B) z
        u = np.stack([sA * cC, sA * sC, cA], 1)
    assert np.allclose(u, axes, atol=1e-9)


def test_a_wrong_block_is_named():
    m = machine()
    axes = unit([[0, 0.3, 1], [0.2, 0.1, 1]])
    mv = inverse(m, np.zeros((2, 3)), axes)
    bad = type(mv)(mv.x, mv.y, mv.z, mv.a_deg + [0, 1e-3], mv.c_deg, mv.kind)
    with pytest.raises(PlanningError, match=r"CL point 1: forward kinematics .* off the planned"):
        check_forward(m, bad, np.zeros((2, 3)), axes, 0.0)


@pytest.mark.parametrize("kind", KINDS)
def test_passing_near_the_c_axis_holds_c(kind):
    """A line whose axis passes 0.3 deg from the C axis: C swings by about 180 deg across it,
    59 deg in one block, unless it is held; held, no block turns C by more than 30 deg and no
    axis moves more than the cone."""
    m = machine(kind)
    s = np.linspace(-1, 1, 41)
    tilt = np.radians(np.hypot(10 * s, 0.3))  # 10 deg either side, 0.3 deg at the closest
    az = np.arctan2(0.3, 10 * s)
    axes = np.stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)], 1)
    line = np.zeros(len(s), int)
    raw = inverse(m, np.zeros_like(axes), axes, check_limits=False)
    assert np.abs(np.diff(raw.c_deg)).max() > 30 and np.ptp(raw.c_deg) > 170
    held = hold_c(kind, axes, line, 3.0)
    turn = np.degrees(np.arccos(np.clip((held * axes).sum(1), -1, 1)))
    assert turn.max() < 3.0 and np.allclose(np.linalg.norm(held, axis=1), 1.0)
    mv = inverse(m, np.zeros_like(held), held, check_limits=False)
    assert np.abs(np.diff(mv.c_deg)).max() <= 30.0
    check_forward(m, mv, np.zeros_like(held), held, 0.0)


def test_g93_feeds_keep_every_axis_within_its_speed():
    m = machine()
    rng = np.random.default_rng(3)
    axes = unit(rng.normal(size=(30, 3)) * [0.4, 0.4, 0] + [0, 0, 1])
    tips = np.cumsum(rng.uniform(-2, 2, (30, 3)), axis=0)
    mv = inverse(m, tips, axes)
    f, why = inverse_time_feeds(m, mv, tips, 2000.0)
    P = mv.as_array()
    t_min = 1.0 / f[1:]  # minutes per block
    d = np.abs(np.diff(P, axis=0))
    # Recomputed from the definitions: tip feed at most 2000 mm/min, combined travel at most
    # feed_max, each rotary axis at most its rapid_deg_min.
    chord = np.linalg.norm(np.diff(tips, axis=0), axis=1)
    assert np.all(chord / t_min <= 2000.0 * (1 + 1e-9))
    assert np.all(np.linalg.norm(d, axis=1) / t_min <= m.feed_max_mm_min * (1 + 1e-9))
    assert np.all(d[:, 3] / t_min <= m.five_axis.a.rapid_deg_min * (1 + 1e-9))
    assert np.all(d[:, 4] / t_min <= m.five_axis.c.rapid_deg_min * (1 + 1e-9))
    assert set(why[1:]) <= {0, 1, 2, 3}
    sp = axis_speeds(m, mv, f, np.zeros(30, int))
    assert sp["feed_max_mm_min"] <= m.feed_max_mm_min * (1 + 1e-9)
