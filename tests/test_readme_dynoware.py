"""The README's worked example ("I have DynoWare exports of test cuts; how do I get
coefficients?") as a user types it, on the files that ship in data/dynoware/ (written by
tests/make_dynoware_example.py from a time-domain simulation apart from cutlab's fitting code;
truth.json holds the coefficients they were made with). Run in a copy of the folder: the shipped
files stay as they are.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from rig.cli import main

DATA = Path(__file__).resolve().parent.parent / "data" / "dynoware"
AXES = "x=-Fy,y=Fx,z=-Fz"


@pytest.fixture()
def lab(tmp_path, monkeypatch):
    d = tmp_path / "dynoware"
    shutil.copytree(DATA, d)
    monkeypatch.chdir(d)
    return d


def _check(coefficients: dict, truth: dict) -> None:
    for name, value in truth.items():
        # cutting coefficients within 2 %; the small edge ones within 2 % or 0.1 N/mm (noise)
        tol = 0.02 * value if name.endswith("c") else max(0.02 * value, 0.1)
        assert coefficients[name] == pytest.approx(value, abs=tol), name


def test_readme_worked_example(lab, capsys):
    truth = json.loads((lab / "truth.json").read_text())["coefficients"]
    exports = sorted(str(p.name) for p in lab.glob("cut_*.txt"))
    common = ["--tool", "lab-phi25-2f", "--tools", "my_tools.toml"]
    rc = main(["analyze", "forces", *exports, "--model", "endmill", *common, "--conditions",
               "conditions.csv", "--axes", AXES, "--json"])  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["success"] and out["axes"] == AXES
    _check(out["coefficients"], truth)
    assert out["adequacy"]["edge_identified"]
    # exports with the air trimmed: taken as zeroed, and said so
    assert len([w for w in out["warnings"] if "taken as zeroed" in w]) == len(exports)

    rc = main(["data", "import", *exports, "--conditions", "conditions.csv", "--axes", AXES,
               *common, "-o", "runs"])  # fmt: skip
    capsys.readouterr()
    assert rc == 0
    runs = sorted(str(p) for p in (lab / "runs").glob("*.h5"))
    assert len(runs) == len(exports)
    rc = main(["analyze", "forces", *runs, *common, "--json"])
    again = json.loads(capsys.readouterr().out)
    assert rc == 0
    for name in truth:
        assert again["coefficients"][name] == pytest.approx(out["coefficients"][name], rel=1e-3)


def test_default_mapping_warns_with_figures(lab, capsys):
    """Without --axes the turned dynamometer gives swapped, negative coefficients: said, with
    the figures of the mapping that fits."""
    exports = sorted(str(p.name) for p in lab.glob("cut_*.txt"))
    rc = main(["analyze", "forces", *exports, "--model", "endmill", "--tool", "lab-phi25-2f",
               "--tools", "my_tools.toml", "--conditions", "conditions.csv", "--json"])  # fmt: skip
    cap = capsys.readouterr()
    assert rc == 2 and cap.out == "" and len(cap.err.strip().splitlines()) == 1  # refused
    assert "negative cutting coefficient" in cap.err and "Krc -7" in cap.err
    # slots at one depth fit several mappings alike: said, and --axes asked for
    assert "Ktc 72" in cap.err and "cannot tell them apart" in cap.err and "give --axes" in cap.err


def test_readme_endmill_slot_example(tmp_path, monkeypatch, capsys):
    """The README's end-mill example on data/slots/ (tests/make_slot_example.py, from the same
    independent simulation): each export states its feed in a ``fz_mm`` header line; the 0.1 mm
    cut is beyond phi10-flat's largest chip and is named and left out."""
    slots = DATA.parent / "slots"
    shutil.copytree(slots, tmp_path / "slots")
    monkeypatch.chdir(tmp_path / "slots")
    truth = json.loads(Path("truth.json").read_text())["coefficients"]
    exports = sorted(str(p.name) for p in Path().glob("slot_*.csv"))
    conditions = ["--conditions", "spindle_rpm=3000", "depth_mm=2", "mode=slot"]
    rc = main(["analyze", "forces", *exports, "--model", "endmill", "--tool", "phi10-flat",
               *conditions, "--json"])  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["success"] and len(exports) == 5
    _check(out["coefficients"], truth)
    assert out["adequacy"]["edge_identified"]
    assert [(e["run"], e["kept"]) for e in out["outside_limits"]] == [("slot_0.1", False)]
