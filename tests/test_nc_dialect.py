"""planning.nc.dialect: what GRBL 1.1h answers to hand-worked lines (each expectation taken from
GRBL's source, gnea/grbl at HEAD, file:line cited), the streamer's line transform, and the coarser
Fanuc / LinuxCNC rules; ``cutlab nc check --dialect``."""

from __future__ import annotations

import json

import pytest

from planning.nc.dialect import check_dialect, refused
from planning.nc.grbl import GRBL_LINE_CHARS, GrblParser, grbl_filter, grbl_send_text
from rig.cli import main


def _answers(lines: list[str]) -> list[str]:
    """GRBL's answer to each line, in order, from a fresh parser state (as after a reset)."""
    p = GrblParser()
    out = []
    for line in lines:
        f = grbl_filter(line)
        if f.overflow:
            out.append("error:11")
        elif not f.text:
            out.append("ok")
        else:
            r = p.parse(f.text)
            out.append("ok" if r.ok else f"error:{r.code}")
    return out


# (setup lines, the line, GRBL's answer, where the answer comes from)
CASES = [
    ([], "G1 X10", "error:22", "gcode.c:664 feed rate undefined (F is 0 after gc_init)"),
    (["F100"], "G1 X10", "ok", "gcode.c:664 passes once F is set"),
    (["F100", "G1 X10"], "G90 G2", "error:26", "gcode.c:682 G2 without axis words"),
    ([], "G90 G2", "error:22", "gcode.c:664 comes before :682 when F is undefined"),
    (["F100"], "G17 G2 Z5", "error:32", "gcode.c:683 no axis word in the XY plane"),
    (["F100"], "G2 X10 Y0", "error:35", "gcode.c:783 no I/J in the XY plane"),
    (["F100"], "G2 X0 Y0 R5", "error:33", "gcode.c:692 R arc to the current position"),
    (["F100"], "G2 X20 Y0 R5", "error:34", "gcode.c:748 radius shorter than half the chord"),
    (["F100"], "G2 X10 Y0 R5", "ok", "gcode.c:748 a half circle: h = 0"),
    (["F100"], "G2 X20 Y10 I5 J0", "error:33", "gcode.c:804 end radius 19.5 mm vs 5 mm"),
    ([], "O1234", "error:20", "gcode.c:322 O is no letter GRBL knows"),
    ([], "T1 M6", "error:20", "gcode.c:283 M6 unsupported"),
    ([], "M7", "error:20", "gcode.c:263-267 M7 only with ENABLE_M7 (off in config.h)"),
    ([], "M8", "ok", "gcode.c:266"),
    ([], "M1", "ok", "gcode.c:251 optional stop ignored"),
    ([], "G43 H1", "error:20", "gcode.c:220 only G43.1"),
    ([], "G43.1 Z1", "ok", "gcode.c:218 G43.1 with Z (gcode.c:495)"),
    ([], "G43.1 X1", "error:37", "gcode.c:495 G43.1 axis other than Z"),
    ([], "G41 D1", "error:20", "gcode.c:233 no G41"),
    ([], "G81 X1 Y1 Z-1 R1", "error:20", "gcode.c:233 no canned cycles"),
    ([], "G98", "error:20", "gcode.c:233 no G98"),
    ([], "G90.1", "error:20", "gcode.c:190 G90.1 not supported"),
    ([], "G91.1", "ok", "gcode.c:189-192 G91.1 accepted"),
    ([], "G64", "error:20", "gcode.c:233 only G61"),
    ([], "G61.1", "error:20", "gcode.c:230"),
    ([], "G59.1", "error:23", "gcode.c:235 G59 with a mantissa: not an integer"),
    ([], "G92.2", "error:20", "gcode.c:158 only G92 and G92.1"),
    ([], "M3.5", "error:23", "gcode.c:245 no Mxx.x"),
    ([], "G0 G1 X1", "error:24", "gcode.c:166 two axis commands"),
    ([], "G17 G18", "error:21", "gcode.c:238 modal group violation"),
    ([], "G0 X1 X2", "error:25", "gcode.c:326 word repeated"),
    ([], "F-100", "error:4", "gcode.c:330 negative F"),
    ([], "T256", "error:38", "gcode.c:316 T > MAX_TOOL_NUMBER 255"),
    ([], "N10000001 G0 X1", "error:27", "gcode.c:376 N > MAX_LINE_NUMBER"),
    ([], "N10 G0 X1", "ok", "gcode.c:309 N words are allowed"),
    ([], "G4", "error:28", "gcode.c:450 G4 without P"),
    ([], "G4 P0.5", "ok", "gcode.c:449-452"),
    ([], "G10 L2 X1", "ok", "gcode.c:528 needs P or L, not both (bit_isfalse on the pair)"),
    ([], "G10 X1", "error:28", "gcode.c:528 neither P nor L"),
    ([], "G10 L2 P1", "error:26", "gcode.c:527 G10 without axis words"),
    ([], "G10 L2 P7 X1", "error:29", "gcode.c:530 P > N_COORDINATE_SYSTEM 6"),
    ([], "G10 L3 P1 X1", "error:20", "gcode.c:534 L other than 2 or 20"),
    ([], "G92", "error:26", "gcode.c:563 G92 without axis words"),
    (["F100"], "G53 G2 X1 Y1 R5", "error:30", "gcode.c:639 G53 only with G0/G1"),
    ([], "G80 X1", "error:31", "gcode.c:649 axis words with G80"),
    ([], "G0 X1 I2", "error:36", "gcode.c:836 I unused in a G0"),
    (["F100"], "G1 X1 P1", "error:36", "gcode.c:836 P unused"),
    (["F100"], "G2 X10 Y0 R5 I5", "error:36", "gcode.c:691,836 R mode leaves I unused"),
    ([], "X1.2.3", "error:1", "gcode.c:121 '.' is not a letter after X1.2"),
    ([], "G", "error:2", "gcode.c:123 a letter without a number"),
    ([], "#1=5", "error:1", "gcode.c:121 no parameters"),
    ([], "%", "error:1", "protocol.c:126-131 '%' is not filtered (TODO), gcode.c:121"),
    ([], "G256 X3", "ok", "gcode.c:112,132 uint8_t int_value: G256 reads as G0"),
    ([], "(only a comment)", "ok", "protocol.c:93 empty line after the filter: ok"),
    ([], "G1 X1 F100 " + "Y1 " * 40, "error:11", "protocol.c:141-143,92 more than 79 chars"),
    ([], "G1X1F100(" + "x" * 200 + ")", "ok", "protocol.c:124 comments do not count"),
    ([], "g1 x2 f100", "ok", "protocol.c:144 lower case upper-cased"),
    ([], "/G1 X1 F100", "ok", "protocol.c:122 '/' ignored: the block runs"),
]


