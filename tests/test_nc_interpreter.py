"""Interpreter semantics: words and layout, modal state, units, offsets, M codes, dwell, canned
cycles, strict/lenient modes, the incremental Interpreter and restart from block N."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from analysis.config import load_machine
from planning.nc import (
    DWELL,
    LINE,
    RAPID,
    Interpreter,
    NCError,
    Program,
    arc_sweep_rad,
    interpret,
    interpret_file,
    motion_stats,
    restart_preamble,
    state_at_block,
)

SAMPLE = str(Path(__file__).resolve().parents[1] / "data" / "programs" / "demo-part.nc")


def test_spaceless_lowercase_equals_spaced_uppercase():
    a = interpret("g0x0y0z5\ng1z-1f300\ng1x10y-2.5\ng2x20y-2.5r5")
    b = interpret("G00 X0. Y0. Z5.\nG01 Z-1. F300.\nG01 X10. Y-2.5\nG02 X20 Y-2.5 R5")
    assert a.equals(b) and len(a) == 4


def test_comments_block_delete_percent_o_n():
    text = "\n".join(
        [
            "%",
            "O0042 (NAME ; ok)",
            "N10 G0 X1 Y1 ; move (with parens) inside",
            "/N20 G0 X5 Y5",
            "  (only a comment)",
            "",
            "N30 G0 X2 (mid) Y2",
            "%",
        ]
    )
    it = Interpreter()
    m = it.run(text.splitlines())
    assert len(m) == 2
    np.testing.assert_array_equal(m.end, [[1, 1, 0], [2, 2, 0]])
    np.testing.assert_array_equal(m.line, [3, 7])
    np.testing.assert_array_equal(m.block, [2, 6])
    assert it.state.program_number == 42 and it.state.sequence_number == 30
    # block delete switch off: the deleted block runs
    assert len(interpret(text, block_delete=False)) == 3


def test_units_distance_and_work_offsets():
    m = interpret(
        "G20 G90 G0 X1 Y2 Z0.5\nG91 G0 X1\nG21 G0 Y-10\nG90 G55 G0 X0 Y0\nG53 G0 Z0",
        work_offsets_mm={55: (100.0, 50.0, -20.0)},
    )
    np.testing.assert_allclose(
        m.end,
        [[25.4, 50.8, 12.7], [50.8, 50.8, 12.7], [50.8, 40.8, 12.7], [100, 50, 12.7], [100, 50, 0]],
    )


def test_feed_spindle_tool_coolant_recorded_per_segment():
    m = interpret("T3 M6\nS1200 M4\nM8\nG1 X1 F150\nM3 S900\nM9\nX2\nM5\nG0 X3\nG20 G1 X0.2 F10")
    assert list(m.tool) == [3, 3, 3, 3]
    assert list(m.spindle_rpm) == [-1200, 900, 0, 0]
    assert list(m.coolant) == [True, False, False, False]
    np.testing.assert_allclose(m.feed_mm_min, [150, 150, np.nan, 254], equal_nan=True)


def test_tool_needs_m6_to_change():
    it = Interpreter()
    it.execute("T7")
    assert it.state.tool == 0 and it.state.tool_selected == 7
    it.execute("M6")
    assert it.state.tool == 7


@pytest.mark.parametrize(
    "dialect, words, seconds",
    [
        ("fanuc", "G4 P1500", 1.5),
        ("fanuc", "G4 X2.5", 2.5),
        ("grbl", "G4 P1.5", 1.5),
    ],
)
def test_dwell_units_by_dialect(dialect, words, seconds):
    m = interpret(f"G0 X1\n{words}", dialect=dialect)
    assert m.kind[-1] == DWELL and m.dwell_s[-1] == pytest.approx(seconds)
    np.testing.assert_array_equal(m.start[-1], m.end[-1])


def test_recorded_modes():
    it = Interpreter()
    it.run(["G18 G41 D7 G43 H3 G56 G99 G90.1 G20"])
    s = it.state
    assert (s.plane, s.cutter_comp, s.cutter_comp_d, s.tool_length, s.tool_length_h) == (
        18,
        41,
        7,
        43,
        3,
    )
    assert (s.work_offset, s.retract_initial, s.arc_absolute, s.inch) == (56, False, True, True)


def _moves(m):
    return [(int(k), tuple(np.round(e, 6))) for k, e in zip(m.kind, m.end)]


def test_g81_g98_g99_closed_form():
    m = interpret("G0 X0 Y0 Z20\nG1 F100\nG99 G81 X10 Y0 Z-5 R2\nG98 X20\nG80\nG0 X0")
    assert _moves(m) == [
        (RAPID, (0, 0, 20)),
        (RAPID, (10, 0, 20)),
        (RAPID, (10, 0, 2)),
        (LINE, (10, 0, -5)),
        (RAPID, (10, 0, 2)),
        (RAPID, (20, 0, 2)),
        (LINE, (20, 0, -5)),
        (RAPID, (20, 0, 20)),  # G98: initial level
        (RAPID, (0, 0, 20)),
    ]
    assert np.all(np.isnan(m.feed_mm_min[m.kind == RAPID]))
    assert np.all(m.feed_mm_min[m.kind == LINE] == 100)


def test_g82_dwell_and_g83_pecks():
    m = interpret("G0 X0 Y0 Z10\nG1 F60\nG98 G82 X5 Z-2 R1 P250\nG80")
    assert [int(k) for k in m.kind] == [RAPID, RAPID, RAPID, LINE, DWELL, RAPID]
    assert m.dwell_s[4] == pytest.approx(0.25)
    m = interpret("G0 X0 Y0 Z10\nG1 F60\nG99 G83 X5 Z-7 R1 Q3\nG80", peck_clearance_mm=0.5)
    depths = m.end[m.kind == LINE][:, 2]
    np.testing.assert_allclose(depths, [-2, -5, -7])  # pecks of Q=3 from R=1, last one short
    reentries = m.end[(m.kind == RAPID)][:, 2]
    assert -1.5 in reentries and -4.5 in reentries  # 0.5 mm above the previous peck
    assert m.end[-1, 2] == 1  # G99: back to R


def test_canned_incremental_with_repeats():
    m = interpret("G0 X0 Y0 Z10\nG1 F60\nG91 G99 G81 X10 Z-5 R-8 L3\nG80")
    holes = m.end[m.kind == LINE]
    np.testing.assert_allclose(holes, [[10, 0, -3], [20, 0, -3], [30, 0, -3]])


def test_strict_and_lenient():
    text = "G0 X1\nG5.1 X2\nM99\nE5 X3\nG1 I3 X4 F10"
    with pytest.raises(NCError, match="unknown G-code G5.1") as e:
        interpret(text, file="p.nc")
    assert (e.value.line, e.value.column, e.value.word) == (2, 1, "G5.1")
    it = Interpreter(strict=False, file="p.nc")
    m = it.run(text.splitlines())
    assert len(m) == 4
    assert [w.line for w in it.warnings] == [2, 3, 4, 5]
    assert "unknown M-code M99" in str(it.warnings[1]) and "p.nc:3:1" in str(it.warnings[1])


def test_feed_move_without_feed_is_an_error():
    with pytest.raises(NCError, match="no feed rate") as e:
        interpret("G0 X1\nG1 X2")
    assert e.value.line == 2


def test_after_program_end_is_ignored_with_warning():
    it = Interpreter()
    m = it.run(["G0 X1", "M30", "G0 X5", "%"])
    assert len(m) == 1 and it.state.ended
    assert len(it.warnings) == 1 and it.warnings[0].line == 3


def test_incremental_execute_matches_batch_and_keeps_state_on_error():
    text = Program.read(SAMPLE).lines
    whole = interpret(text)
    it = Interpreter()
    parts = [it.execute(raw, line=i + 1, block=i) for i, raw in enumerate(text)]
    from planning.nc import Motion

    assert Motion.concatenate(parts).equals(whole)
    it = Interpreter()
    it.execute("G0 X5 Y5")
    before = it.state.copy()
    with pytest.raises(NCError):
        it.execute("G20 G2 X0 Y0 R0.01")
    assert it.state == before  # the failed block changed nothing (not even G20)


def test_state_copy_is_independent():
    it = Interpreter()
    it.execute("G81 X1 Z-1 R1 F10")
    snap = it.state.copy()
    it.execute("G98 X2 Z-3")
    assert snap.canned.z_mm == -1 and it.state.canned.z_mm == -3


def test_restart_inside_canned_cycle_is_refused():
    st = state_at_block(Program.read(SAMPLE), 60)  # N540 X20.: second hole of the G83 cycle
    assert st.motion == 83
    with pytest.raises(NCError, match="inside a canned cycle"):
        restart_preamble(st)


def test_restart_preamble_inch_offsets_and_compensation():
    it = Interpreter(work_offsets_mm={55: (100.0, 0.0, -50.0)})
    it.run(["G20 G55 G91.1 T4 M6", "T5", "S2000 M4 M8", "G43 H4 G0 X1 Y2 Z0.5", "G41 D4 G1 X2 F20"])
    pre = restart_preamble(it.state, work_offsets_mm={55: (100.0, 0.0, -50.0)})
    assert pre == [
        "G20 G17 G91.1 G94 G55 G40 G49 G98 G80", "T4 M6", "T5", "S2000 M4", "M8",
        "G90 G0 G43 H4 Z0.5", "X2 Y2", "Z0.5", "F20", "G41 D4", "G90 G1",
    ]  # fmt: skip
    again = Interpreter(work_offsets_mm={55: (100.0, 0.0, -50.0)})
    again.run(pre)
    s1, s2 = it.state, again.state
    assert s2.position_mm == pytest.approx(s1.position_mm)
    names = "inch plane work_offset tool tool_selected spindle_rpm coolant cutter_comp"
    names += " cutter_comp_d tool_length tool_length_h motion"
    for name in names.split():
        assert getattr(s2, name) == getattr(s1, name), name
    assert s2.feed_mm_min == pytest.approx(s1.feed_mm_min)


@pytest.mark.parametrize("n", [0, 9, 20, 37, 56, 57, 59, 65])
def test_restart_from_block_n_reproduces_the_rest(n):
    prog = Program.read(SAMPLE)
    whole = interpret(prog)
    st = state_at_block(prog, n)
    pre = restart_preamble(st)
    resumed = Interpreter().run(pre + prog.lines[n:], first_line=1 - len(pre))
    rest = resumed[resumed.line >= 1]
    expect = whole[whole.block >= n]
    assert rest.same_path(expect, atol_mm=1e-9)


def test_machine_config_sets_tolerance_dialect_and_rapid_time(tmp_path):
    machine = load_machine("lab-grbl")
    m = interpret("G0 X0 Y0\nG1 F100\nG2 X20.001 Y0 I10 J0\nG4 P2", machine)
    assert m.dwell_s[-1] == 2.0  # GRBL: seconds
    with pytest.raises(NCError):
        interpret("G0 X0 Y0\nG1 F100\nG2 X20.01 Y0 I10 J0", machine)
    st = motion_stats(interpret("G0 X30 Y40 Z0"), machine)
    assert st.rapid_time_s == pytest.approx(40 / machine.rapid_mm_min * 60)


def test_stats_closed_form():
    m = interpret("G0 X0 Y0 Z5\nG1 Z0 F60\nG1 X60 F600\nG2 X60 Y0 I-10 J0\nG4 P1000\nG0 Z5")
    st = motion_stats(m, rapid_mm_min=6000)
    circle = 2 * math.pi * 10
    assert st.cutting_length_mm == pytest.approx(5 + 60 + circle)
    assert st.rapid_length_mm == pytest.approx(10)
    assert st.time_s == pytest.approx(5 + 6 + circle / 10 + 1 + 0.1)
    np.testing.assert_allclose(st.bbox_min_mm, (0, -10, 0), atol=1e-3)
    np.testing.assert_allclose(st.bbox_max_mm, (60, 10, 5), atol=1e-3)


def test_interpret_file_streams_same_as_text(tmp_path):
    p = tmp_path / "crlf.nc"
    p.write_bytes(Program.read(SAMPLE).text().replace("\n", "\r\n").encode())
    assert interpret_file(p).equals(interpret(Program.read(SAMPLE)))


def test_machine_limits_warn_and_block_rules():
    machine = load_machine("lab-grbl")
    it = Interpreter(machine)
    it.run(["S30000 M3", "G1 X1 F9000"])
    assert ["spindle_max_rpm" in str(w) for w in it.warnings] == [True, False]
    assert "feed_max_mm_min" in str(it.warnings[1])
    with pytest.raises(NCError, match="both spindle codes"):
        interpret("M3 M4")
    with pytest.raises(NCError, match="cannot share its block with a move"):
        interpret("G4 P100 Y5")


INCH_SAMPLE = Path(SAMPLE).with_name("inch-features.nc")


def test_inch_sample_closed_form():
    it = Interpreter(file=str(INCH_SAMPLE))
    m = it.run(Program.read(INCH_SAMPLE).lines)
    assert [str(w).split(": ", 1)[1] for w in it.warnings] == [
        "'G28': no machine given: the G28 point is taken as machine zero = work zero (0, 0, 0) mm"
        " (give a machine config with reference_mm)"
    ]
    # N230 G28 G91 Z0.: Z alone (intermediate point = here) to the reference point, which
    # without a machine is machine zero; the machine's is 600 mm up
    home = m[m.line == 28]
    np.testing.assert_allclose(home.start, [[38.1, 12.7, 25.4]])
    np.testing.assert_allclose(home.end, [[38.1, 12.7, 0.0]])
    assert home.kind.tolist() == [RAPID]
    m_ace = interpret(INCH_SAMPLE, load_machine("ace-h63"))
    np.testing.assert_allclose(m_ace.end[-1], [38.1, 12.7, 600.0])
    arcs = m[m.is_arc]
    np.testing.assert_array_equal(arcs.plane, [18, 18, 19])
    np.testing.assert_allclose(arcs.center, [[12.7, 0, 0], [38.1, 0, 0], [50.8, 12.7, 0]])
    np.testing.assert_allclose(np.degrees(arc_sweep_rad(arcs)), [180, 180, 180])
    # G18 G2 from X0 to X1": clockwise seen from +Y, where Z points right and X up (Z x X = Y),
    # runs from below the centre through -Z: a groove 0.5" deep
    from planning.nc import linearize

    lin = linearize(arcs, 1e-3)
    for k in range(3):  # all three arcs are grooves (G18 G2, G18 G2, G19 G3)
        assert lin.end[lin.source == k, 2].min() == pytest.approx(-12.7, abs=1e-3)
        assert lin.end[lin.source == k, 2].max() == pytest.approx(0, abs=1e-9)
    # incremental spaceless block, inch feed, block delete skipped (no Z2" rapid)
    line_110 = m[m.line == 16]
    np.testing.assert_allclose(line_110.end, [[38.1, 19.05, 0]])
    assert line_110.feed_mm_min[0] == pytest.approx(8 * 25.4)
    assert m.end[:, 2].max() == pytest.approx(25.4)
    holes = m[(m.kind == LINE) & (m.tool == 4)]
    np.testing.assert_allclose(holes.end, [[12.7, 12.7, -7.62], [25.4, 12.7, -5.08],
                                           [38.1, 12.7, -5.08]])  # fmt: skip
    assert m.dwell_s.sum() == pytest.approx(0.5)  # G82 P250 ms, twice (modal)


def test_g80_with_motion_code_in_one_block():
    m = interpret("G1 F10\nG81 X1 Z-1 R1\nG80 G1 X5")
    assert m.kind[-1] == LINE and tuple(m.end[-1]) == (5, 0, 1)
    with pytest.raises(NCError, match="cannot share a block"):
        interpret("G80 G81 X1 Z-1 R1 F1")


@pytest.mark.parametrize("ending", ["\n", "\r\n", "\r"])
def test_line_endings_and_bom_stream_like_text(tmp_path, ending):
    text = Program.read(SAMPLE).text()
    p = tmp_path / "p.nc"
    p.write_bytes(b"\xef\xbb\xbf" + text.replace("\n", ending).encode())
    want = interpret(text)
    assert interpret(p).equals(want)  # a Path is streamed
    assert interpret(Program.read(p)).equals(want)
    assert Program.read(p).text() == text.replace("\n", ending)  # BOM dropped, ends kept


def test_cutter_compensation_is_named_once_as_not_applied_or_refused():
    it = Interpreter(file="p.nc")
    text = "G0 X0 Y0\nG41 D1 G1 X10 F100\nG40 X20\nG42 D1 X0\nG40 X5"
    motion = it.run(text.splitlines())
    assert [w.line for w in it.warnings] == [2] and "G41" in str(it.warnings[0])
    # The motion is the programmed path, exactly as without the words.
    assert motion.equals(interpret(text.replace("G41 D1 ", "").replace("G42 D1 ", "")))
    with pytest.raises(NCError, match=r"p\.nc:4:1: 'G42': G42 cutter radius compensation"):
        interpret(text.replace("G41 D1 ", ""), cutter_comp="refuse", file="p.nc")


@pytest.mark.parametrize(
    "block,word",
    [("O1001 X1", "O1001"), ("T1 M6", "M6"), ("G41 D1 G1 X1 F100", "G41"), ("G43 H1 Z5", "G43"),
     ("G81 X1 Z-1 R1 F100", "G81"), ("G1 X1 A5 F100", "A5"), ("G90.1", "G90.1")],
)  # fmt: skip
def test_grbl_dialect_refuses_what_grbl_answers_error_20_to(block, word):
    # (a line holding only a program number is taken: the GRBL sender strips it, and so a
    # Fanuc-style program or a plan's own output passes the GRBL machine's check)
    text = f"G21 G90\n{block}\n"
    interpret(text, dialect="fanuc")  # a Fanuc control takes it
    with pytest.raises(NCError, match=rf"p\.nc:2:\d+: '{re.escape(word)}': .*GRBL"):
        interpret(text, dialect="grbl", file="p.nc")
    it = Interpreter(dialect="grbl", strict=False)
    it.run(text.splitlines())
    assert any("GRBL" in w.reason for w in it.warnings)
