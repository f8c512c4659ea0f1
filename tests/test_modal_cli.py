"""`cutlab analyze modal` on a CSV hammer record."""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis.modal import DynamometerFilter
from rig.cli import main


def test_modal_command(tmp_path, capsys):
    fs = 51_200.0
    filt = DynamometerFilter.from_table(fs, [2050, 1810, 3230], [0.02742, 0.0872, 0.10178])
    rng = np.random.default_rng(0)
    n = int(fs * 0.5)
    t = np.arange(n) / fs
    ham = np.zeros(n)
    for t0 in (0.02, 0.12, 0.22, 0.32):
        m = (t >= t0) & (t < t0 + 0.00015)
        ham[m] = 100 * np.sin(np.pi * (t[m] - t0) / 0.00015)
    f = np.zeros((n, 3))
    f[:, 0] = ham
    y = filt.apply(f) + rng.normal(0, 0.05, (n, 3))
    path = tmp_path / "hammer_x.csv"
    np.savetxt(path, np.column_stack([t, ham, y]), delimiter=",", fmt="%.7g",
               header="time_s,hammer,Fx,Fy,Fz", comments="")  # fmt: skip
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
