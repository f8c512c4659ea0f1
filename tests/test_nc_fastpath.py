"""The vectorised path for runs of plain G0/G1 blocks (``Interpreter(fast=True)``, the default)
gives bit for bit the Motion, state, warnings and errors of the block-by-block path."""

from __future__ import annotations

import pytest
from _fastpath import check_fast_is_slow, same_motion
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planning.nc import FAST_MIN_RUN, present_mask
from planning.nc.errors import NCError
from planning.nc.interpreter import Interpreter
from planning.nc.motion import Motion
from planning.nc.run import interpret, iter_motion_chunks

# ---------------------------------------------------------------- generated programs
_num = st.one_of(
    st.integers(-500, 500).map(str),
    st.floats(-500, 500, allow_nan=False).map(lambda v: f"{v:.4f}"),
    st.floats(-50, 50, allow_nan=False).map(lambda v: f"{v:.3f}".rstrip("0")),
    st.sampled_from(
        ["0", "-0", "+0.", "-.5", ".25", "1.", "-0.0", "123456789012", "3.14159265358979"]
    ),
)
_sp = st.sampled_from(["", " ", "  ", "\t", " (c) ", "(x;y)"])


@st.composite
def _plain(draw) -> str:
    words = []
    if draw(st.booleans()):
        words.append("N" + str(draw(st.integers(0, 99999))))
    if draw(st.integers(0, 2)):
        words.append(draw(st.sampled_from(["G0", "G1", "G00", "G01", "g1", "G 1"])))
    axes = draw(st.lists(st.sampled_from("XYZ"), min_size=1, max_size=3, unique=True))
    for a in "XYZ":
        if a in axes:
            words.append(a + draw(_num))
    if draw(st.integers(0, 4)) == 0:
        words.append(
            "F" + draw(st.sampled_from(["300", "1200.5", "0", "-5", "20", "1e3", "99999"]))
        )
    text = draw(_sp).join(words) if draw(st.booleans()) else " ".join(words)
    if draw(st.integers(0, 5)) == 0:
        text = text.lower()
    if draw(st.integers(0, 6)) == 0:
        text += draw(st.sampled_from([" ; note", " (done)", "(ü)", "  "]))
    return text + draw(st.sampled_from(["\n", "\r\n", ""]))


_other = st.sampled_from(
    [
        "G90", "G91", "G20", "G21", "G1 F250", "G0", "G1", "F400", "G94", "G93", "G93 G1 X1 F2",
        "G94 F300", "G92 X1 Y2", "G92.1", "G10 L2 P1 X5 Y-3 Z1", "G10 L20 P2 X1", "G55", "G54",
        "G2 X10 Y0 I5 J0", "G3 X0 Y0 R5", "G81 X1 Y1 R2 Z-1 F100", "G80", "X1 Y1", "M3 S1000",
        "M5", "M8", "M9", "T2 M6", "M0", "M2", "%", "", "(comment only)", "/G1 X9", "G4 P0.5",
        "G17", "G18", "G43 H1", "G41 D1", "G40", "G1 A10", "G1 X1 A5", "G53 G0 X0", "N5",
        "G1 X1 X2", "G1 X", "G1 X(c)1", "G1 X1 ) ", "G1 X1234567890123", "G1 X1\x00Y2", "G2",
        "G1 X1. Y2.5 F1000 M3", "G0 X-0 Y-0 Z-0", "G92 X-0 Y-0", "S20000 M4", "O100",
    ]
)  # fmt: skip


@st.composite
def _programs(draw) -> list[str]:
    lines = [draw(st.sampled_from(["G21 G90 G17 G94", "G20 G91", "G21", ""]))]
    if draw(st.booleans()):
        lines.append("G1 F" + draw(st.sampled_from(["500", "12.5"])))
    for _ in range(draw(st.integers(1, 8))):
        if draw(st.integers(0, 2)):
            lines += draw(st.lists(_plain(), min_size=0, max_size=3 * FAST_MIN_RUN))
        else:
            lines += draw(st.lists(_other, min_size=1, max_size=3))
    return lines


_SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.mark.long
@_SETTINGS
@given(_programs(), st.sampled_from(["fanuc", "linuxcnc", "grbl"]), st.booleans())
def test_generated_programs_same_with_and_without_the_fast_path(lines, dialect, strict):
    check_fast_is_slow(lines, dialect=dialect, strict=strict)


