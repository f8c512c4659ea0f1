"""`cutlab analyze modal` on a CSV hammer record."""

from __future__ import annotations

import json

import pytest
from _cli_inputs import hammer_csv

from rig.cli import main


def test_modal_command(tmp_path, capsys):
    path = hammer_csv(tmp_path / "hammer_x.csv")
    png = tmp_path / "frf.png"
    rc = main(["analyze", "modal", str(path), "--rpm", "600", "24600", "--teeth", "5",
               "--plot", str(png), "--json"])  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    (mode,) = out["modes"]
    assert mode["axis"] == "x"
    assert mode["frequency_hz"] == pytest.approx(2050, rel=0.01)
    assert mode["damping_ratio"] == pytest.approx(0.02742, rel=0.1)
    assert any("24600 rpm" in w for w in out["warnings"])
    assert png.stat().st_size > 10_000
    rc = main(["analyze", "modal", str(path), "--hammer", "impact"])
    assert rc == 2 and "no hammer channel" in capsys.readouterr().err
