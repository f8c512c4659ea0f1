"""The simulated rig's tap test and the stability report's "true" lobes come from the twin's own
structure (rig/sim/structure.toml) when a campaign gives no [[sim.tool_modes]], never from the
catalogue's modes, which are a measurement of it (issue 28 item 4).

The campaign's catalogue (tools_file) claims phi10-flat modes at 2000 Hz and 5e7 N/m; the twin's
structure for that assembly is 700 Hz, 1.5e7 N/m (the shipped stability-sweep campaign's figures,
whose 5500 rpm trough limit is 0.746 mm)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from analysis.config import get_tool
from analysis.modal import modal_file
from rig.campaign import load_campaign, run_campaign
from rig.campaign.runner import tap_records, twin_tool_modes
from rig.sim.structure import twin_modes

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = ROOT / "configs" / "campaigns" / "stability-sweep.toml"
CLAIMED = """[tools.phi10-flat]
kind = "flat"
diameter_mm = 10.0
flute_length_mm = 22.0
flutes = 3
helix_deg = 30.0
stickout_mm = 40.0
max_force_n = 2200
max_chip_mm = 0.08
deflection_tol_mm = 0.05
modes = [
    { axis = "x", f_hz = 2000.0, zeta = 0.05, k_N_m = 5e7 },
    { axis = "y", f_hz = 2000.0, zeta = 0.05, k_N_m = 5e7 },
]
"""


def _campaign(tmp_path: Path, matrix: str) -> Path:
    """The shipped sweep without [[sim.tool_modes]], with the claiming catalogue and ``matrix``."""
    text = SHIPPED.read_text()
    text = text[: text.index("\n[[sim.tool_modes]]")] + text[text.index("\n[tap_test]"):]
    text = text[: text.index("\n[[matrix]]")] + "\n" + matrix
    tools = tmp_path / "tools.toml"
    tools.write_text(CLAIMED)
    text = text.replace('output_dir = "data/campaigns"', f"output_dir = {json.dumps(str(tmp_path))}"
                        f"\ntools_file = {json.dumps(str(tools))}")  # fmt: skip
    cfg = tmp_path / "sweep.toml"
    cfg.write_text(text)
    return cfg


def test_the_tap_test_taps_the_twins_structure(tmp_path: Path) -> None:
    matrix = '[[matrix]]\ngroup = "g"\nspindle_rpm = 5500\nfz_mm = 0.05\ndepth_mm = [0.3]\n'
    campaign = load_campaign(_campaign(tmp_path, matrix))
    assert campaign.spec.sim.tool_modes is None
    assert campaign.tool.modes[0].f_hz == 2000.0  # the catalogue's claim
    truth = twin_modes(get_tool("phi10-flat"))
    assert twin_tool_modes(campaign) == truth and truth[0].f_hz == 700.0
    records = tap_records(campaign, tmp_path / "run")
    out = modal_file(records["x"], response="disp")
    (mode,) = out["modes"]
    assert mode["frequency_hz"] == pytest.approx(700.0, rel=0.005)
    assert mode["stiffness_n_m"] == pytest.approx(1.5e7, rel=0.05)


def test_a_campaigns_own_tool_modes_win(tmp_path: Path) -> None:
    campaign = load_campaign(SHIPPED)
    assert twin_tool_modes(campaign) == tuple(campaign.spec.sim.tool_modes)


@pytest.mark.long
def test_the_reports_true_lobes_are_the_twins(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """One shallow cut: the report's true limit at 5500 rpm is the structure's (0.746 mm, as the
    tapped modes give), not the claimed modes' (several mm)."""
    from rig.cli import main

    matrix = '[[matrix]]\ngroup = "g"\nspindle_rpm = 5500\nfz_mm = 0.05\ndepth_mm = [0.3]\n'
    cfg = _campaign(tmp_path, matrix)
    assert run_campaign(load_campaign(cfg), progress=False).ok
    capsys.readouterr()
    assert main(["campaign", "report", str(cfg), "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)["onset"]
    assert row["true_limit_mm"] == pytest.approx(0.746, rel=0.03)
    assert row["predicted_limit_mm"] == pytest.approx(row["true_limit_mm"], rel=0.02)