@pytest.mark.parametrize("setup,line,answer,source", CASES, ids=[c[1][:30] for c in CASES])
def test_grbl_answers_as_its_source(setup, line, answer, source) -> None:
    assert _answers([*setup, line])[-1] == answer, source


def test_grbl_parser_state_follows_accepted_lines_only() -> None:
    # gcode.c STEP 4 runs only when STEP 3 found nothing: a refused line changes nothing
    assert _answers(["G1 X1 F100 Q1", "G1 X2"]) == ["error:20", "error:22"]  # F was not taken
    p = GrblParser()
    p.parse("G20")
    p.parse("G1X1F10")
    assert p.state.feed == pytest.approx(254.0)  # gcode.c:419 inches converted to mm/min
    assert p.state.position[0] == pytest.approx(25.4)
    p.parse("M30")  # gcode.c:1094-1102 program end resets motion, plane, distance, G94, G54...
    assert (p.state.motion, p.state.incremental, p.state.inches) == (1, False, True)


def test_grbl_sync_and_planner_blocks() -> None:
    p = GrblParser()
    assert p.parse("S1000M3").sync  # gcode.c:946 spindle_sync waits for the planner
    assert p.parse("S2000").sync  # gcode.c:917-927 a new S with the spindle on
    assert p.parse("M8").sync  # gcode.c:955
    assert p.parse("G4P1").sync and p.parse("G4P1").dwell_s == 1.0  # gcode.c:969, mc_dwell
    assert p.parse("G1X10F100").planner_blocks == 1
    assert p.parse("G1X10").planner_blocks == 0  # zero length: PLAN_EMPTY_BLOCK
    # motion_control.c:109 floor(|0.5 * travel * r| / sqrt(tol (2 r - tol))): half circle r = 5
    assert p.parse("G2X20Y0R5").planner_blocks == 55


