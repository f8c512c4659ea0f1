"""Machining time with acceleration (planning.nc.accel) against closed forms and invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.config import load_machine
from analysis.errors import ConfigError
from planning.nc import interpret, motion_stats, segment_time_s
from planning.nc.accel import accel_segment_time_s, segment_tangents

A = 500.0  # mm/s^2
DELTA = 0.01  # mm


def _t(text: str, accel: float = A, delta: float = DELTA) -> np.ndarray:
    m = interpret(text)
    return accel_segment_time_s(m, accel, delta, segment_time_s(m))


def _line_time(length: float, v: float, a: float = A) -> float:
    """Rest to rest over ``length`` at most at ``v``: trapezoid or triangle."""
    if v * v / a <= length:
        return length / v + v / a
    return 2 * math.sqrt(length / a)


def test_a_long_line_from_rest_to_rest_is_a_trapezoid() -> None:
    t = _t("G1 X100 F1200")  # 20 mm/s: 0.04 s to reach, 0.4 mm each way
    assert t.sum() == pytest.approx(100 / 20 + 20 / A, rel=1e-12)


def test_a_short_line_never_reaches_its_feed() -> None:
    t = _t("G1 X0.2 F6000")  # 100 mm/s would need 20 mm
    assert t.sum() == pytest.approx(2 * math.sqrt(0.2 / A), rel=1e-12)


def test_collinear_blocks_cost_what_one_block_does() -> None:
    split = _t("G1 X10 F3000\nX10.5\nX30\nX70")
    assert split.sum() == pytest.approx(_line_time(70, 50), rel=1e-12)


def test_a_right_angle_corner_slows_to_the_junction_deviation_speed() -> None:
    v = 50.0
    sin_half = math.sin(math.pi / 4)
    vj = math.sqrt(A * DELTA * sin_half / (1 - sin_half))
    assert vj < v
    leg = (v - 0) / A + (v - vj) / A + (40 - (v**2) / (2 * A) - (v**2 - vj**2) / (2 * A)) / v
    assert _t("G1 X40 F3000\nY40").sum() == pytest.approx(2 * leg, rel=1e-12)


def test_a_reversal_stops_and_a_dwell_stops() -> None:
    one = _line_time(10, 50)
    assert _t("G1 X10 F3000\nX0").sum() == pytest.approx(2 * one, rel=1e-12)
    assert _t("G1 X10 F3000\nG4 X0.5\nG1 X20").sum() == pytest.approx(2 * one + 0.5, rel=1e-12)


def test_a_feed_change_carries_the_lower_speed_through_the_junction() -> None:
    # 50 mm/s then 10 mm/s on a straight line: the junction runs at 10 mm/s.
    t = _t("G1 X40 F3000\nX80 F600")
    first = 50 / A + (50 - 10) / A + (40 - 50**2 / (2 * A) - (50**2 - 10**2) / (2 * A)) / 50
    second = 10 / A + (40 - 10**2 / (2 * A)) / 10
    assert t.sum() == pytest.approx(first + second, rel=1e-12)


def test_an_arc_runs_at_most_at_its_centripetal_speed() -> None:
    # Full circle R 2 at 6000 mm/min: sqrt(a R) = 31.6 mm/s < 100 mm/s.
    t = _t("G0 X2 Y0\nG2 X2 Y0 I-2 J0 F6000")
    v = math.sqrt(A * 2)
    assert t[1] == pytest.approx(_line_time(2 * math.pi * 2, v), rel=1e-12)


def test_a_line_running_tangentially_into_an_arc_does_not_slow_down() -> None:
    # A line along +X, then a CCW quarter arc starting tangentially: one smooth path.
    r = 50.0
    path = f"G1 X20 F1200\nG3 X{20 + r} Y{r} I0 J{r}"
    t = _t(path)
    length = 20 + math.pi * r / 2
    assert t.sum() == pytest.approx(_line_time(length, 20), rel=1e-9)


def test_rotary_moves_count_in_corners_and_lengths() -> None:
    # Five collinear A steps are one move; an A reversal under straight X slows the path.
    one = _t("G1 A60 F3000").sum()
    assert _t("G1 A10 F3000\nA20\nA30\nA40\nA50\nA60").sum() == pytest.approx(one, rel=1e-12)
    assert one == pytest.approx(_line_time(60, 50), rel=1e-12)
    straight = _t("G1 X30 A30 F3000").sum()
    assert _t("G1 X10 A10 F3000\nX20 A0\nX30 A10").sum() > straight * 1.1


def test_the_path_stops_where_the_spindle_tool_or_coolant_changes() -> None:
    one = _line_time(10, 50)
    for change in ("S500 M3", "M8", "T2 M6"):
        t = _t(f"G1 X10 F3000\n{change}\nX20").sum()
        assert t == pytest.approx(2 * one, rel=1e-12), change


def test_helix_tangents_are_unit_and_follow_the_lead() -> None:
    m = interpret("G1 X10 Y0 F600\nG3 X10 Y0 Z-2 I-10 J0")
    t0, t1 = segment_tangents(m)
    np.testing.assert_allclose(np.linalg.norm(t0, axis=1), 1, rtol=1e-12)
    lead = -2 / (2 * math.pi * 10)
    expect = np.array([0, 1, lead]) / math.hypot(1, lead)
    np.testing.assert_allclose(t0[1], expect, atol=1e-12)
    np.testing.assert_allclose(t1[1], expect, atol=1e-12)


moves = st.lists(
    st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-5, 5), st.floats(10, 8000)),
    min_size=1,
    max_size=25,
)


@settings(max_examples=60, deadline=None)
@given(moves, st.floats(10, 5000), st.floats(0.001, 0.5))
def test_acceleration_only_adds_time_and_vanishes_when_it_is_huge(path, accel, delta) -> None:
    text = "\n".join(f"G1 X{x:.3f} Y{y:.3f} Z{z:.3f} F{f:.1f}" for x, y, z, f in path)
    m = interpret(text)
    plain = segment_time_s(m)
    t = accel_segment_time_s(m, accel, delta, plain)
    assert np.all(t >= plain * (1 - 1e-9))
    huge = accel_segment_time_s(m, 1e12, delta, plain)
    np.testing.assert_allclose(huge, plain, rtol=1e-3, atol=1e-6)
    # More acceleration never makes the program slower.
    assert accel_segment_time_s(m, 2 * accel, delta, plain).sum() <= t.sum() * (1 + 1e-9)


def test_the_machine_config_gives_the_stats_their_accel_time() -> None:
    machine = load_machine("ace-h63")
    assert machine.accel_mm_s2 is not None
    m = interpret("G0 X0 Y0 Z5\nG1 Z0 F500\nG1 X100 F3000\nG0 Z5", machine)
    s = motion_stats(m, machine)
    assert s.accel_time_s > s.time_s
    bare = motion_stats(m, machine.model_copy(update={"accel_mm_s2": None}))
    assert bare.accel_time_s is None and bare.time_s == s.time_s


def test_a_bad_acceleration_is_named(tmp_path) -> None:
    from analysis.config import MachineConfig
    from analysis.validation import load_model

    text = tmp_path / "m.toml"
    base = (
        'name = "m"\nrapid_mm_min = 10000\nfeed_min_mm_min = 1\nfeed_max_mm_min = 5000\n'
        "spindle_max_rpm = 8000\naccel_mm_s2 = -3\n"
        "[x]\nmin_mm = -1\nmax_mm = 1\n[y]\nmin_mm = -1\nmax_mm = 1\n[z]\nmin_mm = -1\nmax_mm = 1\n"
    )
    text.write_text(base)
    with pytest.raises(ConfigError) as e:
        load_model(MachineConfig, text)
    msg = str(e.value)
    assert "m.toml:6" in msg and "accel_mm_s2" in msg and "-3" in msg and "mm/s^2" in msg