@pytest.mark.long
@_SETTINGS
@given(_programs(), st.integers(1, 40))
def test_generated_programs_same_in_chunks(lines, chunk):
    check_fast_is_slow(lines, chunk=chunk)


@settings(max_examples=100, deadline=None)
@given(st.lists(_plain(), min_size=FAST_MIN_RUN, max_size=60), st.booleans(), st.booleans())
def test_plain_runs_under_offsets(lines, inch, incremental):
    head = [
        "G20" if inch else "G21",
        "G10 L2 P1 X1.5 Y-2.25 Z0.125",
        "G92 X3 Y4",
        "M3 S1200 M8",
        "G91" if incremental else "G90",
        "G1 F100",
    ]
    check_fast_is_slow(head + lines)
    check_fast_is_slow(head + lines, chunk=7)


# ---------------------------------------------------------------- specific cases
def _plain_lines(n: int, fmt: str = "G1 X{i} Y{j}\n") -> list[str]:
    return [fmt.format(i=i * 0.5, j=-i * 0.25) for i in range(n)]


def test_fast_path_used_and_identical_for_a_long_run():
    lines = [
        "G21 G90 G94\n",
        "G1 F500\n",
        *_plain_lines(500),
        "G91\n",
        *_plain_lines(300, "X{i} Z{j}\n"),
        "M2\n",
    ]
    check_fast_is_slow(lines)
    check_fast_is_slow(lines, chunk=64)
    m = interpret(lines)
    assert len(m) == 800 and m.line[0] == 3 and m.block[-1] == 802


def test_feed_move_with_no_feed_same_error():
    lines = ["G21 G90\n", *_plain_lines(40, "G0 X{i} Y{j}\n"), *_plain_lines(40)]
    with pytest.raises(NCError) as fast:
        interpret(lines, file="a.ngc")
    with pytest.raises(NCError) as slow:
        interpret(lines, file="a.ngc", fast=False)
    assert str(fast.value) == str(slow.value) and fast.value.line == 42
    check_fast_is_slow(lines)


def test_bad_feed_in_a_run_same_error():
    lines = ["G1 F100\n", *_plain_lines(20), "G1 X1 Y2 F-3\n", *_plain_lines(20)]
    check_fast_is_slow(lines)


def test_feed_above_machine_max_warns_the_same():
    lines = ["G1 F100\n", *_plain_lines(20), "G1 X1 Y2 F9000\n", *_plain_lines(20)]
    it_f = Interpreter(fast=True)
    it_f._feed_max_mm_min = 5000.0
    it_s = Interpreter(fast=False)
    it_s._feed_max_mm_min = 5000.0
    same_motion(it_f.run(lines), it_s.run(lines))
    assert len(it_f.warnings) == 1 and repr(it_f.warnings) == repr(it_s.warnings)


def test_negative_zero_positions_kept():
    lines = ["G10 L2 P1 X-0 Y-0 Z-0\n", "G54 G91 G1 F100\n", "G90 G0 X-0 Y-0 Z-0\n", "G91\n"]
    lines += ["G1 X-0\n", "G1 Y0\n", "G1 Z-0.0\n"] * 10
    check_fast_is_slow(lines)


def test_stream_of_a_file_same(tmp_path):
    path = tmp_path / "p.ngc"
    body = (
        "".join(_plain_lines(3000))
        + "G2 X0 Y0 R900\n"
        + "".join(_plain_lines(3000, "g1x{i}y{j}(c)\r\n"))
    )
    path.write_text("G21 G90 G94\nG1 F500\n" + body + "M30\n")
    fast = Motion.concatenate(list(iter_motion_chunks(path, chunk_blocks=1000)))
    slow = Motion.concatenate(list(iter_motion_chunks(path, chunk_blocks=1000, fast=False)))
    same_motion(fast, slow)
    assert len(fast) == 6001


def test_present_mask_of_mixed_columns():
    for col in [("", "1"), ("1", ""), ("5", "", ""), ("", "-2.5", "", "33", ""), ("7",), ("",)]:
        assert present_mask(col, len(col)).tolist() == [c != "" for c in col]