def test_grbl_filter_and_send_text() -> None:
    f = grbl_filter("n10 G1 x1 (a (b) c) y2 ; rest", limit=GRBL_LINE_CHARS)
    # protocol.c:112-117: comments do not nest, the first ')' ends it: ' c)' survives (error:1)
    assert f.text == "N10G1X1C)Y2"
    assert grbl_send_text("N10 G1 X1 (note!) Y2 ; end") == "G1X1Y2"
    assert grbl_send_text("O1234 (PART)") == "" and grbl_send_text("(just a note)") == ""
    assert grbl_send_text("  $H ") == "$H"
    assert grbl_filter("G1 X1 (stop!)").realtime == ((12, "!"),)  # serial.c:154 in the ISR


def test_check_dialect_grbl_lists_every_refused_line_with_columns() -> None:
    text = "O1234\nG21 G90\nT1 M6\nG1 X1 F100\nG90 G2\n(" + "c" * 170 + ")\nM1\nM30\n"
    probs = check_dialect(text, "grbl", file="p.nc")
    errors = refused(probs)
    assert [(p.line, p.column, p.word, p.answer) for p in errors] == [
        (3, 4, "M6", "error:20"),
        (5, 5, "G2", "error:26"),
    ]
    assert str(errors[0]).startswith("p.nc:3:4: M6: GRBL error:20: unsupported command")
    # M1 runs as nothing (a warning); the O line and the 172-character comment are stripped
    assert [(p.line, p.severity) for p in probs if p.severity == "warning"] == [(7, "warning")]
    # sent as written, the O line is refused and the comment line does not fit the buffer
    raw = refused(check_dialect(text, "grbl", file="p.nc", strip=False))
    assert (1, "error:20") in [(p.line, p.answer) for p in raw]
    assert any(p.line == 6 and p.answer == "cannot be streamed" for p in raw)


def test_check_dialect_grbl_flags_block_delete_and_realtime_characters() -> None:
    probs = check_dialect("G21\n/G0 X1\nG0 X2 (done!)\n", "grbl", strip=False)
    assert [(p.line, p.word) for p in refused(probs)] == [(2, "/"), (3, "!")]


def test_check_dialect_fanuc_and_linuxcnc() -> None:
    text = "O12345\nG21 G90 ; units\nG91.1\nN123456 G0 X10\nM62 P1\ng1 x1 f100\n"
    fan = check_dialect(text, "fanuc", file="f.nc")
    got = {(p.line, p.word) for p in fan}
    assert {(1, "O12345"), (2, ";"), (3, "G91.1"), (4, "N123456"), (5, "M62"), (6, "g1")} <= got
    assert any(p.severity == "warning" and "decimal point" in p.reason for p in fan)
    lin = check_dialect("O1234\nG4 X2\nG4 P500\nG29 X0\nG21 G90.1\n", "linuxcnc", file="l.nc")
    assert [(p.line, p.word, p.severity) for p in lin] == [
        (1, "O1234", "error"),
        (2, "X2", "error"),
        (3, "P500", "warning"),
        (4, "G29", "error"),
    ]


def test_cutlab_nc_check_dialect(tmp_path, capsys) -> None:
    f = tmp_path / "p.nc"
    f.write_text("G21 G90\nT1 M6\nG0 X1 Y1\nM30\n")
    assert main(["nc", "check", str(f), "--dialect", "grbl"]) == 2
    err = capsys.readouterr().err
    assert f"{f}:2:4: M6: GRBL error:20" in err and "grbl would refuse 1 line(s)" in err
    assert main(["nc", "check", str(f), "--dialect", "linuxcnc", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["dialect"] == "linuxcnc" and out["dialect_problems"] == []
    assert main(["nc", "check", str(f), "--dialect", "grbl", "--json"]) == 2
    out = json.loads(capsys.readouterr().out)
    assert out["dialect_problems"][0]["answer"] == "error:20"
    # read as GRBL reads it, the program stops at the refused line: no summary, and why
    assert out["summary"] is None and "M6" in out["summary_reason"]
