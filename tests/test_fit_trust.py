"""How far an end-mill fit holds (issue 27, item 1 and 4), on exports made by the independent
simulator (tests/_force_sim.py, no fitting code): a four-feed slot sweep whose 0.1 mm cut exceeds
phi10-flat's max chip (0.08 mm) and whose forces rise there as the twin's chip breaker makes them.
The truth is the simulator's law; nothing is taken from the code under test."""

from __future__ import annotations

import json

import pytest

from rig.cli import main
from tests._trust_exports import TRUTH, export

FEEDS = (0.03, 0.05, 0.08, 0.1)
COMMON = ["--model", "endmill", "--tool", "phi10-flat"]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    return [str(export(d, fz, seed=k)) for k, fz in enumerate(FEEDS)]


def test_a_run_beyond_the_max_chip_is_named_and_left_out(sweep, capsys):
    rc = main(["analyze", "forces", *sweep, *COMMON, "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["success"]
    (lim,) = out["outside_limits"]
    assert lim["run"] == "slot_ae10_fz0.1" and not lim["kept"]
    assert "max chip thickness 0.1 mm > the tool's max_chip_mm 0.08 mm" in lim["reason"]
    assert "slot_ae10_fz0.1" not in out["runs"] and "--keep" in out["message"]
    for name in ("Ktc_n_mm2", "Krc_n_mm2", "Kac_n_mm2"):
        assert out["coefficients"][name] == pytest.approx(TRUTH[name], rel=0.02), name
        assert out["statistics"][name]["status"] == "identified"
    # per direction and per run, N and %
    assert set(out["by_direction"]) == {"x", "y", "z"}
    assert all(v["r_squared"] > 0.999 for v in out["by_direction"].values())
    assert [r["run"] for r in out["run_residuals"]] == out["runs"]
    assert all(abs(p) < 0.5 for r in out["run_residuals"] for p in r["residual_pct"])


def test_kept_the_run_is_flagged_and_the_coefficients_are_not_identified(sweep, capsys):
    rc = main(["analyze", "forces", *sweep, *COMMON, "--keep", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and "slot_ae10_fz0.1" in out["runs"] and out["outside_limits"][0]["kept"]
    # the bent fit (Ktc near 1517 against 796): named by leave-one-out, not identified
    assert out["coefficients"]["Ktc"] > 1.5 * TRUTH["Ktc_n_mm2"]
    (bad,) = [r for r in out["influence"]["runs"] if r["moved"]]
    assert bad["run"] == "slot_ae10_fz0.1" and "Ktc" in bad["moved"]
    assert bad["without"]["Ktc"] == pytest.approx(TRUTH["Ktc_n_mm2"], rel=0.02)
    st = out["statistics"]["Ktc_n_mm2"]
    assert not st["identified"] and st["status"].startswith("not identified: depends on one run")
    assert out["coefficient_status"]["Ktc"] == st["status"]
    # the pooled R^2 looks good; each direction's does not
    assert out["r_squared"] > 0.97
    assert all(v["r_squared"] < 0.9 for v in out["by_direction"].values())
    rc = main(["analyze", "forces", *sweep, *COMMON, "--keep"])
    text = capsys.readouterr().out
    (line,) = [ln for ln in text.splitlines() if ln.startswith("Ktc_n_mm2")]
    assert "not identified: depends on one run: slot_ae10_fz0.1" in line
    assert "leave-one-out: run slot_ae10_fz0.1 moves Ktc by" in text
    assert "fit per direction: x: R^2" in text and "kept (--keep): slot_ae10_fz0.1" in text
    assert "chip thickness checked against max_chip_mm 0.08 mm; speeds unchecked" in text
