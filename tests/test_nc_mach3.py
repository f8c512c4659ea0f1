"""The fourth dialect, Mach3 ("Using Mach3Mill" 1.84): its interpretation (RS274NGC order of
execution, G4 P in milliseconds, G10 L1/L2), its refusals, its line answers and what the posts
write for it, through the same faces as the other dialects (``cutlab nc check|motions --dialect
mach3``, ``cutlab plan feed --dialect mach3``, :func:`planning.nc.output.for_dialect`)."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from analysis.config import load_machine
from planning.nc import NCError, Program, check_dialect, interpret
from planning.nc.dialects import get
from planning.nc.output import for_dialect
from rig.cli import main

FANUC = """%
O0431 (SLOT)
N10 G21 G90 G17
N20 T1 M6
N30 S2000 M3
N40 G0 X-20. Y30. Z5.
N50 G1 Z-0.3 F1000 ; down
N60 G4 P1500
N70 G1 X120.
N80 G0 Z50.
N90 M30
%
"""


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


def test_mach3_reads_f_before_the_units_and_p_in_milliseconds() -> None:
    m = interpret("G21 G1 X0 F100\nG20 G1 X1 F6\nG4 P500\n", dialect="mach3")
    assert m.feed_mm_min[1] == pytest.approx(6.0)  # F before G20: still mm/min (RS274NGC order)
    assert m.end[1][0] == pytest.approx(25.4)
    assert m.dwell_s[2] == pytest.approx(0.5)
    fanuc = interpret("G21 G1 X0 F100\nG20 G1 X1 F6\n", dialect="fanuc")
    assert fanuc.feed_mm_min[1] == pytest.approx(6.0 * 25.4)


@pytest.mark.parametrize(
    ("block", "why"),
    [("G38.2 Z-5 F100", "G38.2"), ("G43.1 Z5", "G43.1"), ("G28.1", "G28.1"), ("G29 X0", "G29"),
     ("G61.1", "G61.1"), ("M62 P1", "M62"), ("G10 L20 P1 X0", "L20"), ("G4 X1", "P")],
)  # fmt: skip
def test_mach3_refuses_what_its_language_does_not_have(block: str, why: str) -> None:
    with pytest.raises(NCError, match=why.replace(".", r"\.")):
        interpret(f"G21 G90 F100\n{block}\n", dialect="mach3")


def test_mach3_takes_its_own_codes() -> None:
    m = interpret("G21 G90 G10 L2 P1 X5\nG54 G0 X0 Y0\nM48\nG90.1 G2 X10 I5 J0 F100\nG28\n",
                  dialect="mach3")  # fmt: skip
    assert m.end[0][0] == pytest.approx(5.0)  # G10 L2 P1 X5 then G54 X0: machine X5


def test_the_line_check_lists_mach3s_answers() -> None:
    text = "O12 (A)\nN123456 G0 X0 ; c\nG28.1\nM62 P1\n" + "G1 X1 " + "(x)" * 90 + "\n"
    probs = {(p.line, p.word): p for p in check_dialect(text, "mach3")}
    assert probs[(1, "O12")].severity == "warning"
    assert probs[(2, "N123456")].severity == "error" and "N99999" in probs[(2, "N123456")].reason
    assert probs[(2, ";")].severity == "warning"
    assert "homes the axes" in probs[(3, "G28.1")].reason
    assert probs[(4, "M62")].severity == "error"
    assert "256" in probs[(5, "")].reason
    assert str(probs[(3, "G28.1")]).startswith("<program>:3:1: G28.1: Mach3 error")


def test_a_fanuc_program_written_for_mach3_moves_alike() -> None:
    src = Program.parse(FANUC, "slot.nc")
    out = for_dialect(src, "mach3", source="fanuc")
    lines = out.lines
    assert not any(ln.startswith(("%", "O")) for ln in lines)
    assert "N60 G4 P1500" in lines  # ms to ms: as written
    assert "N50 G1 Z-0.3 F1000 (down)" in lines  # ( ) comments
    assert "N20 T1 M6" in lines
    a, b = interpret(src, dialect="fanuc"), interpret(out, dialect="mach3")
    assert (a.end == b.end).all() and (a.dwell_s == b.dwell_s).all()
    assert out.lines[-1] == "N90 M30"


def test_seconds_dwells_are_written_in_milliseconds() -> None:
    out = for_dialect(Program.parse("G21 G0 X0\nG4 P2.5\nM30\n"), "mach3", source="linuxcnc")
    assert "G4 P2500" in out.lines


def test_cli_check_motions_and_plan_feed_in_mach3(tmp_path: Path) -> None:
    prog = tmp_path / "slot.nc"
    prog.write_text(FANUC)
    rc, so, _ = _run(["nc", "check", str(prog), "--dialect", "mach3", "--json"])
    assert rc == 0
    rep = json.loads(so)
    assert rep["dialect"] == "mach3" and rep["dwell_s"] == pytest.approx(1.5)
    assert {p["word"] for p in rep["dialect_problems"]} == {"O0431", ";"}  # warnings only
    csv = tmp_path / "m.csv"
    rc, _, _ = _run(["nc", "motions", str(prog), "--dialect", "mach3", "-o", str(csv)])
    assert rc == 0

    from analysis.rules import derive_rule, save_rule, slot_load_percent

    rule = tmp_path / "rule.toml"
    save_rule(derive_rule("rt", 100, 1000, 3500, slot_load_percent("ball", 30, 0.3, 30)), rule)
    out = tmp_path / "out.nc"
    rc, so, err = _run(["plan", "feed", str(prog), "--rules", str(rule), "--tool", "phi30-ball",
                        "--stock", "box:0,100,0,60,-10,0", "--spacing", "2", "-o", str(out),
                        "--dialect", "mach3", "--json"])  # fmt: skip
    assert rc == 0, err
    assert json.loads(so)["dialect"] == "mach3"
    text = out.read_text()
    assert "%" not in text and "O0431" not in text and "G4 P1500" in text
    assert _run(["nc", "check", str(out), "--dialect", "mach3"])[0] == 0


def test_a_machine_file_may_name_mach3() -> None:
    m = load_machine("ace-h63")
    assert type(m).model_validate({**m.model_dump(), "dialect": "mach3"}).dialect == "mach3"
    assert get("mach3").protocol is None  # no DNC streaming: Mach3 runs files
