"""Identification against an independent time-domain simulation (tests/_force_sim.py: helical
slices, runout, dynamometer modes, spindle wobble, noise; it shares no code with the fit)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.config import EndMill
from analysis.identify import ForceRun, RunConditions, reduce_run
from analysis.identify.endmill import fit_endmill_runs
from tests._force_sim import Cut, Law, Record, simulate

COEF = dict(Ktc_n_mm2=796, Krc_n_mm2=168, Kac_n_mm2=222, Kte_n_mm=27.7, Kre_n_mm=30.8, Kae_n_mm=1.8)
TOOL = EndMill(kind="flat", diameter_mm=10, flute_length_mm=22, flutes=3, helix_deg=30)
FEEDS = (0.04, 0.06, 0.08, 0.1, 0.12)
RUNOUT = (0.001, -0.0005, -0.0005)  # mm per tooth
RATE = 20_000.0
# Modes far above the tooth-passing band (150 Hz): the mean forces the fit uses cannot see them.
MODES = ((2500.0, 0.03), (2900.0, 0.03), (4100.0, 0.02))


def _real(fz, mode="slot", ae=10.0, seed=0, scale=1.0, runout=RUNOUT, **rec):
    """A real-looking record: runout, tooth-to-tooth scatter, 0.5 % speed wobble, modes, noise."""
    entry, exit_ = Cut.immersion(ae, 10.0, mode)
    cut = Cut(fz_mm=fz, depth_mm=2.0, entry_rad=entry, exit_rad=exit_,
              runout_mm=runout, tooth_scale=(1.0, 1.02, 0.98))  # fmt: skip
    law = Law("linear", {k: v * scale for k, v in COEF.items()})
    kw = dict(rate_hz=RATE, rpm_wobble=0.005, noise_n=3.0, modes=MODES,
              offset_n=(4.0, -2.0, 1.0), seed=seed)  # fmt: skip
    t, f = simulate(cut, law, Record(**{**kw, **rec}))
    cond = RunConditions(spindle_rpm=3000, fz_mm=fz, depth_mm=2.0, width_mm=ae, mode=mode)
    return ForceRun(f"{mode}_fz{fz}", f, RATE, cond)


@pytest.mark.parametrize(("mode", "ae", "runout"), [("slot", 10.0, RUNOUT), ("down", 3.0, ())])
def test_six_coefficients_come_back_within_2_percent(mode, ae, runout):
    """Runout stays out of the down-milling case: near the exit the chip f_z sin(phi) is thinner
    than a few microns of runout, a tooth's chip clips at zero and the mean force is no longer
    linear in f_z (3 um of runout at ae = 3 mm, f_z 0.02..0.1: K_tc +6 %, K_te -9 %)."""
    runs = [_real(fz, mode, ae, seed=k, runout=runout) for k, fz in enumerate(FEEDS)]
    fit = fit_endmill_runs(runs, TOOL)
    assert fit.success, fit.message
    for name, true in COEF.items():
        # K_ae is a 2 N axial force in down milling against 3 N of noise per sample
        tol = dict(abs=0.1) if name == "Kae_n_mm" and mode == "down" else dict(rel=0.02)
        assert getattr(fit.coefficients, name) == pytest.approx(true, **tol), name
    assert fit.adequacy.verdict == "edge" and fit.adequacy.edge_identified
    row = fit.fit.as_dict()["Ktc_n_mm2"]
    assert row["boot_ci_low"] < row["value"] < row["boot_ci_high"]


def test_steady_part_of_a_real_cut_keeps_90_percent():
    """120 steady revolutions between 6-revolution ramps and air: at the default tolerance at
    least 108 are kept, and the reason for the rest is given."""
    avg = reduce_run(_real(0.05, steady_revs=120, air_revs=8), TOOL.flutes)
    assert avg.revolutions >= 108
    assert avg.steady.startswith(f"kept {avg.revolutions} of ") and "entry" in avg.steady
    # the refined period (the speed wobbles) may fit a revolution or two fewer in the window
    assert avg.revolutions - 3 <= len(avg.revolution_means_n) <= avg.revolutions


def test_a_cut_with_the_air_trimmed_is_all_cutting():
    """The operator trimmed the air: every revolution cuts; no 'no cutting found', the offset is
    the record's zero (the amplifier was reset before the cut)."""
    run = _real(0.05, steady_revs=60, air_revs=0, ramp_revs=0, offset_n=(0.0, 0.0, 0.0))
    avg = reduce_run(run, TOOL.flutes)
    assert avg.revolutions >= 56
    assert "no air" in avg.steady
    assert np.allclose(avg.offset_n, 0.0)


@pytest.mark.long
def test_bootstrap_intervals_cover_the_truth_in_most_seeds():
    """20 campaigns of 5 runs, each run's material 1 % off the nominal (a real cut's run-to-run
    scatter): the 95 % bootstrap interval holds K_tc in at least 17."""
    hits = {name: 0 for name in COEF}
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        runs = [_real(fz, seed=1000 * seed + k, scale=1 + 0.01 * rng.normal(),
                      steady_revs=40, air_revs=4, ramp_revs=3, rate_hz=10_000.0, modes=())
                for k, fz in enumerate(FEEDS)]  # fmt: skip
        rows = fit_endmill_runs(runs, TOOL).fit.as_dict()
        for name, true in COEF.items():
            hits[name] += rows[name]["boot_ci_low"] <= true <= rows[name]["boot_ci_high"]
    assert min(hits.values()) >= 17, hits
