"""`cutlab plan check`, and the limits in `plan feed` / `plan rough` (issue 22): the command
contract (``violations``: block, limit, value), the seed 000 deep level, --limit."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from analysis.rules import derive_rule, save_rule, slot_load_percent


def cli(argv: list[str], capsys) -> tuple[int, str, str]:
    from rig.cli import main

    rc = main(argv)
    out = capsys.readouterr()
    return rc, out.out, out.err


# The deepest level of seed 000's bisection plan as one slot: phi20-flat (HSS, 4 teeth) 37.8 mm
# deep, 300 mm/min at 1000 rpm (fz 0.075 mm) in al6061-t6.
DEEP = "G21 G90 G17\nS1000 M3\nG0 X-15 Y0 Z5\nG1 Z-37.8 F100\nG1 X100 F300\nG0 Z5\nM30\n"


@pytest.mark.long
def test_check_flags_the_deep_hss_slot(tmp_path: Path, capsys) -> None:
    prog = tmp_path / "deep.nc"
    prog.write_text(DEEP)
    png = tmp_path / "check.png"
    rc, so, _ = cli(["plan", "check", str(prog), "--tool", "phi20-flat", "--material",
                     "al6061-t6", "--stock", "box:-30,110,-20,20,-40,0", "--spacing", "0.5",
                     "--json", "--plot", str(png)], capsys)  # fmt: skip
    assert rc == 3 and png.exists()  # 3: a verdict that failed
    out = json.loads(so)
    assert out["verdict"] == "violations"
    slot = [v for v in out["violations"] if v["block"] == 4]
    # the slot chatters too: 37.8 mm against the phi20-flat's few-mm lobes (its catalogue modes)
    assert {v["limit"] for v in slot} == {"deflection", "stability"}
    v = next(v for v in slot if v["limit"] == "deflection")
    # a full slot of 37.8 mm: about 4.0 kN sideways on a 9383 N/mm stick-out (3 E I / L^3,
    # HSS 210 GPa, d_e 16 mm, L 60 mm) -> about 0.43 mm against the 0.1 mm allowed
    assert v["allowed"] == 0.1 and 0.35 < v["value"] < 0.5 and v["margin_pct"] < -200
    assert out["limits"]["base_rpm"] == pytest.approx(750.3, abs=0.1)  # 11 kW / 140 N m


def test_check_refuses_a_bad_lobes_file(tmp_path: Path, capsys) -> None:
    prog = tmp_path / "deep.nc"
    prog.write_text(DEEP)
    lobes = tmp_path / "lobes.csv"
    lobes.write_text("spindle_rpm,depth_limit_mm\n1000,x\n")
    rc, _, se = cli(["plan", "check", str(prog), "--tool", "phi20-flat", "--material",
                     "al6061-t6", "--lobes", str(lobes)], capsys)  # fmt: skip
    assert rc == 2
    assert se.strip().splitlines()[-1] == (
        f"cutlab: error: {lobes}:2: depth_limit_mm = x: expected > 0 (mm) or empty"
    )


STEP = """%
O0431
N10 G21 G90 G17
N15 S2000 M3
N20 G0 X-20. Y30. Z5.
N30 G1 Z-0.7 F1000
N40 G1 X215.
N50 G0 Z50.
N60 M30
%
"""


# long: two plan feed runs of the phi 30 ball (~10 s); the limited feeds themselves are checked
# quick in tests/test_plan_limits.py (test_limited_feeds_break_no_limit_and_keep_the_path)
@pytest.mark.long
def test_feed_limit_leaves_no_violation(tmp_path: Path, capsys) -> None:
    (tmp_path / "step.nc").write_text(STEP)
    save_rule(derive_rule("r", 100, 1000, 3500, slot_load_percent("ball", 30, 0.7, 30)),
              tmp_path / "rule.toml")  # fmt: skip
    base = ["plan", "feed", str(tmp_path / "step.nc"), "--rules", str(tmp_path / "rule.toml"),
            "--tool", "phi30-ball", "--stock", "box:-30,230,0,60,-10,0", "--spacing", "0.5",
            "--material", "gm241", "--json"]  # fmt: skip
    # the 0.7 mm slot of the phi 30 ball in GM241 takes about 0.077 kW at the rule's feed
    machine = tmp_path / "m.toml"
    text = (Path(__file__).parents[1] / "configs" / "machines" / "ace-h63.toml").read_text()
    machine.write_text(text.replace("spindle_power_kw = 11", "spindle_power_kw = 0.05"))
    rc, so, _ = cli(base + ["-o", str(tmp_path / "a.nc"), "--machine", str(machine)], capsys)
    free = json.loads(so)
    assert rc == 3 and free["violations"]  # written, but over a limit
    assert {v["limit"] for v in free["violations"]} == {"power"}
    rc, so, _ = cli(base + ["-o", str(tmp_path / "b.nc"), "--machine", str(machine), "--limit"],
                    capsys)  # fmt: skip
    capped = json.loads(so)
    assert rc == 0 and capped["violations"] == []
    assert capped["time_after_s"] > free["time_after_s"]
    assert any("limits cap the feed" in n for n in capped["notes"])


@pytest.mark.slow
@pytest.mark.timeout(1200)  # the limit step re-checks 74 levels: 3-5 min of CPU
def test_rough_seed000_deep_level_is_split_and_chatter_it_cannot_cure_is_named(
    tmp_path: Path, capsys
) -> None:
    """The 37.8 mm level of seed 000 (HSS phi 20) breaks the deflection limit; --limit splits
    it. With phi20-flat's modes the stable depth (0.28-0.57 mm) needs sub-levels under the
    part's dh_mm = 0.5: those levels are named, not split into passes that still chatter."""
    args = ["plan", "rough", "seed000-bump", "--machine", "ace-h63", "--no-png", "--json",
            "-o", str(tmp_path / "b.nc"), "--limit"]  # fmt: skip
    rc, so, _ = cli(args, capsys)
    res = json.loads(so)
    lim = res["limits"]
    assert lim["before"]["violations"] > 0
    assert any(s["height_mm"] == pytest.approx(37.795) for s in lim["levels_split"])
    assert {v["limit"] for v in res["violations"]} == {"stability"}  # deflection cured
    assert lim["not_split"] and all(n["sub_level_mm"] < n["dh_mm"] for n in lim["not_split"])
    assert res["verdict"] == "violations"
    assert lim["path_added_mm"] > 0 and lim["time_lost_s"] > 0


