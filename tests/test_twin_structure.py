"""The twin's own structure and the catalogue's measured modes (issue 28 item 4): the simulated
rig cuts with rig/sim/structure.toml, never with the catalogue's modes; the shipped tools' modes
are what `cutlab analyze modal` measures on a tap test of that structure, with their provenance."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from analysis.config import get_material, get_tool, load_rig, load_tools
from rig.sim.machine import SimMachine, ZMapStock
from rig.sim.structure import twin_modes
from rig.sim.tap import tap_twin

ROOT = Path(__file__).resolve().parent.parent


def _machine(tool) -> SimMachine:
    from planning.stock import ZMap

    stock = ZMapStock(ZMap.box(-20, 20, -20, 20, -10, 0, 0.5), tool)
    return SimMachine(tool, get_material("al6061-t6"), load_rig().dynamometer, stock, 10_000.0)


def test_the_twin_cuts_with_its_structure_not_the_catalogues_modes() -> None:
    tool = get_tool("phi10-flat")
    truth = twin_modes(tool)
    assert [(m.axis, m.f_hz, m.zeta, m.k_N_m) for m in truth] == [
        ("x", 700.0, 0.03, 1.5e7), ("y", 700.0, 0.03, 1.5e7)]  # fmt: skip
    # a catalogue claiming other modes does not change the twin's physics
    claimed = tool.model_copy(update={"modes": tuple(m.model_copy(update={"f_hz": 2000.0})
                                                     for m in tool.modes)})  # fmt: skip
    regen = _machine(claimed).regen
    assert regen is not None and regen.modes == truth
    # a cutter the twin has no assembly for cuts quasi-statically, whatever its catalogue says
    other = tool.model_copy(update={"stickout_mm": 55.0})
    assert twin_modes(other) == () and _machine(other).regen is None
    assert twin_modes(get_tool("seed003-facemill")) == ()


def test_shipped_modes_carry_their_provenance() -> None:
    for name, tool in load_tools().items():
        for m in getattr(tool, "modes", ()):
            p = m.provenance
            assert p is not None and p.source and p.command and p.date, (name, m.axis)
            assert (ROOT / p.file).exists(), (name, p.file)
            assert "analyze modal" in p.command and p.file in p.command


@pytest.mark.parametrize("axis", ["x", "y"])
def test_catalogue_modes_are_what_analyze_modal_measures(axis: str, tmp_path: Path,
                                                         capsys) -> None:  # fmt: skip
    """The shipped tap file analysed again, and a fresh tap of the twin with the recorded seed,
    give the catalogue's figures (frequency 0.1 %, damping 2 %, stiffness 2 %)."""
    from rig.cli import main

    mode = next(m for m in get_tool("phi10-flat").modes if m.axis == axis)
    seed = int(mode.provenance.command.split("--seed ")[1].split(";")[0])
    fresh = tap_twin("phi10-flat", axis, tmp_path / f"tap-{axis}.csv", seed=seed)
    for record in (ROOT / mode.provenance.file, fresh):
        assert main(["analyze", "modal", str(record), "--json"]) == 0
        found = json.loads(capsys.readouterr().out)["modes"]
        got = next(f for f in found if f["axis"] == axis)
        assert got["frequency_hz"] == pytest.approx(mode.f_hz, rel=1e-3)
        assert got["damping_ratio"] == pytest.approx(mode.zeta, rel=0.02)
        assert got["stiffness_n_m"] == pytest.approx(mode.k_N_m, rel=0.02)
