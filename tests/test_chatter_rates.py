"""Chatter detection's rates on the regenerative twin, the truth from the twin's own force.

The cuts and the truth are bench/bench_chatter_detect.py's: the true cutting force (before the
dynamometer, noise and the DAQ), its share of power off the tooth-passing harmonics per quarter
of the cut, never the detector's features. The detector sees the force through the
dynamometer's modes with noise and hum, and the commanded speed (the twin's spindle runs up to
0.3 % off it). Depths are fractions of the semi-discretization limit (analysis.stability) of
each case, written here as computed by the bench (``sd_limit_mm``) so the default run does not
recompute them.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from analysis.chatter import ChatterSettings, detect_chatter

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))

from bench_chatter_detect import (  # noqa: E402
    RATE_HZ,
    Cut,
    near_tooth_harmonic,
    rates,
    run_half,
    simulate,
    truth,
)

# (teeth, immersion, holder, SD limit mm at 6000 rpm, depth factor, seed, speed error, truth)
CASES = [
    # The cut: three flutes at 6000 rpm, tooth frequency 300 Hz.
    (3, "slot", "A", 0.9901, 0.5, 1108, 0.00094, "stable"),
    (3, "slot", "A", 0.9901, 0.8, 1109, -0.00149, "stable"),
    (3, "slot", "A", 0.9901, 1.2, 1112, -0.00054, "chatter"),
    (3, "slot", "A", 0.9901, 1.5, 1113, -0.00017, "chatter"),
    (2, "slot", "B", 2.287, 0.8, 1007, 0.00152, "stable"),
    (2, "slot", "B", 2.287, 1.2, 1010, 0.00183, "chatter"),
    (2, "half-up", "B", 3.4459, 0.8, 1031, -0.00094, "stable"),
    (2, "half-up", "B", 3.4459, 1.5, 1035, -0.00111, "chatter"),
    (2, "quarter-down", "B", 4.3079, 0.8, 1091, 0.00179, "stable"),
    (2, "quarter-down", "B", 4.3079, 1.2, 1094, 0.00124, "chatter"),
    (3, "half-up", "A", 2.7138, 0.5, 1132, 0.0011, "stable"),
    (3, "half-up", "A", 2.7138, 1.2, 1136, -0.00227, "chatter"),
    (4, "slot", "B", 2.3264, 0.8, 1217, 0.00107, "stable"),
    (4, "slot", "B", 2.3264, 1.2, 1220, -0.00274, "chatter"),
    (4, "quarter-up", "B", 3.842, 0.8, 1289, -0.00073, "stable"),
    (4, "quarter-up", "B", 3.842, 1.5, 1293, -0.00182, "chatter"),
]


def test_fixed_cuts_stable_never_flagged_chattering_caught_never_at_a_tooth_harmonic() -> None:
    """16 cuts at 6000 rpm, 2-4 teeth, slot, half and quarter immersion: every stable cut (the
    twin's truth) judged stable with the library defaults, every chattering one caught, at a
    frequency away from the tooth-passing harmonics."""
    wrong = []
    for teeth, imm, holder, limit, factor, seed, err, expected in CASES:
        cut = Cut(teeth, imm, holder, 6000.0, factor, limit, seed, err)
        f_true, f_meas, exit_s = simulate(cut)
        says, shares, _ = truth(f_true, cut.rpm * (1 + err), teeth, exit_s)
        assert says == expected, (cut, shares)  # the twin itself, before the detector
        r = detect_chatter(f_meas, RATE_HZ, cut.rpm)
        if r.chatter != (says == "chatter"):
            wrong.append((cut.group, factor, r.whole))
        if r.chatter:
            assert not near_tooth_harmonic(r.frequency_hz, cut), (cut, r.frequency_hz)
    assert not wrong, wrong


def test_the_old_defaults_called_these_stable_cuts_chatter() -> None:
    """The issue's 3-flute slot at 6000 rpm, 0.8 x the limit: the former detector (an
    unwindowed spectrum with a 2 % band, energy 0.1 and opr 0.1) called this kind of cut chatter
    (energy 0.37, opr 0.47 measured on it at 0.5 and 0.8 x); the window, the band and the speed
    taken from the record keep the ripple's spread near the harmonics."""
    cut = Cut(3, "slot", "A", 6000.0, 0.8, 0.9901, 1109, -0.00149)
    _, f_meas, _ = simulate(cut)
    r = detect_chatter(f_meas, RATE_HZ, cut.rpm)
    assert not r.chatter and r.whole.energy_ratio < 0.1
    assert r.whole.spindle_rpm_measured == pytest.approx(6000.0 * (1 - 0.00149), rel=2e-4)
    assert r.whole.band_hz == pytest.approx(0.05 * r.whole.spindle_rpm_measured / 60)


def test_settings_growth_and_band_are_validated() -> None:
    from analysis.errors import AnalysisError

    with pytest.raises(AnalysisError, match="growth_ratio"):
        ChatterSettings(growth_ratio=0.0)
    with pytest.raises(AnalysisError, match="harmonic_band"):
        ChatterSettings(harmonic_band=1.5)


@pytest.mark.slow
def test_held_out_rates_meet_the_targets() -> None:
    """The bench's held-out half (252 cuts at speeds the defaults were not chosen on): no false
    positive on a stable cut, none at a tooth harmonic, at most 5 % of the chatter beyond 1.1 x
    the limit missed (period-doubling chatter of even tooth counts, seen only at spindle
    harmonics, is counted apart)."""
    judged = run_half("held")
    r = rates(judged)
    assert r["stable"] >= 50 and r["beyond"] >= 50
    assert r["fp"] <= 0.01 * r["stable"] and r["fp_at_tooth"] == 0
    assert r["missed_beyond"] <= 0.05 * r["beyond"]
