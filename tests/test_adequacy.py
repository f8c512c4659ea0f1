"""Model adequacy: a size effect (force ~ h^0.75) against edge forces (F = K h b + P b), on mean
forces made by the independent simulation (tests/_force_sim.py), with known truth."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.config import EndMill
from analysis.identify import ForceRun, RunConditions
from analysis.identify.adequacy import compare_models
from analysis.identify.endmill import fit_endmill_runs
from tests._force_sim import Cut, Law, Record, mean_force, simulate

LINEAR = Law("linear", dict(Ktc_n_mm2=796, Krc_n_mm2=168, Kac_n_mm2=222, Kte_n_mm=27.7,
                            Kre_n_mm=30.8, Kae_n_mm=1.8))  # fmt: skip
SIZE = Law("power", dict(Kt=500.0, Kr=180.0, Ka=90.0), mc=0.25)  # force ~ h^0.75
FEEDS = (0.03, 0.05, 0.08, 0.12, 0.2)


def _means(law, feeds, noise, seed=0):
    """Mean forces (runs, 3) of slots 2 mm deep, each off by ``noise`` (relative, rms)."""
    rng = np.random.default_rng(seed)
    f = np.array([mean_force(Cut(fz_mm=fz, depth_mm=2.0), law, slices=4, n_phi=720)
                  for fz in feeds])  # fmt: skip
    return f * (1 + noise * rng.normal(size=f.shape))


@pytest.mark.parametrize("noise", [0.0, 0.005])
def test_size_effect_data_is_recognised(noise):
    a = compare_models(FEEDS, [2.0] * 5, _means(SIZE, FEEDS, noise))
    assert a.verdict == "size_effect" and not a.edge_identified
    assert a.exponent == pytest.approx(0.75, abs=0.02)
    assert "add cuts at fz below 0.015 and above 0.3 mm/tooth" in a.suggestion


@pytest.mark.parametrize("noise", [0.0, 0.005])
def test_ploughing_data_is_recognised(noise):
    a = compare_models(FEEDS, [2.0] * 5, _means(LINEAR, FEEDS, noise))
    assert a.verdict == "edge" and a.edge_identified
    assert "linear model fits better" in a.line()


def test_one_feed_cannot_separate_them():
    """Seed 003's design: one feed per tooth, several depths."""
    a = compare_models([0.236] * 3, [0.5, 1.5, 3.0], _means(SIZE, [0.236] * 3, 0.0))
    assert a.verdict == "undecided" and not a.edge_identified
    assert "1 feed(s)" in a.reason and "NOT identified" in a.line()


def test_an_end_mill_fit_on_size_effect_runs_says_the_edge_is_not_identified():
    tool = EndMill(kind="flat", diameter_mm=10, flute_length_mm=22, flutes=3, helix_deg=30)
    runs = []
    for k, fz in enumerate(FEEDS):
        _, f = simulate(Cut(fz_mm=fz), SIZE, Record(steady_revs=40, noise_n=1.0, seed=k))
        runs.append(ForceRun(f"fz{fz}", f, 20_000.0, RunConditions(
            spindle_rpm=3000, fz_mm=fz, depth_mm=2.0, width_mm=10.0, mode="slot")))  # fmt: skip
    fit = fit_endmill_runs(runs, tool)
    assert fit.success and fit.fit.r_squared > 0.99  # the straight line fits well ...
    assert fit.adequacy.verdict == "size_effect"  # ... but the data are curved
    assert "edge coefficients Kte, Kre, Kae not identified" in fit.message
