"""Every tool of a program through `plan check` and `plan feed` (issue 28): the 3-tool program
(data/programs/three-tools.nc: phi10-flat face and pocket, phi10-ball grooves, phi5-drill holes)
and the demo part, each tool's run cut by its own cutter on one stock.

References are the parts' geometry by hand (areas of the programmed shapes), the program text,
and the simulated rig's force on the demo part's T1 blocks (tests/test_plan_limits_vs_rig.py).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from analysis.rules import derive_rule, save_rule, slot_load_percent

ROOT = Path(__file__).resolve().parents[1]
THREE = ROOT / "data" / "programs" / "three-tools.nc"
DEMO = ROOT / "data" / "programs" / "demo-part.nc"
TOOLS3 = "T1=phi10-flat,T2=phi10-ball,T3=phi5-drill"
STOCK = "box:-40,40,-30,30,-20,0"  # both parts' header: 80 x 60 x 20, origin top centre


def cli(argv: list[str], capsys) -> tuple[int, str, str]:
    from rig.cli import main

    rc = main(argv)
    out = capsys.readouterr()
    return rc, out.out, out.err


def face_mm3() -> float:
    return 80 * 60 * 1.0  # the face pass: the whole top, 1 mm


def pocket_mm3() -> float:
    """The pocket: the path's rectangle X -10..10, Y -3..3 swept by the r 5 cutter, 2 mm below
    the face (the ramp's back pass runs the whole centre line at Z-3)."""
    return (20 * 6 + 2 * (20 + 6) * 5 + math.pi * 25) * 2.0


def grooves_mm3() -> float:
    """Four ball passes (r 5, bottom Z-2.5) at X 20, 23, 26, 29 across the 60 mm stock, under
    the faced top Z-1: the union of their sections by a 1-micron integration."""
    x = np.arange(10.0, 40.0, 1e-3)
    z = np.full_like(x, -1.0)
    for xc in (20, 23, 26, 29):
        d = np.abs(x - xc)
        zb = np.where(d < 5, 2.5 - np.sqrt(np.clip(25 - d**2, 0, None)), np.inf)
        z = np.minimum(z, zb)
    return float(np.sum(-1.0 - z) * 1e-3) * 60.0


def holes_mm3() -> float:
    return 4 * math.pi * 2.5**2 * 11.0  # tip at Z-12 from the faced top Z-1 (the cylinder)


@pytest.fixture(scope="module")
def three_check() -> dict:
    from planning.limits import check_job

    _, out = check_job(THREE, tool_name=TOOLS3, material="al6061-t6", stock_spec=STOCK)
    return out


def test_check_cuts_each_tool_with_its_own_cutter(three_check: dict) -> None:
    tools = {t["tool_number"]: t for t in three_check["tools"]}
    assert [tools[t]["tool"] for t in (1, 2, 3)] == ["phi10-flat", "phi10-ball", "phi5-drill"]
    # the Z-map at 0.25 mm against the shapes by hand: within 1 %
    assert tools[1]["removed_mm3"] == pytest.approx(face_mm3() + pocket_mm3(), rel=0.01)
    assert tools[2]["removed_mm3"] == pytest.approx(grooves_mm3(), rel=0.01)
    assert tools[3]["removed_mm3"] == pytest.approx(holes_mm3(), rel=0.01)
    total = sum(t["removed_mm3"] for t in tools.values())
    assert three_check["removed_mm3"] == pytest.approx(total)
    # the drill is machined but not checked, and says so; the others are checked
    assert tools[3]["verdict"] == "unchecked" and tools[3]["cutting_blocks"] == 0
    assert tools[1]["cutting_blocks"] > 0 and tools[2]["cutting_blocks"] > 0
    assert {u["tool"] for u in three_check["unchecked"] if u["limit"] == "all"} == {"T3"}


def test_check_cli_prints_each_tool_and_the_verdict(capsys) -> None:
    rc, so, _ = cli(["plan", "check", str(THREE), "--tool", TOOLS3, "--material", "al6061-t6",
                     "--stock", STOCK], capsys)  # fmt: skip
    # phi10-flat's tapped modes flag T1's deeper cuts; the drill and phi10-ball (no modes) are
    # listed as unchecked
    assert rc == 3
    assert "phi10-ball" in so and "phi5-drill" in so
    assert "verdict: violations" in so and "not checked: T3 all" in so


@pytest.fixture(scope="module")
def rules(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("rules")
    out = {"flat": d / "flat.toml", "ball": d / "ball.toml"}
    # each tool's base cut: a 1 mm full slot at 800 mm/min (flat), 1.5 mm at 1000 (ball)
    save_rule(derive_rule("flat-al", 100, 800, 3500, slot_load_percent("flat", 10, 1.0, 22),
                          tool="phi10-flat"), out["flat"])  # fmt: skip
    save_rule(derive_rule("ball-al", 100, 1000, 3500, slot_load_percent("ball", 10, 1.5, 20, 5),
                          tool="phi10-ball"), out["ball"])  # fmt: skip
    return out


def test_feed_gives_each_tool_its_rule_and_keeps_the_drill(
    rules: dict[str, Path], three_check: dict, tmp_path: Path, capsys
) -> None:
    out = tmp_path / "three-afc.nc"
    rc, so, se = cli(["plan", "feed", str(THREE), "--rules",
                      f"T1={rules['flat']},T2={rules['ball']}", "--tool", TOOLS3, "--stock",
                      STOCK, "-o", str(out), "--json"], capsys)  # fmt: skip
    assert rc == 0, se
    s = json.loads(so)
    tools = {t["tool_number"]: t for t in s["tools"]}
    assert [tools[t]["rule"] for t in (1, 2, 3)] == ["flat-al", "ball-al", None]
    for t in (1, 2, 3):  # the same cutters on the same stock as plan check
        want = {c["tool_number"]: c for c in three_check["tools"]}[t]["removed_mm3"]
        assert tools[t]["removed_mm3"] == pytest.approx(want, rel=1e-6)
    assert tools[3]["feed_time_after_s"] == tools[3]["feed_time_before_s"]
    assert tools[1]["feed_time_after_s"] != tools[1]["feed_time_before_s"]
    # the drill's lines byte for byte (the T3 M6 block to the end)
    src, new = THREE.read_text().splitlines(), out.read_text().splitlines()
    k = next(i for i, ln in enumerate(src) if "T3 M6" in ln)
    assert new[-(len(src) - k) :] == src[k:]
    # T1 and T2 blocks changed F only (the geometry check of the post), and some did change
    assert s["split_blocks"] > 0 and s["time_after_s"] < s["time_before_s"]
    assert s["verdict"] == "unchecked" and s["unchecked"][0]["reason"].startswith("no --material")


@pytest.mark.faults
def test_feed_refuses_one_rule_for_several_tools(rules: dict[str, Path], tmp_path: Path,
                                                 capsys) -> None:  # fmt: skip
    out = tmp_path / "x.nc"
    rc, _, se = cli(["plan", "feed", str(THREE), "--rules", str(rules["flat"]), "--tool",
                     TOOLS3, "--stock", STOCK, "-o", str(out)], capsys)  # fmt: skip
    assert rc == 2 and not out.exists()
    line = se.strip().splitlines()[-1]
    assert line.startswith(f"cutlab: error: {THREE}: the program changes tools (T1, T2, T3)")
    assert "T1=RULE,T2=RULE,T3=RULE" in line
    rc, _, se = cli(["plan", "feed", str(THREE), "--rules", f"T3={rules['flat']}", "--tool",
                     TOOLS3, "--stock", STOCK, "-o", str(out)], capsys)  # fmt: skip
    assert rc == 2 and not out.exists() and "T3 (phi5-drill) only drills" in se


@pytest.mark.slow
def test_demo_part_t1_in_the_whole_program_against_the_rig() -> None:
    """The demo part checked whole (T1 and the T2 drill): the T1 blocks' mean and peak force
    against the simulated rig's, per block, as the README compares them for T1 alone."""
    from test_plan_limits_vs_rig import TOLERANCE_PCT, t1_motion, twin_per_block

    from planning.limits import check_job

    res, out = check_job(DEMO, tool_name="T1=phi10-flat,T2=phi5-drill", material="al6061-t6",
                         stock_spec=STOCK)  # fmt: skip
    t1 = res[0].blocks.set_index("block")
    twin = twin_per_block(t1_motion(), 10_000.0)
    cut = twin[twin["twin_peak_n"] > 1.0].join(t1[["force_mean", "force"]], how="inner")
    assert len(cut) == 30
    mean_err = 100 * (cut["force_mean"] / cut["twin_mean_n"] - 1)
    peak_err = 100 * (cut["force"] / cut["twin_peak_n"] - 1)
    assert mean_err.abs().max() < TOLERANCE_PCT and peak_err.abs().max() < TOLERANCE_PCT
    assert [t["tool"] for t in out["tools"]] == ["phi10-flat", "phi5-drill"]


def test_lobes_per_tool(tmp_path: Path, capsys) -> None:
    """`--lobes T1=FILE`: T1's stability limit from its table (0.5 mm at every speed, 0.4 mm
    with the 0.8 margin: the 1 mm face pass breaks it), T2's from its catalogue modes (its
    1.3 mm grooves break it too: the 45 mm phi10-ball is a 4.0e6 N/m stick-out); one table for a
    program that changes tools is refused."""
    lobes = tmp_path / "lobes.csv"
    lobes.write_text("spindle_rpm,depth_limit_mm\n1000,0.5\n20000,0.5\n")
    base = ["plan", "check", str(THREE), "--tool", TOOLS3, "--material", "al6061-t6", "--stock",
            STOCK, "--spacing", "0.5"]  # fmt: skip
    rc, so, _ = cli([*base, "--lobes", f"T1={lobes}", "--json"], capsys)
    out = json.loads(so)
    assert rc == 3 and out["verdict"] == "violations"
    stab = [v for v in out["violations"] if v["limit"] == "stability"]
    assert stab and {v["tool"] for v in stab} == {"T1", "T2"}
    assert all(v["allowed"] == pytest.approx(0.4) for v in stab if v["tool"] == "T1")
    assert all(v["allowed"] != pytest.approx(0.4) for v in stab if v["tool"] == "T2")
    assert not [u for u in out["unchecked"] if u["limit"] == "stability"]
    rc, _, se = cli([*base, "--lobes", str(lobes)], capsys)
    assert rc == 2 and "a lobes table is one tool's" in se