MODES = "".join(
    f'\n[[{{table}}]]\n{{axis}} = "{ax}"\nf_hz = 1000.0\nzeta = 0.03\nk_N_m = 2.0e7\n'
    for ax in "xy"
)  # a stiff 2-dof tool tip: a slot's chatter-free depth of about 1.27 mm at 6000 rpm


def _slot_nc(depth_mm: float) -> str:
    return (f"G21 G90 G17\nS6000 M3\nG0 X-10 Y0 Z5\nG1 Z{-depth_mm:g} F100\nG1 X40 F600\n"
            "G0 Z5\nM30\n")  # fmt: skip


def test_stability_from_tool_modes_matches_analyze_stability(tmp_path: Path, capsys) -> None:
    """A user tool with [[tools.NAME.modes]] and no --lobes: the limit is the chatter-free depth
    `cutlab analyze stability` finds for the same case (3 teeth, full slot, down milling, the
    material's Ktc / Krc, the same modes) times the 0.8 margin."""
    from analysis.config import get_material

    tools = tmp_path / "tools.toml"
    tools.write_text('[tools.flex10]\nkind = "flat"\ndiameter_mm = 10.0\nflute_length_mm = 22.0\n'
                     "flutes = 3\nhelix_deg = 30.0\nstickout_mm = 40.0\n"
                     + MODES.format(table="tools.flex10.modes", axis="axis"))  # fmt: skip
    coef = get_material("al6061-t6").endmill
    case = tmp_path / "case.toml"
    case.write_text(f'[tool]\nteeth = 3\n[cut]\nmilling = "down"\nradial_immersion = 1.0\n'
                    f"[coefficients]\nKtc_N_mm2 = {coef.Ktc_n_mm2}\nKrc_N_mm2 = {coef.Krc_n_mm2}\n"
                    + MODES.format(table="modes", axis="axis")
                    + "[spindle]\nrpm_min = 6000\nrpm_max = 6001\npoints = 2\n")  # fmt: skip
    lobes = tmp_path / "lobes.csv"
    rc, _, _ = cli(["analyze", "stability", str(case), "-o", str(lobes)], capsys)
    assert rc == 0
    depth_6000 = float(lobes.read_text().splitlines()[1].split(",")[1])
    assert 1.0 < depth_6000 < 1.5
    base = ["plan", "check", "--tool", "flex10", "--tools", str(tools), "--material",
            "al6061-t6", "--stock", "box:-20,50,-20,20,-20,0", "--json"]  # fmt: skip
    for depth, broken in ((3.0, True), (0.9 * 0.8 * depth_6000, False)):
        prog = tmp_path / f"slot{depth:g}.nc"
        prog.write_text(_slot_nc(depth))
        rc, so, _ = cli(["plan", "check", str(prog), *base[2:]], capsys)
        out = json.loads(so)
        # flex10 gives no max_chip_mm nor deflection_tol_mm: without a violation, "unchecked"
        assert rc == (3 if broken else 4) and out["limits"]["stability"].startswith("tool modes")
        assert out["verdict"] == ("violations" if broken else "unchecked")
        assert {u["limit"] for u in out["unchecked"]} == {"chip", "deflection"}
        slot = [v for v in out["violations"] if v["block"] == 4]
        assert bool(slot) is broken
        if broken:
            v = slot[0]
            assert v["limit"] == "stability" and v["value"] == pytest.approx(depth)
            assert v["allowed"] == pytest.approx(0.8 * depth_6000, rel=2e-3)
    # the same limit from the lobes CSV
    rc, so, _ = cli(["plan", "check", str(tmp_path / "slot3.nc"), *base[2:], "--lobes",
                     str(lobes)], capsys)  # fmt: skip
    v = [v for v in json.loads(so)["violations"] if v["block"] == 4][0]
    assert v["allowed"] == pytest.approx(0.8 * depth_6000, rel=2e-3)
