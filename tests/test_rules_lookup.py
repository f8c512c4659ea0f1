"""Each tool's rule from the rule base by tool and material when `plan feed` gets no --rules
(issue 28 item 1): the same program as with the rules named, drills and tools the base lacks
keep their feeds and are listed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PROGRAM = ROOT / "data" / "programs" / "three-tools.nc"
TOOLS = "T1=phi10-flat,T2=phi10-ball,T3=phi5-drill"
STOCK = "box:-40,40,-30,30,-20,0"


def cli(argv: list[str], capsys) -> tuple[int, str, str]:
    from rig.cli import main

    rc = main(argv)
    out = capsys.readouterr()
    return rc, out.out, out.err


def add(db: Path, rule: str, flute_mm: float, capsys) -> None:
    rc, _, se = cli(["rules", "add", str(ROOT / "data" / "rules" / rule), "--part-family", "demo",
                     "--operation", "pocket", "--tool-diameter", "10", "--flute-length",
                     str(flute_mm), "--material", "al6061-t6", "--spindle", "8000", "--depth", "1",
                     "--tolerance", "0.1", "--db", str(db)], capsys)  # fmt: skip
    assert rc == 0, se


def feed(out: Path, *extra: str) -> list[str]:
    return ["plan", "feed", str(PROGRAM), "--tool", TOOLS, "--stock", STOCK, "--spacing", "0.5",
            "-o", str(out), "--json", *extra]  # fmt: skip


def test_rules_looked_up_by_tool_and_material(tmp_path: Path, capsys) -> None:
    db = tmp_path / "rb.sqlite"
    add(db, "flat.toml", 22.0, capsys)  # its rule was derived with phi10-flat
    rc, so, se = cli(feed(tmp_path / "a.nc", "--material", "al6061-t6", "--db", str(db)), capsys)
    assert rc == 0, se
    found = {r["tool"]: r for r in json.loads(so)["rule_lookup"]}
    assert found["phi10-flat"]["rule"] == "flat-al" and found["phi10-flat"]["exact"]
    # phi10-ball: no rule derived with it, none of its diameter and flute length (20 mm)
    assert found["phi10-ball"]["rule"] is None and "no rule for phi10-ball" in found[
        "phi10-ball"]["reason"]  # fmt: skip
    assert found["phi5-drill"]["rule"] is None and "only drills" in found["phi5-drill"]["reason"]
    add(db, "ball.toml", 20.0, capsys)
    rc, so, se = cli(feed(tmp_path / "b.nc", "--material", "al6061-t6", "--db", str(db)), capsys)
    assert rc == 0, se
    rules = {t["tool"]: t["rule"] for t in json.loads(so)["tools"]}
    assert rules == {"phi10-flat": "flat-al", "phi10-ball": "ball-al", "phi5-drill": None}
    named = f"T1={ROOT}/data/rules/flat.toml,T2={ROOT}/data/rules/ball.toml"
    rc, _, se = cli(feed(tmp_path / "c.nc", "--rules", named), capsys)
    assert rc == 0, se
    assert (tmp_path / "b.nc").read_bytes() == (tmp_path / "c.nc").read_bytes()


def test_no_rules_and_no_material_is_refused(tmp_path: Path, capsys) -> None:
    rc, _, se = cli(feed(tmp_path / "a.nc"), capsys)
    assert rc == 2 and "no --rules: give --material" in se
    with pytest.raises(AssertionError):
        assert (tmp_path / "a.nc").exists()
