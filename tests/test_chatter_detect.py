"""Chatter detection (analysis.chatter) on synthetic signals and on the regenerative twin."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.chatter import ChatterSettings, detect_chatter, indicators
from analysis.errors import AnalysisError
from tests.test_regen_twin import RATE, slot, zoa_slot

RPM = 3000.0


def _tooth_force(t: np.ndarray, rpm: float = RPM, amp: float = 200.0) -> np.ndarray:
    """A stable 2-flute cut: tooth-passing harmonics plus a runout line at the spindle speed."""
    w = 2 * math.pi * rpm / 60
    fx = amp * (0.5 + 0.4 * np.sin(2 * w * t) + 0.2 * np.sin(4 * w * t + 1)) + 8 * np.sin(w * t)
    fy = amp * (0.3 + 0.3 * np.cos(2 * w * t))
    return np.column_stack([fx, fy])


def _noise(n: int, sigma: float = 2.0, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, sigma, (n, 2))


def test_stable_periodic_cut_with_noise_and_hum_is_not_chatter() -> None:
    t = np.arange(int(2 * RATE)) / RATE
    f = _tooth_force(t) + _noise(t.size) + 0.5 * np.sin(2 * math.pi * 50 * t)[:, None]
    v = indicators(f, RATE, RPM)
    assert v.judged and not v.chatter
    assert v.energy_ratio < 0.01 and v.opr_ratio < 0.01


def test_a_growing_component_off_the_harmonics_is_chatter_at_its_frequency() -> None:
    t = np.arange(int(2 * RATE)) / RATE
    grow = 60 * np.minimum(np.exp(3 * (t - 1.0)), 1.5) * np.sin(2 * math.pi * 931.0 * t)
    f = _tooth_force(t) + _noise(t.size) + np.column_stack([grow, 0.5 * grow])
    v = indicators(f, RATE, RPM)
    assert v.chatter and v.frequency_hz == pytest.approx(931.0, abs=1.0)
    assert v.energy_ratio > 0.1 and v.opr_ratio > 0.1


def test_light_noisy_cut_entry_and_exit_are_not_chatter() -> None:
    t = np.arange(int(2 * RATE)) / RATE
    ramp = np.clip((t - 0.3) / 0.05, 0, 1) * np.clip((1.7 - t) / 0.05, 0, 1)
    f = _tooth_force(t, amp=20.0) * ramp[:, None] + _noise(t.size, 2.0)
    assert not indicators(f, RATE, RPM).chatter


def test_too_short_a_stretch_is_not_judged_and_bad_input_is_refused() -> None:
    t = np.arange(200) / RATE
    v = indicators(_tooth_force(t), RATE, RPM)
    assert not v.judged and not v.chatter and "cutting revolutions" in v.reason
    with pytest.raises(AnalysisError, match="spindle speed 0"):
        indicators(_tooth_force(t), RATE, 0.0)
    with pytest.raises(AnalysisError, match="energy_ratio"):
        ChatterSettings(energy_ratio=1.5)


@pytest.mark.parametrize("rpm", [6000.0, 10000.0, 15000.0])
def test_twin_runs_every_chattering_cut_flagged_no_stable_one(rpm: float) -> None:
    a = zoa_slot(rpm)[0]
    for scale, chatters in ((0.5, False), (0.8, False), (1.3, True), (1.8, True)):
        f, _ = slot(rpm, scale * a)
        f = f[:, :2] + _noise(len(f), 1.0)
        r = detect_chatter(f, RATE, rpm)
        assert r.chatter == chatters, (rpm, scale, r.whole)
        if chatters:  # near the mode, or one of its tooth-passing sidebands
            ft = rpm / 60 * 2
            folded = r.frequency_hz - round((r.frequency_hz - 922.0) / ft) * ft
            assert folded == pytest.approx(922.0, rel=0.12)


def test_per_block_verdicts_mark_the_chattering_block_only() -> None:
    rpm = 10000.0
    a = zoa_slot(rpm)[0]
    stable, _ = slot(rpm, 0.6 * a)
    chatter, _ = slot(rpm, 1.5 * a)
    f = np.vstack([stable[:, :2], chatter[:, :2]])
    blocks = np.repeat([7, 8], [len(stable), len(chatter)])
    r = detect_chatter(f, RATE, rpm, blocks=blocks)
    assert r.chatter and r.chattering_blocks() == [8]
    assert [b.block for b in r.blocks] == [7, 8] and all(b.judged for b in r.blocks)


def _three_flute(t: np.ndarray, rpm: float, amp: float = 200.0) -> np.ndarray:
    w = 2 * math.pi * rpm / 60
    fx = amp * (0.5 + 0.4 * np.sin(3 * w * t) + 0.2 * np.sin(6 * w * t + 1)) + 6 * np.sin(w * t)
    return np.column_stack([fx, amp * (0.3 + 0.3 * np.cos(3 * w * t))])


def test_a_line_near_a_tooth_harmonic_is_never_chatter_even_off_the_commanded_speed() -> None:
    """The issue's 'chatter at 297 Hz' (3 flutes, 6000 rpm: 300 Hz tooth passing): a cut whose
    level falls by a third over the stretch (a ramp spreads each harmonic by a few Hz), the
    spindle 0.2 % fast, plus a steady line 3 Hz from the tooth frequency: not chatter, and the
    spindle speed is read from the record."""
    t = np.arange(int(2 * RATE)) / RATE
    level = 1 - np.clip((t - 1.2) / 0.8, 0, 1) / 3
    f = _three_flute(t, 6012.0) * level[:, None] + _noise(t.size)
    f[:, 0] += 15 * np.sin(2 * math.pi * 297.0 * t)
    v = indicators(f, RATE, 6000.0)
    assert v.judged and not v.chatter, v
    assert v.spindle_rpm_measured == pytest.approx(6012.0, rel=2e-4)
    # The line is within the band (5 % of the 100.2 Hz spindle frequency): never reported.
    assert v.band_hz == pytest.approx(5.01, abs=0.01)
    assert abs(v.frequency_hz - 3 * 6012.0 / 60) > v.band_hz


def test_a_decaying_transient_off_the_harmonics_is_not_chatter_a_growing_one_is() -> None:
    """Energy alone would call both: a stable cut's entry transient at the mode (dying out in
    the first half) against the same component growing."""
    t = np.arange(int(2 * RATE)) / RATE
    mode = np.sin(2 * math.pi * 931.0 * t)
    decay = 300 * np.exp(-t / 0.5) * mode
    grow = 60 * np.minimum(np.exp(3 * (t - 1.0)), 1.5) * mode
    calm = indicators(_tooth_force(t) + _noise(t.size) + decay[:, None], RATE, RPM)
    loud = indicators(_tooth_force(t) + _noise(t.size) + grow[:, None], RATE, RPM)
    assert calm.energy_ratio > 0.1 and calm.growth < 0.8 and not calm.chatter
    assert loud.growth > 1 and loud.chatter
