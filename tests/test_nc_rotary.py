"""Rotary axes A/B/C in planning.nc: motion, feeds and times, writing back, restart, refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.config import load_machine
from planning.errors import PlanningError
from planning.nc import (
    LINE,
    RAPID,
    Interpreter,
    NCError,
    Program,
    interpret,
    motion_stats,
    motion_to_program,
    restart_preamble,
    segment_time_s,
    state_at_block,
)
from planning.nc.edit import split_moves
from planning.nc.stats import DEFAULT_ROTARY_RAPID_DEG_MIN, axis_limit_problems


def test_rotary_words_move_with_the_linear_axes_absolute_and_incremental() -> None:
    m = interpret("G0 X0 Y0 Z10\nG1 X10 A30 F600\nG0 A-27 C-46\nG91 G1 C10 F100\nG20 G90 B2")
    np.testing.assert_allclose(m.rotary_start_deg[1:], [[0, 0, 0], [30, 0, 0], [-27, 0, -46],
                                                        [-27, 0, -36]])  # fmt: skip
    np.testing.assert_allclose(m.rotary_end_deg[1:], [[30, 0, 0], [-27, 0, -46], [-27, 0, -36],
                                                      [-27, 2, -36]])  # fmt: skip
    # A rotary-only block is a segment that stands still in X Y Z; G20 leaves degrees alone.
    assert list(m.kind) == [RAPID, LINE, RAPID, LINE, LINE]
    np.testing.assert_array_equal(m.start[2:], m.end[2:])
    assert m.has_rotary_travel.tolist() == [False, True, True, True, True]


def test_feed_counts_millimetres_and_degrees_together() -> None:
    m = interpret("G1 X30 A40 F100\nG1 C90 F900\nG0 C0")
    t = segment_time_s(m)
    assert t[0] == pytest.approx(math.hypot(30, 40) / 100 * 60)  # 0.5 min
    assert t[1] == pytest.approx(90 / 900 * 60)
    assert t[2] == pytest.approx(90 / DEFAULT_ROTARY_RAPID_DEG_MIN * 60)
    five = load_machine("mill-5axis")
    assert segment_time_s(m, five)[2] == pytest.approx(90 / five.five_axis.c.rapid_deg_min * 60)
    # Inverse time: the block takes 1/F min whatever it moves.
    g93 = interpret("G93 G1 X3 A4 F2\nG1 C90 F4")
    np.testing.assert_allclose(segment_time_s(g93), [30.0, 15.0])


def test_rotary_words_in_dwell_home_and_cycle_blocks_are_refused() -> None:
    for text, why in (
        ("G4 X1 A10", "G4"),
        ("G28 Z0 C10", "G28"),
        ("G81 X1 Z-1 R1 F100 A5", "G81"),
    ):
        with pytest.raises(NCError, match=rf"p\.nc:1:\d+: '[ABC]-?[\d.]*': A/B/C words cannot "
                           rf"move in a {why} block"):  # fmt: skip
            interpret(text, file="p.nc")


moves5 = st.lists(
    st.tuples(
        st.sampled_from([0, 1]),
        *[st.floats(-100, 100).map(lambda v: round(v, 3)) for _ in range(3)],
        *[st.floats(-360, 360).map(lambda v: round(v, 3)) for _ in range(3)],
    ),
    min_size=1,
    max_size=20,
)


@settings(max_examples=50, deadline=None)
@given(moves5)
def test_written_programs_read_back_with_their_rotary_moves(moves) -> None:
    text = "\n".join(
        f"G{g} X{x} Y{y} Z{z} A{a} B{b} C{c}" + (" F500" if g else "")
        for g, x, y, z, a, b, c in moves
    )
    m = interpret(text)
    back = interpret(motion_to_program(m))
    keep = (np.linalg.norm(back.end - back.start, axis=1) > 0) | back.has_rotary_travel
    ref = (np.linalg.norm(m.end - m.start, axis=1) > 0) | m.has_rotary_travel
    assert back[keep].same_path(m[ref], atol_mm=1e-9)


def test_restart_turns_the_rotary_axes_before_approaching() -> None:
    prog = Program.parse("G0 X0 Y0 Z10\nG1 Z0 F500\nG1 X10 A30 C-20 F600\nX20 A45\nX30 C10\nX40")
    whole = interpret(prog)
    for n in (3, 4, 5):
        pre = restart_preamble(state_at_block(prog, n))
        assert any(b.startswith("A") and " C" in b for b in pre)
        resumed = Interpreter().run(pre + prog.lines[n:], first_line=1 - len(pre))
        assert resumed[resumed.line >= 1].same_path(whole[whole.block >= n], atol_mm=1e-9)


def test_moves_that_turn_an_axis_are_not_split_nor_simulated() -> None:
    prog = Program.parse("G1 X10 F100\nG1 X20 A10\n")
    assert split_moves(prog, {0: [(0.5, 50.0), (1.0, 100.0)]}).lines[:2] == [
        "G1 X5 F50",
        "X10 F100",
    ]
    with pytest.raises(NCError, match="rotary axes .* are not split"):
        split_moves(prog, {1: [(0.5, 50.0), (1.0, 100.0)]})
    from planning.stock import check_motion

    with pytest.raises(PlanningError, match=r"p\.nc:2: block 1: the block turns a rotary axis"):
        check_motion(interpret(prog), None, file="p.nc")


def test_rotary_limits_of_the_five_axis_machine_are_checked() -> None:
    five = load_machine("mill-5axis")  # A -120..30
    m = interpret("G0 A-20 C100\nG1 X5 A40 F100\nG0 A0", five)
    problems = axis_limit_problems(m, five)
    assert problems == [
        "line 2: A goes to 40 deg, outside machine 'mill-5axis' A limits -120..30 deg"
    ]
    s = motion_stats(m, five)
    assert s.rotary_min_deg == (-20.0, 0.0, 0.0) and s.rotary_max_deg == (40.0, 0.0, 100.0)
    assert axis_limit_problems(m, load_machine("ace-h63")) == []  # no 5-axis section
    # The value named is the one outside the limits, not the larger in size.
    m = interpret("G0 A-100\nG1 X5 A40 F100", five)
    assert axis_limit_problems(m, five)[0].startswith("line 2: A goes to 40 deg")


def test_travel_limits_include_the_bulge_of_arcs() -> None:
    from analysis.config import AxisTravel

    small = load_machine("ace-h63").model_copy(
        update={"y": AxisTravel(min_mm=-8, max_mm=8), "reference_mm": None}
    )
    m = interpret("G1 X5 F100\nG2 X25 I10\nG1 X5000", small)
    assert axis_limit_problems(m, small) == [
        "line 3: X goes to 5000 mm, outside machine 'ace-h63' travel -630..630 mm",
        "line 2: Y goes to 10 mm, outside machine 'ace-h63' travel -8..8 mm",
    ]
