"""Dynamometer modes from synthetic impulse-hammer records with seed 003 Table 2's modes."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from analysis.config import load_rig
from analysis.errors import AnalysisError
from analysis.modal import DynamometerFilter
from analysis.modal.hammer import (
    ImpactRecord,
    double_hit,
    half_power,
    modal_analysis,
    tooth_passing_warnings,
)

FS = 51_200.0
# Seed 003 Table 2, with the workpiece mounted (x, y, z).
TABLE2 = {"x": (2050.0, 0.02742), "y": (1810.0, 0.08720), "z": (3230.0, 0.10178)}


def _record(axis: int, seed: int, hits=(0.02, 0.12, 0.22, 0.32, 0.42), bounce_at=None, modes=None):
    rng = np.random.default_rng(seed)
    filt = modes or DynamometerFilter.from_table(
        FS, [v[0] for v in TABLE2.values()], [v[1] for v in TABLE2.values()]
    )
    n = int(FS * 0.6)
    t = np.arange(n) / FS
    ham = np.zeros(n)
    w = 0.00015  # 0.15 ms half-sine: a steel tip, flat spectrum to ~6 kHz
    for k, t0 in enumerate(hits):
        t0 += rng.uniform(0, 0.001)
        m = (t >= t0) & (t < t0 + w)
        ham[m] = rng.uniform(80, 120) * np.sin(np.pi * (t[m] - t0) / w)
        if bounce_at == k:
            t1 = t0 + 0.003
            m = (t >= t1) & (t < t1 + w)
            ham[m] = 40 * np.sin(np.pi * (t[m] - t1) / w)
    f = np.zeros((n, 3))
    f[:, axis] = ham
    resp = filt.apply(f) + rng.normal(0, 0.05, (n, 3))
    return ImpactRecord(ham + rng.normal(0, 0.05, n), resp, FS, ("x", "y", "z"), f"hit-{axis}")


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_table2_modes_come_back(axis):
    name = "xyz"[axis]
    res = modal_analysis(_record(axis, seed=axis))
    (mode,) = res.modes
    f, z = TABLE2[name]
    assert mode.channel == name
    assert mode.frequency_hz == pytest.approx(f, rel=0.01)
    assert mode.damping_ratio == pytest.approx(z, rel=0.10)
    # The exponential window's damping was taken out: the raw value is larger.
    assert mode.damping_windowed > mode.damping_ratio
    assert mode.half_power_frequency_hz == pytest.approx(f, rel=0.03)
    assert mode.coherence > 0.95
    assert {s[0] for s in res.skipped} == set("xyz") - {name}


def test_modes_from_the_rig_config_filter():
    dyno = load_rig().dynamometer
    filt = DynamometerFilter.from_config(dyno, FS, crosstalk=False)
    res = modal_analysis(_record(1, seed=11, modes=filt))
    cfg = {m.axis: m for m in dyno.modes}["y"]
    assert res.modes[0].frequency_hz == pytest.approx(cfg.frequency_hz, rel=0.01)
    assert res.modes[0].damping_ratio == pytest.approx(cfg.damping_ratio, rel=0.10)


def test_double_hit_is_detected_and_left_out():
    res = modal_analysis(_record(0, seed=3, bounce_at=2))
    assert res.double_hits == (2,)
    assert 2 not in res.hits_used
    assert any("double hit" in w for w in res.warnings)
    assert res.modes[0].frequency_hz == pytest.approx(2050, rel=0.01)
    pulse = np.zeros(500)
    pulse[10:18] = np.sin(np.linspace(0, np.pi, 8))
    assert not double_hit(pulse, FS)
    pulse[200:208] = 0.3 * np.sin(np.linspace(0, np.pi, 8))
    assert double_hit(pulse, FS)


def test_half_power_of_a_single_mode():
    f = np.linspace(100, 5000, 20000)
    fn, z = 2000.0, 0.03
    r = f / fn
    mag = 1 / np.sqrt((1 - r * r) ** 2 + (2 * z * r) ** 2)
    fp, zh = half_power(f, mag, 500, 4000)
    assert fp == pytest.approx(fn * np.sqrt(1 - 2 * z * z), rel=1e-4)
    assert zh == pytest.approx(z, rel=0.02)


def test_one_hit_is_analysed_with_a_warning_and_the_spread_over_orders():
    rec = _record(0, seed=5, hits=(0.02,))
    res = modal_analysis(rec)
    (mode,) = res.modes
    assert mode.frequency_hz == pytest.approx(TABLE2["x"][0], rel=0.01)
    assert np.isfinite(mode.frequency_uncertainty_hz) and np.isfinite(mode.damping_uncertainty)
    assert "one hit: no coherence" in res.warnings[0]
    assert "+-" in res.warnings[0]


def test_no_usable_hit_and_flat_hammer():
    rec = _record(0, seed=5, hits=(0.02,), bounce_at=0)
    with pytest.raises(AnalysisError, match="no usable hit"):
        modal_analysis(rec)
    flat = ImpactRecord(np.zeros(1000), np.zeros((1000, 3)), FS)
    with pytest.raises(AnalysisError, match="flat"):
        modal_analysis(flat)


def test_tooth_passing_warning():
    modes = load_rig().dynamometer.modes
    # Seed 003: 600 rpm, one insert -> 10 Hz, far below 1.81 kHz: no warning.
    assert tooth_passing_warnings(modes, 600, 1) == []
    # 18 000 rpm with 6 inserts: 1.8 kHz sits on the y mode.
    w = tooth_passing_warnings(modes, [600, 18_000], 6)
    assert len(w) >= 1 and "y mode" in w[0] and "18000 rpm" in w[0]


def test_tooth_passing_warning_names_the_frequency_and_the_harmonic_apart():
    # 600 rpm x 20 teeth: tooth passing at 200 Hz, its 10th harmonic on a 2 kHz mode. The message
    # must not print 2000 Hz where it names the tooth-passing frequency.
    mode = SimpleNamespace(frequency_hz=2000.0, damping_ratio=0.02, axis="x")
    (w,) = tooth_passing_warnings([mode], 600, 20, margin=0.05)
    assert "tooth-passing frequency 200 Hz" in w
    assert "harmonic 10 = 2000 Hz" in w
    assert "x mode at 2000 Hz" in w
    assert "frequency (2000 Hz)" not in w
