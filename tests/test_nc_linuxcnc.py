"""LinuxCNC's interpretation (dialect "linuxcnc"), each feature against a case worked by hand:
order of execution (F before G20/G21), G94 clearing F, path control G61/G61.1/G64 as state,
G10 L2/L20 work offsets and G54..G59.3, G10 L1/L10 tool table, the G92 family and G52, G28/G30
with stored points (G28.1/G30.1), G53, LinuxCNC's arc radius tolerance (spirals), P turns, the
feed of moves with rotary axes, G4 P in seconds before the block's move, LinuxCNC's canned
cycles, its M codes, and restarts after programmed offsets. The expected numbers are written
out here, not computed by the interpreter."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planning.nc import (
    ARC_CW,
    DWELL,
    LINE,
    RAPID,
    Interpreter,
    ModalState,
    NCError,
    interpret,
    restart_preamble,
)


def lcnc(text: str, **kw):
    it = Interpreter(dialect="linuxcnc", reference_mm=(0, 0, 0), **kw)
    return it, it.run(text.splitlines())


def ends(m) -> list[list[float]]:
    return m.end.tolist()


# ---------------------------------------------------------------- order of execution
def test_g20_f6_sets_the_feed_before_the_units_change():
    # LinuxCNC's order: F (step 3) before G20/G21 (step 11); rs274 prints SET_FEED_RATE(6)
    # then USE_LENGTH_UNITS(INCHES): the feed is 6 mm/min, the move 1 in = 25.4 mm
    _, m = lcnc("G21\nG20 F6\nG1 X1")
    assert ends(m) == [[25.4, 0.0, 0.0]]
    assert m.feed_mm_min[0] == 6.0
    _, m = lcnc("G20\nF6\nG1 X1")  # F in its own block: 6 in/min
    assert m.feed_mm_min[0] == pytest.approx(152.4)
    _, m = lcnc("G20\nG21 F100\nG1 X10")  # read under inch: 100 in/min, the move in mm
    assert ends(m) == [[10.0, 0.0, 0.0]] and m.feed_mm_min[0] == pytest.approx(2540.0)
    m = interpret("G20 F6\nG1 X1", dialect="fanuc")  # Fanuc: the block's units apply to F
    assert m.feed_mm_min[0] == pytest.approx(152.4)


def test_g94_always_clears_the_feed():
    with pytest.raises(NCError, match="no feed rate"):
        lcnc("G94 F100\nG94\nG1 X1")
    _, m = lcnc("G94 F100\nG94 F50\nG1 X1")
    assert m.feed_mm_min[0] == 50.0
    assert interpret("G94 F100\nG94\nG1 X1").feed_mm_min[0] == 100.0  # Fanuc keeps it


# ---------------------------------------------------------------- path control
def test_path_control_modes_are_state_and_leave_the_motion_alone():
    it, _ = lcnc("G61")
    assert it.state.path_control == 61
    it, _ = lcnc("G61.1")
    assert it.state.path_control == 61.1
    it, _ = lcnc("G64 P0.05 Q0.02")
    st = it.state
    assert (st.path_control, st.path_tolerance_mm, st.naive_cam_tolerance_mm) == (64, 0.05, 0.02)
    it, _ = lcnc("G64 P0.1")  # Q not given: Q = P
    assert (it.state.path_tolerance_mm, it.state.naive_cam_tolerance_mm) == (0.1, 0.1)
    it, _ = lcnc("G64 P0.1\nG64")  # neither: 0 (as fast as possible)
    assert (it.state.path_tolerance_mm, it.state.naive_cam_tolerance_mm) == (0.0, 0.0)
    it, _ = lcnc("G20 G64 P0.001")  # inch: 0.0254 mm
    assert it.state.path_tolerance_mm == pytest.approx(0.0254)
    path = "G1 X10 F500\nG2 X20 I5\nG1 Y10"
    _, plain = lcnc(path)
    for mode in ("G61", "G61.1", "G64 P0.5 Q0.5"):
        _, m = lcnc(mode + "\n" + path)
        assert m.same_path(plain)
    assert interpret("G61\nG1 X1 F100", dialect="fanuc").end[0, 0] == 1.0  # Fanuc has G61
    with pytest.raises(NCError, match="unknown G-code G61.1"):
        interpret("G61.1", dialect="fanuc")
    with pytest.raises(NCError, match="G64 is not a GRBL 1.1 command"):
        interpret("G64", dialect="grbl")
    with pytest.raises(NCError, match="G64 P must be >= 0"):
        lcnc("G64 P-1")


# ---------------------------------------------------------------- work offsets
def test_g10_l2_sets_work_offsets_p1_to_p9_and_p0():
    it, m = lcnc("G10 L2 P1 X10 Y20 Z-5\nG0 X1 Y1 Z1\nG10 L2 P2 X100\nG55 G0 X0")
    assert ends(m) == [[11.0, 21.0, -4.0], [100.0, 21.0, -4.0]]
    assert it.state.work_offsets_mm[0] == (10.0, 20.0, -5.0)
    assert it.work_offsets_mm[55] == (100.0, 0.0, 0.0)
    _, m = lcnc("G10 L2 P7 X1 Y2 Z3\nG59.1 G0 X0 Y0 Z0")  # P7 = G59.1
    assert ends(m) == [[1.0, 2.0, 3.0]]
    _, m = lcnc("G59.3\nG10 L2 P0 X7\nG0 X0")  # P0: the active system (G59.3)
    assert ends(m) == [[7.0, 0.0, 0.0]]
    # values are absolute under G91 in LinuxCNC; Fanuc adds them
    it, _ = lcnc("G10 L2 P1 X10\nG91 G10 L2 P1 X5")
    assert it.state.work_offsets_mm[0] == (5.0, 0.0, 0.0)
    it = Interpreter(dialect="fanuc")
    it.run(["G10 L2 P1 X10", "G91 G10 L2 P1 X5"])
    assert it.state.work_offsets_mm[0] == (15.0, 0.0, 0.0)
    _, m = lcnc("G20 G10 L2 P1 X1\nG0 X0")  # inch: 25.4 mm
    assert ends(m) == [[25.4, 0.0, 0.0]]


def test_g10_l2_refusals():
    with pytest.raises(NCError, match="P must be in 0..9"):
        lcnc("G10 L2 P10 X1")
    with pytest.raises(NCError, match="rotated coordinate systems"):
        lcnc("G10 L2 P1 R30")
    with pytest.raises(NCError, match="G10 needs L"):
        lcnc("G10 P1 X1")
    with pytest.raises(NCError, match="not one of L2, L20"):
        interpret("G10 L1 P1 Z1", dialect="grbl")
    with pytest.raises(NCError, match="external offset P0"):
        interpret("G10 L2 P0 X1", dialect="fanuc")
    with pytest.raises(NCError, match="unknown G-code G59.1"):
        interpret("G59.1", dialect="fanuc")


def test_g10_l20_makes_the_current_position_read_the_values():
    # at machine (15, 15, 5) in G54 = (10, 10, 0): L20 X0 Y0 makes G54 = (15, 15, 0)
    it, m = lcnc("G10 L2 P1 X10 Y10\nG0 X5 Y5 Z5\nG10 L20 P1 X0 Y0\nG1 X1 Y1 F100")
    assert ends(m)[-1] == [16.0, 16.0, 5.0]
    assert it.state.work_offsets_mm[0] == (15.0, 15.0, 0.0)
    # a system not in use: G55's Z = 5 - 10 = -5
    it, m = lcnc("G0 Z5\nG10 L20 P2 Z10\nG55 G0 Z0")
    assert it.state.work_offsets_mm[1] == (0.0, 0.0, -5.0) and ends(m)[-1] == [0.0, 0.0, -5.0]
    # with a G92 offset of 5 in force, G54 = 15 - 5 - 0 = 10 (the program still reads X0)
    it, m = lcnc("G10 L2 P1 X10\nG0 X5\nG92 X0\nG10 L20 P1 X0\nG0 X1")
    assert it.state.work_offsets_mm[0][0] == 10.0 and ends(m)[-1] == [16.0, 0.0, 0.0]


def test_g53_moves_in_machine_coordinates():
    _, m = lcnc("G10 L2 P1 X10 Y10\nG0 X1 Y1\nG53 G0 X0 Y0\nG53 G1 X5 F100\nG0 X0")
    assert ends(m) == [[11.0, 11.0, 0.0], [0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [10.0, 0.0, 0.0]]
    with pytest.raises(NCError, match="incremental"):
        lcnc("G91 G53 G0 X0")


def test_work_offset_option_takes_g59_x_keys():
    _, m = lcnc("G59.2 G0 X0 Y0 Z0", work_offsets_mm={59.2: (1.0, 2.0, 3.0)})
    assert ends(m) == [[1.0, 2.0, 3.0]]


# ---------------------------------------------------------------- G92 family, G52
def test_g92_family():
    text = "\n".join(
        [
            "G10 L2 P1 X10",
            "G0 X5",  # machine 15
            "G92 X0",  # G92 offset 15 - 10 - 0 = 5
            "G1 X1 F100",  # 16
            "G92.2",  # cancelled, kept
            "G0 X1",  # 11
            "G92.3",  # restored
            "G0 X1",  # 16
            "G92.1",  # cancelled, forgotten
            "G0 X1",  # 11
            "G92.3",  # nothing to restore
            "G0 X2",  # 12
            "G52 X2",  # local offset 2
            "G0 X0",  # 12
            "G55 G0 X0",  # G55 = 0, plus 2
        ]
    )
    it, m = lcnc(text)
    assert [e[0] for e in ends(m)] == [15.0, 16.0, 11.0, 16.0, 11.0, 12.0, 12.0, 2.0]
    assert it.state.g92_offset_mm == (2.0, 0.0, 0.0) and it.state.origin_mm == (2.0, 0.0, 0.0)
    _, m = lcnc("G20\nG0 X1\nG92 X0\nG0 X1")  # inch: the offset is 1 in
    assert ends(m)[-1] == [50.8, 0.0, 0.0]
    with pytest.raises(NCError, match="needs at least one axis word"):
        lcnc("G92")
    with pytest.raises(NCError, match="unknown G-code G92.2"):
        interpret("G92.2", dialect="fanuc")


# ---------------------------------------------------------------- G28 / G30
def test_g28_g30_go_to_the_points_g28_1_g30_1_store():
    text = "G0 X10 Y20 Z30\nG28.1\nG0 X40 Y40 Z40\nG30.1\nG0 X1 Y2 Z3\nG28\nG0 X1 Y2 Z3\nG28 Z5"
    it, m = lcnc(text)
    assert it.state.reference_mm == (10.0, 20.0, 30.0)
    assert it.state.second_reference_mm == (40.0, 40.0, 40.0)
    home = m[m.line == 6]  # no axis word: all axes straight there (the intermediate is here)
    assert home.kind.tolist() == [RAPID] and ends(home) == [[10.0, 20.0, 30.0]]
    home = m[m.line == 8]  # through Z5, then Z alone
    assert ends(home) == [[1.0, 2.0, 5.0], [1.0, 2.0, 30.0]]
    _, m = lcnc("G0 X40 Y40 Z40\nG30.1\nG0 X0 Y0 Z0\nG91 G30 Z0")  # straight up to Z40
    assert ends(m)[-1] == [0.0, 0.0, 40.0]
    with pytest.raises(NCError, match="takes no axis words"):
        lcnc("G28.1 X1")
    with pytest.raises(NCError, match="unknown G-code G28.1"):
        interpret("G28.1", dialect="fanuc")
    with pytest.raises(NCError, match="unknown G-code G29"):
        lcnc("G29 X1")


# ---------------------------------------------------------------- arcs
def test_inch_arc_rounded_to_4_decimals_is_a_spiral_not_an_error():
    # start radius 0.5 in, end radius 0.5001 in: 0.00254 mm apart (more than Fanuc's default
    # 0.002 mm, within LinuxCNC's 0.0028 in); the centre and end are as programmed
    text = "G20 G17 F10\nG0 X0 Y0\nG2 X1.0001 Y0 I0.5 J0"
    with pytest.raises(NCError, match="differs from start radius"):
        interpret(text)
    _, m = lcnc(text)
    arc = m[m.kind == ARC_CW]
    np.testing.assert_allclose(arc.end[0], [25.40254, 0, 0], atol=1e-12)
    np.testing.assert_allclose(arc.center[0], [12.7, 0, 0], atol=1e-12)


@pytest.mark.parametrize(
    "block, ok",
    [
        ("G2 X20.03 Y0 I10 J0", False),  # 0.03 mm > 0.0283 and 0.3 % > 0.1 %
        ("G2 X20.02 Y0 I10 J0", True),  # 0.02 mm <= 0.0283
        ("G2 X100.04 Y0 I50 J0", True),  # 0.04 mm, but 0.08 % <= 0.1 %
        ("G2 X10003 Y0 I5000 J0", False),  # 0.06 %, but 3 mm > 100 x 0.0283 mm
        ("G2 X10.002 Y0 R5", True),  # half chord 5.001 exceeds R by 0.001 <= 0.00127
        ("G2 X10.003 Y0 R5", False),  # by 0.0015 > 0.00127
        ("G2 X0.001 Y0 I0.0005 J0", False),  # radius 0.0005 mm < 0.00127: zero radius
    ],
)
def test_linuxcnc_arc_tolerances(block, ok):
    text = "G0 X0 Y0\nG1 F100\n" + block
    if ok:
        lcnc(text)
    else:
        with pytest.raises(NCError, match="differs from start radius|too small|smaller|zero"):
            lcnc(text)


def test_r_arc_a_hair_over_the_half_chord_has_its_centre_at_the_midpoint():
    _, m = lcnc("G0 X0 Y0\nG2 X10.002 Y0 R5 F100")
    np.testing.assert_allclose(m.center[-1], [5.001, 0, 0], atol=1e-12)


def test_arc_p_turns_are_full_circles_then_the_arc():
    # a CW half circle about (5, 0) with one extra turn: 3 pi in all, Z -3 spread evenly:
    # the full circle ends at Z -3 * 2pi / 3pi = -2
    _, m = lcnc("G0 X0 Y0 Z0\nG2 X10 Y0 I5 J0 P2 Z-3 F100")
    arc = m[m.kind == ARC_CW]
    np.testing.assert_allclose(arc.start, [[0, 0, 0], [0, 0, -2]], atol=1e-12)
    np.testing.assert_allclose(arc.end, [[0, 0, -2], [10, 0, -3]], atol=1e-12)
    np.testing.assert_allclose(arc.center, [[5, 0, 0], [5, 0, -2]], atol=1e-12)
    for bad, why in (("P1.5", "whole"), ("P0", "1 or more")):
        with pytest.raises(NCError, match=why):
            lcnc(f"G2 X10 Y0 I5 J0 {bad} F100")
    with pytest.raises(NCError, match="word P is not used"):
        interpret("G2 X10 Y0 I5 J0 P2 F100")  # Fanuc: no turns


# ---------------------------------------------------------------- feeds with rotary axes
def test_rotary_moves_take_linuxcncs_time():
    # X30 A40 at F100: LinuxCNC's F is along X (the A axis follows): 30 / 100 = 0.3 min; the
    # Motion's feed along the combined travel hypot(30, 40) = 50 is 50 / 0.3 = 166.67 mm/min
    _, m = lcnc("G94 F100\nG1 X30 A40\nG1 A100")
    assert m.feed_mm_min[0] == pytest.approx(500.0 / 3.0)
    assert m.feed_mm_min[1] == 100.0  # A alone: 100 deg/min
    _, m = lcnc("G20 F10\nG1 A10")  # degrees/min whatever the length units
    assert m.feed_mm_min[0] == 10.0
    assert interpret("G94 F100\nG1 X30 A40").feed_mm_min[0] == 100.0  # Fanuc: along both


# ---------------------------------------------------------------- dwell
def test_g4_p_is_seconds_and_comes_before_the_blocks_move():
    _, m = lcnc("G4 P1.5\nG4 P0.25 G0 X10")
    assert m.kind.tolist() == [DWELL, DWELL, RAPID]
    assert m.dwell_s.tolist()[:2] == [1.5, 0.25] and ends(m)[-1] == [10.0, 0.0, 0.0]
    with pytest.raises(NCError, match="needs P"):
        lcnc("G4 X1")
    with pytest.raises(NCError, match="both use P"):
        lcnc("G4 P1 G2 X10 I5 F100")


# ---------------------------------------------------------------- canned cycles
def test_g81_g99_then_g98_approaches_at_the_clearance_level_diagonally():
    _, m = lcnc("G0 X0 Y0 Z20\nG1 F100\nG99 G81 X10 Y10 Z-5 R2\nG98 X20")
    assert m.kind.tolist()[1:] == [RAPID, RAPID, LINE, RAPID, RAPID, RAPID, LINE, RAPID]
    assert ends(m)[1:] == [
        [10, 10, 20], [10, 10, 2], [10, 10, -5], [10, 10, 2],  # G99: back to R
        [20, 10, 20], [20, 10, 2], [20, 10, -5], [20, 10, 20],  # G98: from R up to 20 at once
    ]  # fmt: skip
    # Fanuc: the next hole is approached at the height the tool is at
    m = interpret("G0 X0 Y0 Z20\nG1 F100\nG99 G81 X10 Y10 Z-5 R2\nG98 X20")
    assert ends(m)[5] == [20, 10, 2]


def test_g83_pecks_reenter_0_254_mm_above_the_last_depth():
    _, m = lcnc("G0 X0 Y0 Z5\nG1 F100\nG99 G83 X1 Y1 Z-7 R1 Q3")
    assert [e[2] for e in ends(m)[1:]] == [5, 1, -2, 1, -1.746, -5, 1, -4.746, -7, 1]
    assert m.kind.tolist()[1:] == [RAPID, RAPID, LINE, RAPID, RAPID, LINE, RAPID, RAPID, LINE,
                                   RAPID]  # fmt: skip


def test_cycle_started_below_r_goes_straight_up_first():
    _, m = lcnc("G0 X0 Y0 Z0\nG1 F100\nG98 G81 X5 Y0 Z-1 R2")
    assert ends(m)[1:] == [[0, 0, 2], [5, 0, 2], [5, 0, -1], [5, 0, 2]]


def test_incremental_cycle_with_repeats():
    # initial level 10: R = 10 - 8 = 2, bottom = 2 - 4 = -2; holes at X5, X10, X15
    _, m = lcnc("G0 X0 Y0 Z10\nG1 F100\nG91 G99 G81 X5 Z-4 R-8 L3")
    assert ends(m)[1:] == [
        [5, 0, 10], [5, 0, 2], [5, 0, -2], [5, 0, 2],
        [10, 0, 2], [10, 0, -2], [10, 0, 2],
        [15, 0, 2], [15, 0, -2], [15, 0, 2],
    ]  # fmt: skip


def test_g18_cycle_drills_along_y():
    _, m = lcnc("G18 G0 X0 Y20 Z0\nG1 F100\nG98 G81 X5 Z5 Y10 R22")
    assert ends(m)[1:] == [[0, 22, 0], [5, 22, 5], [5, 10, 5], [5, 22, 5]]


@pytest.mark.parametrize(
    "text, why",
    [
        ("G1 F100\nG81 X1 Y1 Z-1", "R plane"),
        ("G1 F100\nG81 X1 Y1 R1", "hole bottom"),
        ("G1 F100\nG82 X1 Y1 Z-1 R1", "dwell time P"),
        ("G1 F100\nG83 X1 Y1 Z-1 R1", "peck depth Q"),
        ("G1 F100\nG81 X1 Y1 Z-1 R1 L0", "repeat count"),
        ("G1 F100\nG83 X1 Y1 Z-1 R1 Q-1", "Q > 0"),
    ],
)
def test_linuxcnc_cycle_refusals(text, why):
    with pytest.raises(NCError, match=why):
        lcnc(text)


def test_cycle_words_carry_over_within_the_same_cycle():
    _, m = lcnc("G0 Z5\nG1 F100\nG99 G82 X1 Y1 Z-1 R1 P0.5\nX2")
    assert m.dwell_s[m.kind == DWELL].tolist() == [0.5, 0.5]


# ---------------------------------------------------------------- M codes, G8, G97
def test_linuxcnc_m_codes_and_modes():
    it, _ = lcnc("T3 M6\nM61 Q5\nM48\nM49\nM62 P1\nG8 G97 S1000 M3")
    assert it.state.tool == 5 and it.state.spindle_rpm == 1000
    it, _ = lcnc("M60")
    assert it.state.stopped
    with pytest.raises(NCError, match="unknown M-code M61"):
        interpret("M61 Q5")
    with pytest.raises(NCError, match="M61 needs the tool number Q"):
        lcnc("M61")


# ---------------------------------------------------------------- tool table
def test_g10_l1_l10_write_the_tool_table_only():
    it, m = lcnc("G10 L1 P2 Z1.5 R3\nG20 G10 L1 P4 Z1\nG21 G0 Z5\nG10 L10 P3 Z2\nG43 H2 G0 Z0")
    table = it.state.tool_table
    assert table[2] == (0.0, 0.0, 1.5, 3.0)
    assert table[4] == (0.0, 0.0, 25.4, 0.0)
    assert table[3] == (0.0, 0.0, 3.0, 0.0)  # Z 5 reads 2: offset 3
    assert ends(m)[-1] == [0.0, 0.0, 0.0]  # the length is not applied to the motion
    before = it.state.copy()
    it.run(["G10 L1 P2 Z9"])
    assert before.tool_table[2][2] == 1.5  # copies do not share a changing table


# ---------------------------------------------------------------- state and restart
def test_modal_state_has_slots_and_copies_independently():
    st = ModalState()
    assert not hasattr(st, "__dict__")
    st.canned.r_mm = 1.0
    cp = st.copy()
    cp.canned.r_mm = 2.0
    assert st.canned.r_mm == 1.0 and cp == cp.copy()


def test_restart_preamble_writes_back_programmed_offsets_and_path_mode():
    it, _ = lcnc("G10 L2 P2 X100 Y0 Z0\nG55 G0 X101 Y2 Z3\nG64 P0.05")
    pre = restart_preamble(it.state)
    assert pre[:2] == ["G21 G17 G91.1 G94 G55 G40 G49 G98 G80 G64 P0.05 Q0.05",
                       "G90 G10 L2 P2 X100 Y0 Z0"]  # fmt: skip
    assert "X101 Y2" in pre  # the position in G55: machine 201 - 100
    again, _ = lcnc("\n".join(pre))
    assert again.state.position_mm == pytest.approx(it.state.position_mm)
    it, _ = lcnc("G0 X5\nG92 X0")
    with pytest.raises(NCError, match="G92"):
        restart_preamble(it.state)


def test_offsets_are_kept_in_mm_whatever_the_units():
    it, _ = lcnc("G20 G10 L2 P1 X1 Y2\nG92 Z0.5")
    assert it.state.work_offsets_mm[0] == (25.4, 50.8, 0.0)
    assert it.state.g92_offset_mm == pytest.approx((0.0, 0.0, -12.7))
    assert math.isclose(it.state.origin_mm[2], -12.7)
