"""G93 inverse-time feed: each feed move takes 1/F minutes (feed = path length * F), F is not modal,
switching G93/G94 needs a new F; times, restart and refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planning.nc import (
    Interpreter,
    NCError,
    Program,
    interpret,
    restart_preamble,
    segment_time_s,
    state_at_block,
)
from planning.nc.edit import split_moves


def test_line_takes_one_over_f_minutes_in_mm_and_inch():
    m = interpret("G93 G1 X30 F2")
    assert m.feed_mm_min[0] == pytest.approx(60.0)  # 30 mm in 0.5 min
    assert segment_time_s(m)[0] == pytest.approx(30.0)
    m = interpret("G20 G93 G1 X1 F2")  # F is 1/min whatever the units
    assert m.feed_mm_min[0] == pytest.approx(2 * 25.4)
    assert segment_time_s(m)[0] == pytest.approx(30.0)


def test_arcs_and_helices_use_their_path_length():
    m = interpret("G0 X0 Y0\nG93 G2 X10 Y0 I5 J0 F4\nG3 X10 Y0 Z6 I-5 J0 F3")
    np.testing.assert_allclose(segment_time_s(m)[1:], [15.0, 20.0])  # 60/F s each
    np.testing.assert_allclose(
        m.feed_mm_min[1:], [5 * math.pi * 4, math.hypot(10 * math.pi, 6) * 3]
    )


def test_rapids_unaffected_and_f_not_modal():
    m = interpret("G93 G0 X100\nG1 X110 F6")
    assert math.isnan(m.feed_mm_min[0]) and m.feed_mm_min[1] == pytest.approx(60.0)
    with pytest.raises(NCError, match="every feed move needs its own F") as info:
        interpret("G93 G1 X1 F2\nX2")
    assert (info.value.line, info.value.column, info.value.word) == (2, 1, "X2")


def test_switching_modes_needs_a_new_feed():
    with pytest.raises(NCError, match="no feed rate set"):
        interpret("G94 G1 X1 F100\nG93 G1 X2 F10\nG94 G1 X3")
    m = interpret("G94 G1 X1 F100\nG93 G1 X2 F10\nG94 G1 X3 F200")
    np.testing.assert_allclose(m.feed_mm_min, [100, 10, 200])


def test_refusals():
    with pytest.raises(NCError, match="moves no axis"):
        interpret("G93 G1 X0 F2")  # no travel at all: 1/F min of standing still
    # A rotary-only move is a segment of its own and takes 1/F min (feed counts degrees).
    m = interpret("G93 G1 X0 A90 F2")
    assert m.feed_mm_min[0] == pytest.approx(180.0)
    assert segment_time_s(m)[0] == pytest.approx(30.0)
    with pytest.raises(NCError, match="canned cycles"):
        interpret("G93 G81 X1 Z-1 R1 F2")
    with pytest.raises(NCError, match="must be > 0"):
        interpret("G93 G1 X1 F0")
    prog = Program.parse("G93 G1 X10 F2\nG94 G1 X20 F100\n")
    with pytest.raises(NCError, match="inverse-time feed G93 are not split"):
        split_moves(prog, {0: [(1.0, 50.0)]})
    assert split_moves(prog, {1: [(1.0, 50.0)]}).get_word(1, "F") is not None


def test_restart_inside_g93_reproduces_the_rest():
    prog = Program.parse("G0 X0 Y0 Z1\nG93 G1 Z-1 F30\nX10 F6\nG2 X20 Y0 I5 J0 F2\nG1 Y5 F1\n")
    whole = interpret(prog)
    for n in (2, 3, 4):
        st = state_at_block(prog, n)
        pre = restart_preamble(st)
        assert pre[0].split()[3] == "G94" and pre[-1].endswith("G93")
        resumed = Interpreter().run(pre + prog.lines[n:], first_line=1 - len(pre))
        rest = resumed[resumed.line >= 1]
        expect = whole[whole.block >= n]
        assert rest.same_path(expect, atol_mm=1e-9)
        np.testing.assert_allclose(segment_time_s(rest), segment_time_s(expect))
