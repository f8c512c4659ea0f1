"""planning.nc.output: one program written for Fanuc, LinuxCNC and GRBL 1.1 moves the same.

The written program is interpreted here in its own dialect and compared with the source segment by
segment (independently of the module's own check), and its text is held to the controller's rules
with plain string checks and planning.nc.dialect's checker.
"""

from __future__ import annotations

import itertools
import re

import numpy as np
import pytest

from analysis.config import REPO_ROOT, load_machine
from planning.nc import NCError, Program, interpret
from planning.nc.dialect import check_dialect
from planning.nc.output import GRBL_LINE_CHARS, for_dialect, grbl_problems

PROGRAMS = REPO_ROOT / "data" / "programs"
SHIPPED = sorted(PROGRAMS.glob("*.nc"))
WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
COMMENT = re.compile(r"\([^)]*\)|;.*$")


def words(line: str) -> list[tuple[str, float]]:
    return [(a, float(b)) for a, b in WORD.findall(COMMENT.sub("", line).upper())]


def assert_same_motion(src: Program, out: Program, dialect: str, source: str = "fanuc",
                       machine=None, tools: bool = True) -> None:  # fmt: skip
    """Interpreting ``out`` in ``dialect`` gives the moves of ``src`` read in ``source``: end
    points (and arc centres) within 1e-6 mm, the same feeds, dwells, spindle and coolant."""
    a = interpret(src, machine, dialect=source)
    b = interpret(out, machine, dialect=dialect)
    assert len(a) == len(b)
    np.testing.assert_array_equal(a.kind, b.kind)
    np.testing.assert_allclose(b.start, a.start, atol=1e-6, rtol=0)
    np.testing.assert_allclose(b.end, a.end, atol=1e-6, rtol=0)
    np.testing.assert_allclose(b.center, a.center, atol=1e-6, rtol=0)
    np.testing.assert_allclose(b.feed_mm_min, a.feed_mm_min, rtol=1e-12)
    np.testing.assert_allclose(b.dwell_s, a.dwell_s, atol=1e-9)
    np.testing.assert_array_equal(b.spindle_rpm, a.spindle_rpm)
    np.testing.assert_array_equal(b.coolant, a.coolant)
    np.testing.assert_array_equal(b.plane, a.plane)
    if tools:
        np.testing.assert_array_equal(b.tool, a.tool)


def assert_grbl_rules(out: Program, m6: bool = False) -> None:
    """GRBL 1.1h: lines <= 80 characters (79 and the NUL), no O word, no M6 (no tool changer),
    no canned cycles or their return modes, no G41/G42/G43, no '%' or '/' lines."""
    for line in out.lines:
        assert len(line) <= 80 and len(line) <= GRBL_LINE_CHARS, line
        assert line.strip() not in ("%", "") and not line.lstrip().startswith("/"), line
        for letter, v in words(line):
            assert letter not in "OHDQABC", line
            assert m6 or (letter, v) != ("M", 6), line
            if letter == "G":
                assert v not in (41, 42, 43, 98, 99, 90.1) and not (73 <= v <= 89 and v != 80), line


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
@pytest.mark.parametrize("dialect", ["grbl", "linuxcnc", "fanuc"])
def test_shipped_programs_move_alike_in_every_dialect(path, dialect) -> None:
    src = Program.read(path)
    out = for_dialect(src, dialect)
    assert_same_motion(src, out, dialect, tools=dialect != "grbl")
    if dialect == "grbl":
        assert_grbl_rules(out)
        assert not grbl_problems(out)


