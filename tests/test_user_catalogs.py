"""User tool and material catalogues next to the data (issue 17): ``--tools FILE`` /
``--materials FILE`` on every command that reads the catalogues, and a campaign's
``tools_file`` / ``materials_file``; a name in them shadows the shipped one, configs/ untouched."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from analysis.config import get_material, get_tool, user_catalogs
from analysis.errors import ConfigError

ROOT = Path(__file__).parents[1]

MY_TOOLS = """[tools.my-flat]
kind = "flat"
description = "a phi 6 end mill of my own"
diameter_mm = 6.0
flute_length_mm = 15.0
flutes = 3
helix_deg = 30.0
stickout_mm = 30.0

# shadows the shipped phi10-flat with an 8 mm cutter
[tools.phi10-flat]
kind = "flat"
diameter_mm = 8.0
flute_length_mm = 22.0
flutes = 3
helix_deg = 30.0
stickout_mm = 40.0
"""
MY_MATERIALS = """[materials.my-alu]
description = "my aluminium"
density_kg_m3 = 2700

[materials.my-alu.endmill]
Ktc_n_mm2 = 700
Krc_n_mm2 = 150
Kac_n_mm2 = 200
Kte_n_mm = 25
Kre_n_mm = 30
Kae_n_mm = 2
"""
# one straight slot, 1 mm deep, 30 mm long
SLOT = "G21 G90 G17\nS6000 M3\nG0 X10 Y20 Z5\nG1 Z-1 F200\nG1 X40 F600\nG0 Z5\nM30\n"


def slot_mm3(d_mm: float) -> float:
    return (30 * d_mm + math.pi * d_mm**2 / 4) * 1.0


def cli(argv: list[str], capsys) -> tuple[int, str, str]:
    from rig.cli import main

    rc = main(argv)
    out = capsys.readouterr()
    return rc, out.out, out.err


@pytest.fixture
def files(tmp_path: Path) -> Path:
    (tmp_path / "my-tools.toml").write_text(MY_TOOLS)
    (tmp_path / "my-materials.toml").write_text(MY_MATERIALS)
    (tmp_path / "slot.nc").write_text(SLOT)
    return tmp_path


def test_user_catalogue_comes_first_and_goes_away(files: Path) -> None:
    shipped = (ROOT / "configs" / "tools.toml").read_text()
    with user_catalogs(files / "my-tools.toml", files / "my-materials.toml"):
        assert get_tool("my-flat").diameter_mm == 6.0
        assert get_tool("phi10-flat").diameter_mm == 8.0  # shadowed
        assert get_tool("phi20-flat").diameter_mm == 20.0  # the shipped ones stay
        assert get_material("my-alu").endmill.Ktc_n_mm2 == 700
    assert get_tool("phi10-flat").diameter_mm == 10.0
    with pytest.raises(ConfigError, match="tool 'my-flat' not found"):
        get_tool("my-flat")
    assert (ROOT / "configs" / "tools.toml").read_text() == shipped


def test_plan_simulate_with_a_user_tool(files: Path, capsys) -> None:
    args = ["plan", "simulate", str(files / "slot.nc"), "--stock", "box:0,50,0,40,-5,0",
            "--spacing", "0.1", "--json", "--tools", str(files / "my-tools.toml")]  # fmt: skip
    for tool, d in (("my-flat", 6.0), ("phi10-flat", 8.0)):
        rc, so, se = cli([*args, "--tool", tool], capsys)
        assert rc == 0, se
        assert json.loads(so)["removed_mm3"] == pytest.approx(slot_mm3(d), rel=0.02)
    rc, _, se = cli(args[:-2] + ["--tool", "my-flat"], capsys)
    assert rc == 2 and "tool 'my-flat' not found" in se


def test_plan_check_with_a_user_tool_and_material(files: Path, capsys) -> None:
    rc, so, se = cli(["plan", "check", str(files / "slot.nc"), "--tool", "my-flat", "--material",
                      "my-alu", "--stock", "box:0,50,0,40,-5,0", "--spacing", "0.5", "--json",
                      "--tools", str(files / "my-tools.toml"), "--materials",
                      str(files / "my-materials.toml")], capsys)  # fmt: skip
    assert rc == 4, se  # my-flat has no modes: stability unchecked, never "within"
    out = json.loads(so)
    assert out["tool"] == "my-flat" and out["verdict"] == "unchecked"


def _campaign(files: Path, extra: str = "") -> Path:
    text = (ROOT / "configs" / "campaigns" / "feed-sweep.toml").read_text()
    text = text.replace('tool = "phi30-ball"', f'tool = "my-ball"{extra}')
    p = files / "camp.toml"
    p.write_text(text)
    ball = (ROOT / "configs" / "tools.toml").read_text().split("[tools.phi30-ball]")[1]
    (files / "ball.toml").write_text("[tools.my-ball]" + ball.split("\n[")[0])
    return p


def test_campaign_dry_run_with_a_user_tool(files: Path, capsys) -> None:
    p = _campaign(files, '\ntools_file = "ball.toml"')  # relative to the campaign file
    rc, so, se = cli(["campaign", "run", str(p), "--dry-run", "--json"], capsys)
    assert rc == 0, se
    p = _campaign(files)
    rc, _, se = cli(["campaign", "run", str(p), "--dry-run", "--json"], capsys)
    assert rc == 2 and "tool 'my-ball' not found" in se
    rc, _, se = cli(["campaign", "run", str(p), "--dry-run", "--json", "--tools",
                     str(files / "ball.toml")], capsys)  # fmt: skip
    assert rc == 0, se


def test_a_bad_catalogue_is_one_line_naming_it(files: Path, capsys) -> None:
    (files / "bad.toml").write_text('[tools.x]\nkind = "flat"\ndiameter_mm = -1\n')
    for name in ("missing.toml", "bad.toml"):
        rc, _, se = cli(["plan", "simulate", str(files / "slot.nc"), "--tool", "my-flat",
                         "--tools", str(files / name)], capsys)  # fmt: skip
        assert rc == 2 and len(se.strip().splitlines()) == 1
        assert se.startswith(f"cutlab: error: {files / name}")
    p = _campaign(files, '\ntools_file = "bad.toml"')
    rc, _, se = cli(["campaign", "run", str(p), "--dry-run"], capsys)
    # --dry-run lists every problem, one line each, each naming the catalogue
    lines = se.strip().splitlines()
    assert rc == 2 and lines and all(
        ln.startswith("cutlab: error: ") and str(files / "bad.toml") in ln for ln in lines
    ), lines


@pytest.mark.parametrize(
    "cmd",
    [["plan", "simulate"], ["plan", "feed"], ["plan", "check"], ["plan", "rough"],
     ["plan", "orient"], ["rules", "derive"], ["campaign", "run"], ["campaign", "status"],
     ["campaign", "report"]],
)  # fmt: skip
def test_every_catalogue_reader_takes_the_options(cmd: list[str], capsys) -> None:
    with pytest.raises(SystemExit):
        cli([*cmd, "--help"], capsys)
    out = capsys.readouterr().out
    assert "--tools FILE" in out and "--materials FILE" in out and "shadows" in out
