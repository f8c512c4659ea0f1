"""`plan simulate` cuts each block with the tool in the spindle (issue 19): a program that changes
tools (T M6) maps each T number to a tool; an unmapped T, or one tool named for a program that
changes tools, is refused naming the block."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from planning.errors import PlanningError
from planning.stock import load_plan

ROOT = Path(__file__).parents[1]

# T1 (phi 10 flat): one slot 2 mm deep from X10 to X40 at Y10; T2 (phi 5 drill): two G81 holes
# 6 mm deep at Y30, clear of the slot.
TWO_TOOLS = """G21 G90 G17 G94
T1 M6
S3000 M3
G0 X10 Y10 Z5
G1 Z-2 F200
G1 X40
G0 Z5
T2 M6
S2000 M3
G0 X10 Y30 Z5
G98 G81 X10 Y30 Z-6 R2 F100
X30
G80
G0 Z20
M30
"""
SLOT_MM3 = (30 * 10 + math.pi * 5**2) * 2  # a 30 mm slot, phi 10, 2 deep, with round ends
HOLE_MM3 = math.pi * 2.5**2 * 6  # phi 5 cylinder (the Z-map's drill), 6 deep

STOCK = """[stock]
kind = "box"
xmin_mm = 0.0
xmax_mm = 50.0
ymin_mm = 0.0
ymax_mm = 40.0
bottom_mm = -10.0
top_mm = 0.0
spacing_mm = 0.1

[plan]
machine = "ace-h63"
"""


def cli(argv: list[str], capsys) -> tuple[int, str, str]:
    from rig.cli import main

    rc = main(argv)
    out = capsys.readouterr()
    return rc, out.out, out.err


def _plan(tmp_path: Path, tools: str) -> Path:
    (tmp_path / "two.nc").write_text(TWO_TOOLS)
    p = tmp_path / "plan.toml"
    p.write_text(STOCK + f'[[operations]]\nname = "two"\nprogram = "two.nc"\n{tools}\n')
    return p


def test_the_drill_cuts_its_holes_with_5_mm_not_10(tmp_path: Path) -> None:
    plan, _ = load_plan(_plan(tmp_path, 'tools = { T1 = "phi10-flat", T2 = "phi5-drill" }'))
    (res,) = plan.run()
    runs = {t: (name, removed) for t, name, _, removed, _ in res.tool_runs}
    assert runs[1][0] == "phi10-flat" and runs[2][0] == "phi5-drill"
    # closed forms; the 0.1 mm grid's area error on these circles is well under 2 %
    assert runs[1][1] == pytest.approx(SLOT_MM3, rel=0.02)
    assert runs[2][1] == pytest.approx(2 * HOLE_MM3, rel=0.02)  # phi 10: 4x as much
    assert res.removed_mm3 == pytest.approx(runs[1][1] + runs[2][1])


def test_a_program_with_a_tool_map_on_the_command_line(tmp_path: Path, capsys) -> None:
    (tmp_path / "two.nc").write_text(TWO_TOOLS)
    args = ["plan", "simulate", str(tmp_path / "two.nc"), "--stock", "box:0,50,0,40,-10,0",
            "--spacing", "0.1", "--json"]  # fmt: skip
    rc, so, se = cli([*args, "--tool", "T1=phi10-flat,T2=phi5-drill"], capsys)
    assert rc == 0, se
    (op,) = json.loads(so)["operations"]
    assert [(t["T"], t["tool"]) for t in op["tools"]] == [(1, "phi10-flat"), (2, "phi5-drill")]
    assert op["tools"][1]["removed_mm3"] == pytest.approx(2 * HOLE_MM3, rel=0.02)
    # one name for a program that changes tools stays refused, naming the block and both T
    rc, _, se = cli([*args, "--tool", "phi10-flat"], capsys)
    assert rc == 2 and len(se.strip().splitlines()) == 1
    assert "two.nc:10:" in se and "T1 to T2" in se and "T1=NAME,T2=NAME" in se
    rc, _, se = cli([*args, "--tool", "X1=phi10-flat"], capsys)
    assert rc == 2 and "X1='phi10-flat'" in se and "T<number>=TOOL" in se


def test_an_unmapped_tool_number_is_refused(tmp_path: Path, capsys) -> None:
    p = _plan(tmp_path, 'tools = { T1 = "phi10-flat" }')
    with pytest.raises(PlanningError, match=r"two.nc:10: block 9: T2 \(M6\) is not in"):
        load_plan(p)
    rc, _, se = cli(["plan", "simulate", str(p)], capsys)
    assert rc == 2 and len(se.strip().splitlines()) == 1 and "T2" in se
    # a single tool for a program that changes tools, as before
    with pytest.raises(PlanningError, match=r"changes from T1 to T2 .*\(tools = \{ T1"):
        load_plan(_plan(tmp_path, 'tool = "phi10-flat"'))
    # both or neither of tool / tools
    with pytest.raises(Exception, match="tool = NAME"):
        load_plan(_plan(tmp_path, 'tool = "phi10-flat"\ntools = { T1 = "phi10-flat" }'))


def test_the_shipped_plan_uses_each_programs_tools(capsys) -> None:
    rc, so, se = cli(["plan", "simulate", str(ROOT / "data/plans/demo-plan.toml"), "--json"],
                     capsys)  # fmt: skip
    assert rc == 0, se
    ops = {o["operation"]: o for o in json.loads(so)["operations"]}
    named = {k: [(t["T"], t["tool"]) for t in o["tools"]] for k, o in ops.items()}
    assert named == {"demo-part": [(1, "phi10-flat"), (2, "phi5-drill")],
                     "inch-features": [(3, "quarter-inch-ball"), (4, "no7-drill")]}  # fmt: skip
    # demo-part's four G83 holes, phi 5 to Z-12: at most their cylinders (some stock above them
    # is already gone), a quarter of what phi 10 would take
    drilled = ops["demo-part"]["tools"][1]["removed_mm3"]
    assert 0 < drilled <= 4 * math.pi * 2.5**2 * 12 * 1.03


def test_plan_feed_refuses_one_rule_for_a_program_that_changes_tools(tmp_path: Path,
                                                                     capsys) -> None:  # fmt: skip
    """Issue 28: a program that changes tools takes a rule per tool (tests/test_plan_multitool.py);
    one rule for two tools is refused, naming them."""
    from analysis.rules import derive_rule, save_rule, slot_load_percent

    (tmp_path / "two.nc").write_text(TWO_TOOLS)
    save_rule(derive_rule("r", 100, 600, 2000, slot_load_percent("flat", 10, 2, 22)),
              tmp_path / "rule.toml")  # fmt: skip
    rc, _, se = cli(["plan", "feed", str(tmp_path / "two.nc"), "--rules",
                     str(tmp_path / "rule.toml"), "--tool", "T1=phi10-flat,T2=phi5-drill", "-o",
                     str(tmp_path / "o.nc")], capsys)  # fmt: skip
    assert rc == 2 and "two.nc: the program changes tools (T1, T2) and --rules" in se
    assert not (tmp_path / "o.nc").exists()
