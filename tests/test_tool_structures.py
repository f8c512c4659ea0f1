"""Every shipped end mill's twin structure and catalogue modes (issue 28 item 4).

The twin's structure of each shipped end mill (rig/sim/structure.toml) is the first bending mode
of its stick-out as a cantilever on a rigid holder; here k and f are recomputed from the
catalogue's geometry with this file's own handbook constants and the clamped-free beam's
eigenvalue solved from cos(l) cosh(l) = -1. The catalogue's modes are what `cutlab analyze
modal` measures on the shipped tap records of that structure, so they lie within the tap test's
accuracy of it. phi10-flat keeps the figures its campaigns were tuned with (700 Hz, 1.5e7 N/m:
tests/test_twin_structure.py); drills carry no modes (plan check does not check a drilling run).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from scipy.optimize import brentq

from analysis.config import get_tool, load_tools
from rig.sim.structure import twin_modes

ROOT = Path(__file__).resolve().parent.parent

#: (E in Pa, density in kg/m^3) by the catalogue's cutter material, handbook values.
HANDBOOK = {"carbide": (600e9, 14_500.0), "hss": (210e9, 8_100.0),
            "cermet": (430e9, 7_000.0), "steel": (210e9, 7_850.0)}  # fmt: skip
DERIVED = ["phi30-ball", "phi50-bull", "phi32-ball", "phi16-ball", "phi20-flat", "phi10-ball",
           "phi12-bull", "quarter-inch-ball"]  # fmt: skip


def _cantilever(name: str) -> tuple[float, float]:
    """(k N/m, f Hz) of the tool's stick-out: tip stiffness 3 E I / L^3 and the first
    clamped-free bending mode, with the fluted part's equivalent diameter 0.8 D."""
    tool = get_tool(name)
    e_pa, rho = HANDBOOK[tool.material.lower()]
    if tool.youngs_modulus_gpa is not None:
        e_pa = tool.youngs_modulus_gpa * 1e9
    d_m = 0.8 * tool.diameter_mm * 1e-3
    l_m = tool.length_mm * 1e-3
    i_m4 = math.pi * d_m**4 / 64
    area_m2 = math.pi * d_m**2 / 4
    lam = brentq(lambda x: math.cos(x) * math.cosh(x) + 1.0, 1.0, 3.0)  # 1.8751
    f_hz = lam**2 / (2 * math.pi) * math.sqrt(e_pa * i_m4 / (rho * area_m2 * l_m**4))
    return 3 * e_pa * i_m4 / l_m**3, f_hz


def test_every_shipped_end_mill_has_a_structure_and_modes() -> None:
    for name, tool in load_tools().items():
        if tool.kind == "facemill" or "drill" in name:
            continue
        assert twin_modes(tool), name
        assert {m.axis for m in tool.modes} == {"x", "y"}, name


@pytest.mark.parametrize("name", DERIVED)
def test_structure_is_the_cantilever_of_the_stickout(name: str) -> None:
    k_n_m, f_hz = _cantilever(name)
    modes = twin_modes(get_tool(name))
    assert [m.axis for m in modes] == ["x", "y"]
    for m in modes:
        assert m.k_N_m == pytest.approx(k_n_m, rel=1e-3)  # 4 digits in the file
        assert m.f_hz == pytest.approx(f_hz, rel=1e-3)
        assert 0.02 <= m.zeta <= 0.04


def test_cantilever_figures_by_hand() -> None:
    """One case by hand: phi20-flat, HSS, d_e 16 mm, L 60 mm: I = pi 0.016^4 / 64 = 3.217e-9
    m^4, k = 3 * 210e9 * 3.217e-9 / 0.06^3 = 9.383e6 N/m; f = 3.5160 / (2 pi) * (d_e / 4)
    sqrt(E / rho) / L^2 = 0.5596 * 0.004 * 5092 / 0.0036 = 3166 Hz."""
    k_n_m, f_hz = _cantilever("phi20-flat")
    assert k_n_m == pytest.approx(9.383e6, rel=1e-3)
    assert f_hz == pytest.approx(3166.0, rel=1e-3)


@pytest.mark.parametrize("name", DERIVED)
def test_catalogue_modes_measure_the_structure(name: str, capsys) -> None:  # noqa: ANN001
    """The catalogue's modes are within the tap test's accuracy of the twin's structure
    (frequency 0.1 %, damping 3 %, stiffness 3 %), and the shipped tap record analysed again
    gives the catalogue's figures."""
    from rig.cli import main

    tool = get_tool(name)
    truth = {m.axis: m for m in twin_modes(tool)}
    for mode in tool.modes:
        true = truth[mode.axis]
        assert mode.f_hz == pytest.approx(true.f_hz, rel=1e-3)
        assert mode.zeta == pytest.approx(true.zeta, rel=0.03)
        assert mode.k_N_m == pytest.approx(true.k_N_m, rel=0.03)
        assert mode.provenance is not None and mode.provenance.file
        assert main(["analyze", "modal", str(ROOT / mode.provenance.file), "--json"]) == 0
        found = json.loads(capsys.readouterr().out)["modes"]
        got = next(f for f in found if f["axis"] == mode.axis)
        assert got["frequency_hz"] == pytest.approx(mode.f_hz, rel=1e-4)
        assert got["damping_ratio"] == pytest.approx(mode.zeta, rel=1e-3)
        assert got["stiffness_n_m"] == pytest.approx(mode.k_N_m, rel=1e-3)
