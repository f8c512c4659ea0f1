"""planning.orient.kinematics: AC inverse kinematics: round trips, limits, CL CSV, G-code."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.config import load_machine
from planning.errors import PlanningError
from planning.orient.kinematics import forward, inverse, nc_program, write_cl_csv

ROOT = Path(__file__).resolve().parent.parent


def machine(kind="table-table-AC", **five):
    m = load_machine(ROOT / "configs" / "machines" / "mill-5axis.toml")
    fa = m.five_axis.model_copy(update={"kind": kind, **five})
    return m.model_copy(update={"five_axis": fa})


unit_axes = (
    st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.05, 1))
    .filter(lambda v: np.linalg.norm(v) > 0.1)
    .map(lambda v: np.asarray(v) / np.linalg.norm(v))
)


@settings(max_examples=150, deadline=None)
@given(
    st.lists(unit_axes, min_size=1, max_size=6),
    st.sampled_from(["table-table-AC", "head-table-AC"]),
    st.integers(0, 1000),
)
def test_inverse_then_forward_is_identity(axes, kind, seed):
    m = machine(kind, pivot_mm=(10.0, -5.0, -100.0), head_pivot_length_mm=150.0)
    axes = np.asarray(axes)
    tips = np.random.default_rng(seed).uniform(-60, 60, (len(axes), 3))
    mv = inverse(m, tips, axes, gauge_length_mm=90.0, check_limits=False)
    t2, u2 = forward(kind, m, mv, 90.0)
    # Round trip to float error of the rotations: 1e-7 mm at the tip, and 1e-9 on the unit axis
    # (1e-9 rad tilts a 100 mm tool by 1e-7 mm at its end); a wrong angle is off by >> 1e-6.
    assert np.allclose(t2, tips, atol=1e-7)
    assert np.allclose(u2, axes, atol=1e-9)
    a = m.five_axis.a
    assert np.all((mv.a_deg >= a.min_deg - 1e-9) & (mv.a_deg <= a.max_deg + 1e-9))


def test_vertical_axis_keeps_c_and_needs_no_tilt():
    m = machine()
    axes = np.array([[0.0, 0.6, 0.8], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    mv = inverse(m, np.zeros((3, 3)), axes)
    assert np.allclose(mv.a_deg[1:], 0.0, atol=1e-12)
    assert mv.c_deg[1] == mv.c_deg[0] == mv.c_deg[2]  # C stays put at the singular pose


def test_c_is_unwrapped_continuously_through_a_full_turn():
    m = machine()  # C travel -360..360 deg: a turn and a bit in one direction fits
    ang = np.radians(np.arange(0, 400, 10))
    axes = np.stack([0.5 * np.cos(ang), 0.5 * np.sin(ang), np.full_like(ang, np.sqrt(0.75))], 1)
    mv = inverse(m, np.zeros_like(axes), axes)
    assert np.max(np.abs(np.diff(mv.c_deg))) < 10.0 + 1e-9
    assert np.ptp(mv.c_deg) == pytest.approx(390.0)


def test_axis_limits_are_named():
    m = machine()  # A limits -120..30
    with pytest.raises(
        PlanningError, match=r"CL point 1: tool axis .* outside the A limits \[-120, 30\]"
    ):
        inverse(m, np.zeros((2, 3)), np.array([[0, 0, 1.0], [0, 0, -1.0]]))
    with pytest.raises(PlanningError, match=r"CL point 0: X = 500.000 mm is outside the travel"):
        inverse(m, np.array([[500.0, 0, 0]]), np.array([[0, 0, 1.0]]))
    with pytest.raises(PlanningError, match="five_axis.kind = 'head-head-AC' is not supported"):
        inverse(machine("head-head-AC"), np.zeros((1, 3)), np.array([[0, 0, 1.0]]))
    with pytest.raises(PlanningError, match="expected a unit vector"):
        inverse(m, np.zeros((1, 3)), np.array([[0, 0, 2.0]]))
    no5 = m.model_copy(update={"five_axis": None})
    with pytest.raises(PlanningError, match=r"has no \[five_axis\] section"):
        inverse(no5, np.zeros((1, 3)), np.array([[0, 0, 1.0]]))


def test_gcode_reads_back_through_planning_nc(tmp_path):
    from planning.nc import LINE, Program, interpret, segment_time_s

    m = machine()
    rng = np.random.default_rng(4)
    axes = rng.normal(size=(12, 3)) * [0.3, 0.3, 0] + [0, 0, 1]
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    tips = rng.uniform(-40, 40, (12, 3))
    line = np.repeat([0, 1, 2], 4)
    mv = inverse(m, tips, axes)
    for tips_mm in (None, tips):
        text = nc_program(mv, line, 900.0, 8000.0, tips_mm=tips_mm)
        (tmp_path / "p.nc").write_text(text)
        prog = Program.read(tmp_path / "p.nc")  # strict parse by the NC package
        motion = interpret(prog, m)
        cuts = motion.kind == LINE
        assert cuts.sum() == 12  # a plunge and 3 cutting blocks per line
        ends, rot = motion.end[cuts], motion.rotary_end_deg[cuts]
        assert np.allclose(ends, mv.as_array()[:, :3], atol=1e-4)
        assert np.allclose(rot[:, [0, 2]], mv.as_array()[:, 3:], atol=1e-4)
        back = type(mv)(ends[:, 0], ends[:, 1], ends[:, 2], rot[:, 0], rot[:, 2], mv.kind)
        t2, u2 = forward(mv.kind, m, back, 0.0)
        assert np.allclose(t2, tips, atol=5e-4)
        assert np.allclose(u2, axes, atol=5e-6)
        t = segment_time_s(motion, m)[cuts]
        plunge = line != np.roll(line, 1)
        assert np.all(motion.feed_mm_min[cuts][plunge] == 900.0)
        if tips_mm is None:  # G94: F over millimetres and degrees together
            assert np.all(motion.feed_mm_min[cuts] == 900.0)
        else:  # G93: the tip crosses the part at 900 mm/min
            chord = np.linalg.norm(np.diff(tips, axis=0), axis=1)[~plunge[1:]]
            np.testing.assert_allclose(t[~plunge], chord / 900.0 * 60.0, rtol=1e-5)


def test_cl_csv_has_one_row_per_feasible_point(tmp_path):
    from types import SimpleNamespace

    m = 5
    ok = np.array([True, True, False, True, True])
    cc = SimpleNamespace(
        line=np.zeros(m, int),
        u=np.arange(m) / 4,
        v=np.zeros(m),
        point=np.ones((m, 3)),
        kappa_per_mm=np.zeros(m),
    )
    nan3 = np.where(ok[:, None], 1.0, np.nan) * np.ones((m, 3))
    res = SimpleNamespace(
        feasible=ok,
        cc=cc,
        tip_mm=nan3,
        centre_mm=nan3,
        axis=nan3 / np.sqrt(3),
        alpha_deg=np.ones(m),
        beta_deg=np.zeros(m),
        K_per_mm=np.ones(m),
        clearance_mm=np.zeros(m),
    )
    write_cl_csv(tmp_path / "cl.csv", res)
    df = pd.read_csv(tmp_path / "cl.csv")
    assert list(df["index"]) == [0, 1, 3, 4]
    assert np.isfinite(df.to_numpy()).all()