def test_shipped_programs_for_grbl_look_like_this() -> None:
    out = for_dialect(Program.read(PROGRAMS / "demo-part.nc"), "grbl")
    text = out.text()
    assert out.lines[0] == "(CUTLAB DEMO PART - 60 X 40 POCKET, CONTOUR AND HOLES)"  # no O1001
    assert "N20 T1 (PHI10 FLAT END MILL)" in out.lines  # the first tool: loaded before the start
    assert "N60 Z5." in out.lines  # G43 H1 left out
    # the second tool: a pause for the operator (the spindle was already stopped at N480)
    k = out.lines.index("N500 T2 (PHI5 DRILL)")
    assert out.lines[k - 1].startswith("M0 (") and "T2" in out.lines[k - 1]
    assert "N580 G4 P0.5" in out.lines  # Fanuc's P500 ms
    assert "G83" not in text and "G98" not in text and "Q3" not in text
    holes = [ln for ln in out.lines if ln.startswith("G1 Z-12")]
    assert len(holes) == 4  # four holes, each pecked to the bottom


def test_linuxcnc_wrapping_o_words_end_and_dwell() -> None:
    src = Program.read(PROGRAMS / "inch-features.nc")
    out = for_dialect(src, "linuxcnc")
    assert out.lines[0] == "%" and out.lines[-1] == "%"
    assert sum(ln.strip() == "%" for ln in out.lines) == 2
    assert not any(ln.lstrip().upper().startswith("O") for ln in out.lines)
    assert out.lines[-2].endswith("M30")
    assert "/N100 G0 Z2. (OPTIONAL CHECK STOP, SKIPPED WITH BLOCK DELETE ON)" in out.lines
    assert "G4 P0.25" in out.lines  # G82 P250 (ms) expanded: its dwell in seconds
    # a program without % and M30 gets both; blocks after the end are left out
    p = Program.parse("O12 (X)\nG21 G90 G0 X1 Y2 Z3\nG4 X1.5\nG4 P250\nG80 G0 Z5\n")
    out = for_dialect(p, "linuxcnc")
    assert out.lines == ["%", "(X)", "G21 G90 G0 X1 Y2 Z3", "G4 P1.5", "G4 P0.25", "G0 Z5",
                         "M30", "%"]  # fmt: skip
    assert_same_motion(p, out, "linuxcnc")
    p = Program.parse("G0 X1\nM30\nG0 X5\n%\n")
    assert for_dialect(p, "linuxcnc").lines == ["%", "G0 X1", "M30", "%"]


def test_fanuc_keeps_o_and_n_words_and_writes_iso_code() -> None:
    src = Program.read(PROGRAMS / "demo-part.nc")
    out = for_dialect(src, "fanuc")
    assert out.lines == src.lines  # already ISO code: nothing changes
    p = Program.parse("%\nO7 (T)\nN1 G21 G90 G91.1 G17\nn2 g0 x10 y-2 z5 ; lower case\nN3 G1 Z-1"
                      " F300\nN4 G4 X1\nN5 M30\n%\n")  # fmt: skip
    out = for_dialect(p, "fanuc")
    assert out.lines == ["%", "O7 (T)", "N1 G21 G90 G17", "N2 G0 X10. Y-2. Z5. (lower case)",
                         "N3 G1 Z-1. F300", "N4 G4 X1.", "N5 M30", "%"]  # fmt: skip
    assert_same_motion(p, out, "fanuc")
    # from GRBL: dwell P in seconds becomes X
    g = Program.parse("G21 G90\nG0 X1\nG4 P0.5\nM30\n")
    out = for_dialect(g, "fanuc", source="grbl")
    assert "G4 X0.5" in out.lines
    assert_same_motion(g, out, "fanuc", source="grbl")


