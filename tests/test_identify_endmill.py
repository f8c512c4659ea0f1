"""End-mill average-force identification against known truth, and its bad-input answers."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.config import EndMill, EndMillCoefficients, FaceMill, load_rig
from analysis.errors import AnalysisError
from analysis.identify import RunConditions, compare_runs, reduce_run
from analysis.identify.endmill import fit_endmill, fit_endmill_runs, synthetic_endmill_run
from analysis.modal import DynamometerFilter

TRUE = EndMillCoefficients(
    Ktc_n_mm2=796, Krc_n_mm2=168, Kac_n_mm2=222, Kte_n_mm=27.7, Kre_n_mm=30.8, Kae_n_mm=1.8
)
FLAT = EndMill(kind="flat", diameter_mm=10, flute_length_mm=22, flutes=3, helix_deg=30)
BALL = EndMill(kind="ball", diameter_mm=10, corner_radius_mm=5, flute_length_mm=20, flutes=2,
               helix_deg=30)  # fmt: skip
FEEDS = (0.02, 0.04, 0.06, 0.08, 0.1)


@pytest.fixture(scope="module")
def modes():
    return DynamometerFilter.from_config(load_rig().dynamometer, 20_000.0, crosstalk=False)


def _runs(tool, mode, ae, modes, seed=0, feeds=FEEDS, depth=2.0):
    rng = np.random.default_rng(seed)
    return [
        synthetic_endmill_run(
            f"{mode}_fz{fz}",
            tool,
            TRUE,
            RunConditions(spindle_rpm=3000, fz_mm=fz, depth_mm=depth, width_mm=ae, mode=mode),
            cut_s=1.0,
            noise_frac=0.02,
            dynamometer=modes,
            rng=rng,
            offset_n=rng.normal(0, 3, 3),
            phase_rad=rng.uniform(0, 6.3),
        )  # fmt: skip
        for fz in feeds
    ]


@pytest.mark.long
@pytest.mark.parametrize(("mode", "ae"), [("slot", 10.0), ("down", 3.0), ("up", 4.0)])
def test_flat_end_mill_coefficients_come_back(modes, mode, ae):
    seed = {"slot": 1, "down": 2, "up": 3}[mode]
    fit = fit_endmill_runs(_runs(FLAT, mode, ae, modes, seed=seed), FLAT)
    assert fit.success, fit.message
    for name in ("Ktc_n_mm2", "Krc_n_mm2", "Kac_n_mm2", "Kte_n_mm", "Kre_n_mm"):
        assert getattr(fit.coefficients, name) == pytest.approx(getattr(TRUE, name), rel=0.02)
    assert fit.coefficients.Kae_n_mm == pytest.approx(TRUE.Kae_n_mm, abs=0.1)
    assert fit.fit.r_squared > 0.999 and fit.residuals_n.shape == (5, 3)
    s = fit.fit.as_dict()["Ktc_n_mm2"]
    assert s["ci_low"] < 796 < s["ci_high"] or abs(s["value"] - 796) < 3 * s["std_error"] + 2


@pytest.mark.long
def test_ball_end_mill_and_validation_at_other_depth(modes):
    fit = fit_endmill_runs(_runs(BALL, "down", 4.0, modes, seed=3), BALL)
    assert fit.success, fit.message
    for name in ("Ktc_n_mm2", "Krc_n_mm2", "Kac_n_mm2", "Kte_n_mm", "Kre_n_mm"):
        assert getattr(fit.coefficients, name) == pytest.approx(getattr(TRUE, name), rel=0.03)
    other = _runs(BALL, "down", 4.0, modes, seed=4, feeds=(0.05, 0.09), depth=3.0)
    cmp = compare_runs([reduce_run(r, BALL.flutes) for r in other], BALL, fit.coefficients)
    assert cmp.max_error_pct < 3.0


@pytest.mark.long
def test_too_few_runs_one_feed_and_wrong_tool(modes):
    out = fit_endmill_runs(_runs(FLAT, "slot", 10.0, modes, feeds=(0.05, 0.1)), FLAT)
    assert not out.success and "too few runs" in out.message
    out = fit_endmill_runs(_runs(FLAT, "slot", 10.0, modes, feeds=(0.05, 0.05, 0.05)), FLAT)
    assert not out.success and "1 feed" in out.message
    fm = FaceMill(kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15,
                  axial_rake_deg=7, radial_rake_deg=0, nose_radius_mm=0.4)  # fmt: skip
    with pytest.raises(AnalysisError, match="end mills"):
        fit_endmill([], fm)
    with pytest.raises(AnalysisError, match="radial width"):
        fit_endmill_runs(_runs(FLAT, "down", np.nan, modes, feeds=(0.05,)) * 3, FLAT)


def test_tooth_peaks_show_runout():
    rng = np.random.default_rng(8)
    c = RunConditions(spindle_rpm=3000, fz_mm=0.05, depth_mm=2.0, width_mm=10.0, mode="slot")
    straight = FLAT.model_copy(update={"helix_deg": 0.0})
    clean = reduce_run(synthetic_endmill_run("c", straight, TRUE, c, cut_s=1.0, rng=rng), 3)
    wobbly_tool = straight.model_copy(update={"runout_mm": 0.01})
    wobbly = reduce_run(synthetic_endmill_run("w", wobbly_tool, TRUE, c, cut_s=1.0, rng=rng), 3)
    assert clean.tooth_peak_n.shape == (3,)
    assert clean.runout_ratio < 0.05
    # chips fz + 1.5 e, fz, fz - 1.5 e (see test_endmill_model); in a slot two teeth overlap,
    # so the peaks spread less than the chips: 0.14 here, against < 0.05 without runout
    assert wobbly.runout_ratio > 0.1
