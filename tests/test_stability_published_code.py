"""Lobes against the semi-discretization code Insperger & Stepan published with their benchmark
(IJNME 61, 2004, appendix), run in GNU Octave: an implementation written by others, of another
order (zeroth-order semi-discretization; cutlab's is a third-order full discretization).

The reference values (tests/data/stability/published_sd.csv, made once, provenance in the README
beside it) are the benchmark's cases: 1-DOF (N = 2, Kt 6e8 N/m^2, Kn 2e8 N/m^2, 922 Hz, zeta 0.011,
m 0.03993 kg) at a/D = 1, 0.5, 0.1, 0.05 in up and down milling, and the same mode in x and y
(2-DOF) for the slot and a/D = 0.05 down; 41 speeds from 5000 to 25000 rpm. The issue's criterion:
median deviation and minimum critical depth within 2 %.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.stability import StabilityCase, stability_lobes

DATA = Path(__file__).parent / "data" / "stability" / "published_sd.csv"
CASES = {  # name: (modes, a/D, milling)
    "d1-slot": (("x",), 1.0, "down"),
    "d1-up-0.5": (("x",), 0.5, "up"),
    "d1-down-0.5": (("x",), 0.5, "down"),
    "d1-up-0.1": (("x",), 0.1, "up"),
    "d1-down-0.1": (("x",), 0.1, "down"),
    "d1-up-0.05": (("x",), 0.05, "up"),
    "d1-down-0.05": (("x",), 0.05, "down"),
    "d2-slot": (("x", "y"), 1.0, "down"),
    "d2-down-0.05": (("x", "y"), 0.05, "down"),
}
W0 = 2 * np.pi * 922.0


def _case(name: str, rpm: np.ndarray) -> StabilityCase:
    modes, ae, milling = CASES[name]
    n = len(modes)
    return StabilityCase(
        teeth=2, milling=milling, radial_immersion=ae, kt_n_m2=6e8, kn_n_m2=2e8,
        f_hz=np.full(n, 922.0), zeta=np.full(n, 0.011), k_n_m=np.full(n, 0.03993 * W0**2),
        direction=modes, rpm=rpm, name=name,
    )  # fmt: skip


@pytest.fixture(scope="module")
def reference() -> pd.DataFrame:
    return pd.read_csv(DATA)


@pytest.mark.long
@pytest.mark.parametrize("name", list(CASES))
def test_lobes_match_the_published_code(reference: pd.DataFrame, name: str) -> None:
    ref = reference[reference["case"] == name]
    assert len(ref) == 41
    lobes = stability_lobes(_case(name, ref["spindle_rpm"].to_numpy()), "sd")
    mine, theirs = lobes.depth_limit_mm, ref["depth_limit_mm"].to_numpy()
    # deeper than cutlab searches (30 x the ZOA minimum) is "stable" there
    beyond = theirs > lobes.depth_max_mm
    assert np.isfinite(mine[~beyond]).all() and np.isinf(mine[beyond]).all()
    assert beyond.sum() <= 3  # (the reference searched up to 50 mm)
    mine, theirs = mine[~beyond], theirs[~beyond]
    dev = np.abs(mine / theirs - 1)
    assert np.median(dev) < 0.02, (name, np.median(dev))
    assert mine.min() == pytest.approx(theirs.min(), rel=0.02)


def test_default_lobes_are_converged_where_30_steps_read_high() -> None:
    """2-DOF a/D 0.05 down milling at 6700-6900 rpm: 30 steps per tooth period read 10-14 %
    above the converged limit (the unsafe side); the default doubles the steps per speed until
    the limit moves by at most 1 % and says so."""
    rpm = np.linspace(6700, 6900, 5)
    case = _case("d2-down-0.05", rpm)
    fixed30 = stability_lobes(case, "sd", 30).depth_limit_mm
    fine = stability_lobes(case, "sd", 240).depth_limit_mm
    lobes = stability_lobes(case, "sd")
    assert (fixed30 / fine - 1).min() > 0.08  # the fault the default had
    assert np.abs(lobes.depth_limit_mm / fine - 1).max() < 0.01
    conv = lobes.convergence()
    assert conv["checked"] and conv["max_change_pct"] <= 1.0 and conv["unconverged_speeds"] == 0
    assert (lobes.steps >= 30).all()