def _cycle_program(cycle: int, ret: int, dist: int, inch: bool) -> str:
    """Drill cycles in every mode: G81/G82/G83, G98/G99 returns, G90 or G91 words (G91: R from
    the initial level, Z from R; L repeats at X/Y steps), mm or inch."""
    u = 1 / 25.4 if inch else 1.0

    def n(v: float) -> str:
        return f"{v * u:.6f}".rstrip("0").rstrip(".")

    extra = {81: "", 82: " P250", 83: f" Q{n(1.5)}"}[cycle]
    lines = ["%", "O100", f"G{20 if inch else 21} G17 G94 G54 G80", "S1500 M3",
             f"G90 G0 X0 Y0 Z{n(10)}", f"G1 Z{n(8)} F{n(400)}"]  # fmt: skip
    if dist == 90:
        lines += [f"G{ret} G{cycle} X{n(5)} Y{n(5)} Z{n(-3.3)} R{n(2)}{extra} F{n(120)}",
                  f"X{n(10)}", f"Y{n(10)} Z{n(-4.7)} R{n(1)}", f"X{n(12)} L2",
                  f"G91 X{n(3)} Y{n(-1)} L2", "G90 G80 G0 Z20"]  # fmt: skip
    else:
        lines += [f"G91 G{ret} G{cycle} X{n(5)} Y{n(5)} Z{n(-5.3)} R{n(-6)}{extra} L3"
                  f" F{n(120)}", f"X{n(-2)} Y{n(1)}", f"Z{n(-3)} X{n(1)}",
                  "G80", f"G90 G0 Z{n(20)}"]  # fmt: skip
    return "\n".join([*lines, "M5", "M30", "%"]) + "\n"


CYCLES = list(itertools.product((81, 82, 83), (98, 99), (90, 91), (False, True)))


@pytest.mark.parametrize(
    "cycle,ret,dist,inch", CYCLES, ids=lambda v: str(v) if not isinstance(v, bool) else "in"
)
@pytest.mark.parametrize("dialect", ["grbl", "linuxcnc"])
def test_canned_cycles_expand_to_the_interpreters_own_moves(cycle, ret, dist, inch, dialect):
    src = Program.parse(_cycle_program(cycle, ret, dist, inch), "cycles.nc")
    out = for_dialect(src, dialect)
    assert_same_motion(src, out, dialect)
    for line in out.lines:
        gs = [v for letter, v in words(line) if letter == "G"]
        assert not any(81 <= v <= 89 or v in (98, 99) for v in gs), line  # G80 stays
        assert all(letter not in "QRL" for letter, _ in words(line)), line
    if dialect == "grbl":
        assert_grbl_rules(out)
    if cycle == 82:
        assert any(ln == "G4 P0.25" for ln in out.lines)  # P250 ms: seconds on GRBL/LinuxCNC
    if dist == 91:  # the absolute moves sit between G90 and a G91 that restores the mode
        k = next(j for j, ln in enumerate(out.lines) if ln.startswith("G90 G0"))
        assert "G91" in out.lines[k:]


def test_g29_is_expanded_where_the_controller_has_none() -> None:
    p = Program.parse("G21 G90 G0 X5 Y5 Z10\nG91 G28 X0 Y0 Z0\nG90 G29 X12 Y3 Z1\nM30\n")
    m = load_machine("lab-grbl")
    for dialect in ("grbl", "linuxcnc"):
        out = for_dialect(p, dialect, m, source="fanuc")  # lab-grbl's own is GRBL
        assert not any(("G", 29.0) in words(ln) for ln in out.lines)
        assert_same_motion(p, out, dialect, machine=m)


def test_a_tool_change_on_grbl_pauses_with_the_spindle_stopped() -> None:
    p = Program.parse("G21 G90\nT1 M6\nS2000 M3\nG0 X1 Y1 Z5\nG1 Z-1 F100\nT2 M6\nG1 X5\n"
                      "T3 M6 S3000 M4\nG1 X6\nM30\n")  # fmt: skip
    out = for_dialect(p, "grbl")
    assert out.lines == ["G21 G90", "T1", "S2000 M3", "G0 X1 Y1 Z5", "G1 Z-1 F100", "M5",
                         "M0 (change to tool T2, then cycle start)", "T2", "M3", "G1 X5", "M5",
                         "M0 (change to tool T3, then cycle start)", "T3 S3000 M4", "G1 X6",
                         "M30"]  # fmt: skip
    assert_same_motion(p, out, "grbl", tools=False)
    assert_grbl_rules(out)
    kept = for_dialect(p, "grbl", tool_changer=True)  # a GRBL build with a tool changer
    assert "T2 M6" in kept.lines and not grbl_problems(kept, tool_changer=True)
    assert for_dialect(p, "linuxcnc").lines[2] == "T1 M6"


