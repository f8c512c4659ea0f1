"""Verdicts scripts can trust (issue 28): `plan check` exits 0 only when every block is within
every limit and every limit was checked, 3 when a block breaks one, 4 when none does but a limit
could not be checked (listed with its reason), 2 on bad input; a stock always (given, or derived
and printed); a program that removes nothing is an error naming its stock, never a saving.

The cases are slots whose figures are worked by hand: a phi 10, 3-flute end mill at 6000 rpm and
600 mm/min cuts fz = 600 / (3 x 6000) = 0.033 mm, under the 0.08 mm allowed; its stiff 2-dof
tip (1000 Hz, zeta 0.03, 2e7 N/m) chatters in a full slot of al6061-t6 above about 1.27 mm
(`cutlab analyze stability`, tests/test_plan_check_cli.py), 1.02 mm with the 0.8 margin.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from analysis.rules import derive_rule, save_rule, slot_load_percent

MODES = "".join(
    f'\n[[tools.stiff10.modes]]\naxis = "{ax}"\nf_hz = 1000.0\nzeta = 0.03\nk_N_m = 2.0e7\n'
    for ax in "xy"
)
BODY = ('kind = "flat"\ndiameter_mm = 10.0\nflute_length_mm = 22.0\nflutes = 3\n'
        'helix_deg = 30.0\nstickout_mm = 40.0\nmax_chip_mm = 0.08\ndeflection_tol_mm = 0.05\n')
# stiff10 with its modes; bare10, a user's tool without any
TOOL = "[tools.stiff10]\n" + BODY + MODES + "\n[tools.bare10]\n" + BODY


def slot(depth_mm: float, z_top_mm: float = 0.0, x0_mm: float = -10.0) -> str:
    """A 50 mm slot along X from ``x0_mm``, ``depth_mm`` under ``z_top_mm``."""
    z, up = z_top_mm - depth_mm, z_top_mm + 5
    return (f"G21 G90 G17\nS6000 M3\nG0 Z{up:g}\nG0 X{x0_mm:g} Y0\nG1 Z{z:g} F100\n"
            f"G1 X{x0_mm + 50:g} F600\nG0 Z{up:g}\nM30\n")  # fmt: skip


def cli(argv: list[str], capsys) -> tuple[int, str, str]:
    from rig.cli import main

    rc = main(argv)
    out = capsys.readouterr()
    return rc, out.out, out.err


@pytest.fixture()
def files(tmp_path: Path) -> Path:
    (tmp_path / "tools.toml").write_text(TOOL)
    for name, d in (("shallow", 0.5), ("deep", 3.0)):
        (tmp_path / f"{name}.nc").write_text(slot(d))
    return tmp_path


def check(files: Path, prog: str, tool: str, *extra: str) -> list[str]:
    return ["plan", "check", str(files / prog), "--tool", tool, "--tools",
            str(files / "tools.toml"), "--material", "al6061-t6", "--stock",
            "box:-20,50,-20,20,-20,0", "--spacing", "0.5", *extra]  # fmt: skip


def test_within_every_limit_exits_0(files: Path, capsys) -> None:
    rc, so, _ = cli(check(files, "shallow.nc", "stiff10", "--json"), capsys)
    out = json.loads(so)
    assert rc == 0 and out["verdict"] == "within"
    assert out["violations"] == [] and out["unchecked"] == []
    assert out["limits"]["stability"].startswith("tool modes")
    rc, so, _ = cli(check(files, "shallow.nc", "stiff10"), capsys)
    assert rc == 0 and "verdict: within: every block within every limit" in so


def test_a_violation_exits_3(files: Path, capsys) -> None:
    rc, so, _ = cli(check(files, "deep.nc", "stiff10", "--json"), capsys)
    out = json.loads(so)
    assert rc == 3 and out["verdict"] == "violations"
    assert "stability" in {v["limit"] for v in out["violations"]}
    rc, so, _ = cli(check(files, "deep.nc", "stiff10"), capsys)
    assert rc == 3 and "verdict: violations" in so


def test_a_tool_without_modes_is_unchecked_exit_4(files: Path, capsys) -> None:
    """The same shallow slot with a user's tool without modes: within every limit that was
    checked, but stability was not: never "within"."""
    rc, so, _ = cli(check(files, "shallow.nc", "bare10", "--json"), capsys)
    out = json.loads(so)
    assert rc == 4 and out["verdict"] == "unchecked" and out["violations"] == []
    assert [u["limit"] for u in out["unchecked"]] == ["stability"]
    assert "bare10 has no modes" in out["unchecked"][0]["reason"]
    rc, so, _ = cli(check(files, "shallow.nc", "bare10"), capsys)
    assert rc == 4 and "every block within every limit" not in so
    assert "verdict: unchecked" in so and "not checked: stability" in so


def test_the_shipped_tool_is_checked_for_stability_by_default(files: Path, capsys) -> None:
    """phi10-flat carries the modes tapped on the twin (700 Hz, zeta 0.03, 1.5e7 N/m): the slot
    limit at 6000 rpm is about 0.99 mm (0.79 mm with the margin), so 0.5 mm is within and 3 mm
    is a stability violation, with no --lobes and no modes given."""
    rc, so, _ = cli(check(files, "shallow.nc", "phi10-flat", "--json"), capsys)
    out = json.loads(so)
    assert rc == 0 and out["verdict"] == "within" and out["unchecked"] == []
    assert out["limits"]["stability"].startswith("tool modes")
    rc, so, _ = cli(check(files, "deep.nc", "phi10-flat", "--json"), capsys)
    out = json.loads(so)
    assert rc == 3 and "stability" in {v["limit"] for v in out["violations"]}


def test_a_machine_without_a_spindle_curve_is_unchecked(files: Path, capsys) -> None:
    root = Path(__file__).resolve().parents[1]
    text = (root / "configs" / "machines" / "ace-h63.toml").read_text().splitlines()
    machine = files / "m.toml"
    machine.write_text("\n".join(ln for ln in text if not ln.startswith(
        ("spindle_power_kw", "spindle_torque_nm"))) + "\n")  # fmt: skip
    rc, so, _ = cli(check(files, "shallow.nc", "stiff10", "--machine", str(machine), "--json"),
                    capsys)  # fmt: skip
    out = json.loads(so)
    assert rc == 4 and {u["limit"] for u in out["unchecked"]} == {"power", "torque"}


def test_help_documents_the_exit_statuses(capsys) -> None:
    from rig.cli import main

    with pytest.raises(SystemExit):
        main(["plan", "check", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for part in ("0 every block within every limit", "3 a block breaks a limit", "4 none",
                 "2 bad input"):  # fmt: skip
        assert part in text


def test_without_stock_it_is_derived_and_printed(files: Path, capsys) -> None:
    """The slot's feed moves span X -10..40, Y 0, Z -0.5..5: with the r 5 cutter the box is
    X -15..45, Y -5..5, bottom 1 mm under the slot's floor and the top at Z0 (the slot's level
    is below it)."""
    argv = ["plan", "check", str(files / "shallow.nc"), "--tool", "stiff10", "--tools",
            str(files / "tools.toml"), "--material", "al6061-t6", "--spacing", "0.5"]  # fmt: skip
    rc, so, se = cli([*argv, "--json"], capsys)
    out = json.loads(so)
    assert rc == 0, se
    assert out["stock"]["source"] == "derived"
    assert out["stock"]["spec"] == "box:-15,45,-5,5,-1.5,0"
    assert out["stock"]["allowance_mm"] == 1.0
    # a 10 mm wide slot, 0.5 deep: 50 mm of centre line plus the cutter's disc (all in the box)
    assert out["removed_mm3"] == pytest.approx((50 * 10 + 3.14159 * 25) * 0.5, rel=0.01)
    rc, _, se = cli(argv, capsys)
    assert "stock: box:-15,45,-5,5,-1.5,0 (derived" in se


def test_a_program_above_z0_gets_its_top_above_the_highest_level(files: Path, capsys) -> None:
    """A program in the part's frame (levels above Z0): the derived top is 1 mm above its
    highest level, so the slot removes a 1 mm layer, not nothing. (The slot runs X 20..70: the
    program starts at X0 Y0 Z0, which would be inside a box over X -10..40.)"""
    (files / "high.nc").write_text(slot(0.5, z_top_mm=10.0, x0_mm=20.0))  # the level at Z9.5
    rc, so, se = cli(["plan", "check", str(files / "high.nc"), "--tool", "stiff10", "--tools",
                      str(files / "tools.toml"), "--material", "al6061-t6", "--spacing", "0.5",
                      "--json"],
                     capsys)  # fmt: skip
    out = json.loads(so)
    assert rc == 0, se
    assert out["stock"]["spec"] == "box:15,75,-5,5,-1,10.5"
    assert out["removed_mm3"] == pytest.approx((50 * 10 + 3.14159 * 25) * 1.0, rel=0.01)


@pytest.mark.faults
def test_a_program_that_removes_nothing_is_refused(files: Path, tmp_path: Path, capsys) -> None:
    stock = "box:-20,50,-20,20,-40,-30"  # under the slot: nothing to cut
    argv = check(files, "shallow.nc", "stiff10")
    argv[argv.index("--stock") + 1] = stock
    rc, so, se = cli(argv, capsys)
    assert rc == 2 and so == ""
    assert se.strip().splitlines() == [
        f"cutlab: error: {files / 'shallow.nc'}: the program removes nothing from its stock "
        f"{stock} (--stock): give the stock it cuts (--stock box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP)"
    ]
    rule = tmp_path / "rule.toml"
    save_rule(derive_rule("r", 100, 600, 3500, slot_load_percent("flat", 10, 0.5, 22)), rule)
    out = tmp_path / "out.nc"
    rc, so, se = cli(["plan", "feed", str(files / "shallow.nc"), "--rules", str(rule), "--tool",
                      "stiff10", "--tools", str(files / "tools.toml"), "--stock", stock, "-o",
                      str(out), "--spacing", "0.5"], capsys)  # fmt: skip
    assert rc == 2 and not out.exists() and "time saved" not in so
    assert se.strip().splitlines()[-1].endswith(f"removes nothing from its stock {stock} "
                                                "(--stock): give the stock it cuts (--stock "
                                                "box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP)")  # fmt: skip


def test_plan_feed_states_its_verdict(files: Path, tmp_path: Path, capsys) -> None:
    rule = tmp_path / "rule.toml"
    save_rule(derive_rule("r", 100, 600, 3500, slot_load_percent("flat", 10, 0.5, 22)), rule)
    base = ["plan", "feed", str(files / "shallow.nc"), "--rules", str(rule), "--tool", "stiff10",
            "--tools", str(files / "tools.toml"), "--stock", "box:-20,50,-20,20,-20,0",
            "--spacing", "0.5"]  # fmt: skip
    rc, so, _ = cli([*base, "-o", str(tmp_path / "a.nc"), "--json"], capsys)
    s = json.loads(so)
    assert rc == 0 and s["verdict"] == "unchecked"  # no --material: nothing checked
    assert s["stock"] == {"source": "--stock", "spec": "box:-20,50,-20,20,-20,0"}
    rc, so, _ = cli([*base, "-o", str(tmp_path / "b.nc"), "--material", "al6061-t6"], capsys)
    assert rc == 0 and "verdict: within: every block within every limit" in so


def test_check_plot_without_cutting_says_so(tmp_path: Path) -> None:
    from planning.limits.plot import plot_check

    png = plot_check([], tmp_path / "none.png")
    assert png.exists() and png.stat().st_size > 1000


def test_the_twins_chattering_cut_is_not_passed(tmp_path: Path, capsys) -> None:
    """The issue's case: a 0.82 mm full slot at 5500 rpm with phi10-flat chatters on the twin
    (stability-sweep: tapped modes 700 Hz, zeta 0.03, 1.5e7 N/m; limit 0.746 mm there). Without
    modes or lobes plan check says "unchecked" (exit 4), never "within"; with the lobes of the
    twin's modes (`cutlab analyze stability`) it is a stability violation (exit 3); the shipped
    phi10-flat carries those modes, tapped on the twin, so it is one without --lobes too."""
    import tomllib

    from analysis.config import get_material

    camp = Path(__file__).resolve().parents[1] / "configs" / "campaigns" / "stability-sweep.toml"
    modes = tomllib.loads(camp.read_text())["sim"]["tool_modes"]
    coef = get_material("al6061-t6").endmill
    case = tmp_path / "case.toml"
    case.write_text(
        f'[tool]\nteeth = 3\n[cut]\nmilling = "down"\nradial_immersion = 1.0\n'
        f"[coefficients]\nKtc_N_mm2 = {coef.Ktc_n_mm2}\nKrc_N_mm2 = {coef.Krc_n_mm2}\n"
        + "".join(f'[[modes]]\naxis = "{m["axis"]}"\nf_hz = {m["f_hz"]}\nzeta = {m["zeta"]}'
                  f'\nk_N_m = {m["k_N_m"]}\n' for m in modes)
        + "[spindle]\nrpm_min = 5500\nrpm_max = 5501\npoints = 2\n"
    )  # fmt: skip
    lobes = tmp_path / "lobes.csv"
    rc, _, _ = cli(["analyze", "stability", str(case), "-o", str(lobes)], capsys)
    assert rc == 0
    limit = float(lobes.read_text().splitlines()[1].split(",")[1])
    assert limit == pytest.approx(0.746, abs=0.01)  # the README's stability-sweep figure
    prog = tmp_path / "chatter.nc"
    prog.write_text("G21 G90 G17\nS5500 M3\nG0 Z5\nG0 X-10 Y0\nG1 Z-0.82 F100\nG1 X40 F825\n"
                    "G0 Z5\nM30\n")  # fmt: skip
    base = ["plan", "check", str(prog), "--tool", "phi10-flat", "--material", "al6061-t6",
            "--stock", "box:-20,50,-20,20,-20,0", "--spacing", "0.5", "--json"]  # fmt: skip
    rc, so, _ = cli(base, capsys)
    out = json.loads(so)
    # the shipped phi10-flat carries the modes tapped on the twin: checked without --lobes
    assert rc == 3 and out["limits"]["stability"].startswith("tool modes")
    v = next(v for v in out["violations"] if v["limit"] == "stability")
    assert v["value"] == pytest.approx(0.82)
    assert v["allowed"] == pytest.approx(0.8 * limit, rel=0.01)
    # the same cutter without modes (a user's tool): unchecked (exit 4), never "within"
    tools = tmp_path / "tools.toml"
    tools.write_text("[tools.bare10]\n" + BODY)
    bare = [*base[:4], "bare10", "--tools", str(tools), *base[5:]]
    rc, so, _ = cli(bare, capsys)
    assert rc == 4 and json.loads(so)["verdict"] == "unchecked"
    rc, so, _ = cli([*bare, "--lobes", str(lobes)], capsys)
    out = json.loads(so)
    assert rc == 3 and out["verdict"] == "violations"
    v = next(v for v in out["violations"] if v["limit"] == "stability")
    assert v["value"] == pytest.approx(0.82) and v["allowed"] == pytest.approx(0.8 * limit)