def test_absolute_arc_centres_become_relative_on_grbl_and_fanuc() -> None:
    p = Program.parse("G21 G90 G17 G90.1\nG0 X10 Y0 Z0\nG1 Z-1 F200\nG3 X0 Y10 I0 J0\n"
                      "G2 X10 Y0 I0 J0\nG91.1\nG3 X0 Y10 I-10 J0\nM30\n")  # fmt: skip
    grbl = for_dialect(p, "grbl")
    assert grbl.lines[0] == "G21 G90 G17 G91.1"
    assert "G3 X0 Y10 I-10 J0" in grbl.lines and "G2 X10 Y0 I0 J-10" in grbl.lines
    assert_same_motion(p, grbl, "grbl")
    fanuc = for_dialect(p, "fanuc")
    assert fanuc.lines[0] == "G21 G90 G17" and "G2 X10. Y0. I0. J-10." in fanuc.lines
    assert_same_motion(p, fanuc, "fanuc")


def test_long_comments_are_wrapped_within_grbl_line_buffer() -> None:
    long = "a long comment " * 12
    p = Program.parse(f"%\nO1 ({long})\nG21 G90 G0 X1 Y2 Z3 ({long})\nG1 X2 F100 ; {long}\n%\n")
    out = for_dialect(p, "grbl")
    assert_grbl_rules(out)
    assert "G21 G90 G0 X1 Y2 Z3" in out.lines and "G1 X2 F100" in out.lines
    text = " ".join(ln[1:-1] for ln in out.lines if ln.startswith("("))
    assert text.split() == (long * 3).split()  # every word kept, in order
    assert_same_motion(p, out, "grbl")


@pytest.mark.parametrize(
    "text,dialect,message",
    [
        ("G21 G90 G0 X0 Y0\nG41 D1 G1 X10 F100\n", "grbl", "G41"),
        ("G21 G90 G0 X0 Y0\nG1 X10 A30 F100\n", "grbl", "3 axes"),
        ("G0 X1\n", "heidenhain", "dialect must be one of"),
        (
            "N1234567 G17 G21 G90 G94 G54 G40 G49 G1 X-1234.123456 Y-1234.123456 Z-1234.123456 "
            "F1234.123456 S12345.123 M3\n",
            "grbl",
            "characters without spaces",
        ),
    ],
)
def test_what_cannot_be_written_is_refused(text, dialect, message) -> None:
    with pytest.raises(NCError, match=message):
        for_dialect(Program.parse(text, "bad.nc"), dialect)


def test_block_delete_and_blank_lines_are_left_out_for_grbl() -> None:
    p = Program.parse("G21 G90\n\n/G0 X5\nG0 X1\n")
    assert for_dialect(p, "grbl").lines == ["G21 G90", "G0 X1"]


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
@pytest.mark.parametrize("dialect", ["grbl", "linuxcnc", "fanuc"])
def test_the_dialect_checker_finds_nothing_to_refuse(path, dialect) -> None:
    out = for_dialect(Program.read(path), dialect)
    for strip in (True, False):
        problems = check_dialect(out, dialect, strip=strip)
        assert not problems, "\n".join(map(str, problems))


@pytest.mark.parametrize("cycle,ret,dist,inch", CYCLES[::3])
def test_the_dialect_checker_takes_the_expanded_cycles(cycle, ret, dist, inch) -> None:
    src = Program.parse(_cycle_program(cycle, ret, dist, inch), "cycles.nc")
    for dialect in ("grbl", "linuxcnc"):
        problems = check_dialect(for_dialect(src, dialect), dialect, strip=False)
        assert not problems, "\n".join(map(str, problems))
