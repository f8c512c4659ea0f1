"""The campaign's live chatter interlock (rig.campaign.chatter_watch.ChatterWatch).

References written apart from the detector: closed-form forces (a tooth-passing periodic force,
a sinusoid at a chosen distance from the spindle harmonics, a level that ramps down as a cutter
leaves the block) and the regenerative twin's own truth (bench/bench_chatter_detect.py: the true
cutting force's power off the tooth harmonics), on held-out cuts the former 10-revolution window
judged wrong. Each watch is fed 0.1 s reads, as the rig's DAQ delivers them.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rig.campaign.chatter_watch import CHATTER_WINDOW_REVS, ChatterWatch, level_change

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))

from bench_chatter_detect import RATE_HZ, Cut, simulate, truth  # noqa: E402
from bench_chatter_live import live_before  # noqa: E402

READ = int(0.1 * RATE_HZ)


def _first_alarm_s(force_n: np.ndarray, rpm: float, block: int = READ) -> float:
    """Run-clock s at the end of the read the watch stops on (inf: never)."""
    watch = ChatterWatch(("Fx", "Fy"), RATE_HZ, rpm, 10.0)
    for end in range(block, len(force_n) + 1, block):
        if watch.push(force_n[end - block : end]) is not None:
            return end / RATE_HZ
    return math.inf


def _milling_force(rpm: float, teeth: int, seconds: float, seed: int) -> np.ndarray:
    """A stable cut's (n, 2) N: a periodic force at the tooth frequency with harmonics (a chip
    that opens and closes once per tooth), 1 N noise."""
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    ph = 2 * math.pi * rpm / 60 * teeth * t
    fx = 200 + sum(120 / k * np.cos(k * ph + 0.3 * k) for k in range(1, 8))
    fy = 150 + sum(90 / k * np.sin(k * ph + 0.5 * k) for k in range(1, 8))
    rng = np.random.default_rng(seed)
    return np.column_stack([fx, fy]) + rng.normal(0.0, 1.0, (len(t), 2))


@pytest.mark.parametrize("offset", [0.15, 0.3, 0.5])
def test_a_component_off_the_spindle_harmonics_stops_the_cut_within_the_stated_latency(
    offset: float,
) -> None:
    """Chatter at 1 kHz-ish put ``offset`` x f_sp from a spindle harmonic (0.15 and 0.3: inside
    the former window's 0.375 f_sp bands), as much AC power as the periodic force, growing in
    over 50 ms: stopped within the window, plus one verdict and one read."""
    rpm, teeth = 6000.0, 3
    f_sp = rpm / 60
    f = _milling_force(rpm, teeth, 1.0, 1)
    t = np.arange(len(f)) / RATE_HZ
    f_c = (10 + offset) * f_sp
    amp = np.sqrt(2) * np.std(f[:, 0]) * np.minimum(t / 0.05, 1.0)
    f[:, 0] += amp * np.sin(2 * math.pi * f_c * t)
    f[:, 1] += amp * np.cos(2 * math.pi * f_c * t + 0.4)
    window_s = CHATTER_WINDOW_REVS / f_sp
    assert _first_alarm_s(f, rpm) <= window_s + 0.05 + 2 * 0.1 + 1e-9
    # the former window's bands, 0.375 f_sp, hid the nearest one (a Hann main lobe is 0.25 f_sp
    # wide each side there: a strong component further out leaks past the band)
    old = live_before(Cut(teeth, "slot", "A", rpm, 1.5, 1.0, 0), f)
    assert old.chatter == (offset > 0.2)


@pytest.mark.parametrize("block", [READ, 256, 4096])
def test_a_stable_cut_leaving_the_block_is_never_chatter(block: int) -> None:
    """A periodic force at full level for 0.5 s, then falling linearly to air over 0.4 s (the
    cutter leaving the block: 40 revolutions at 6000 rpm), then air; the force limit's level
    change spreads every harmonic, which the former window judged as chatter. Any DAQ block
    size."""
    rpm = 6000.0
    f = _milling_force(rpm, 4, 1.2, 2)
    t = np.arange(len(f)) / RATE_HZ
    level = np.clip(1 - (t - 0.5) / 0.4, 0, 1)[:, None]
    f = f * level + np.random.default_rng(3).normal(0, 1.0, f.shape) * (1 - level)
    assert _first_alarm_s(f, rpm, block) == math.inf


def test_level_change_of_a_ramp_and_a_steady_cut() -> None:
    spr = 100.0
    steady = np.ones((2000, 2))
    assert level_change(steady, spr) == pytest.approx(0.0)
    ramp = np.linspace(1.0, 0.5, 2000)[:, None] * np.ones((1, 2))
    # 20 revolutions: the last 6's mean over the first 6's differs by 0.35 of 0.75
    assert level_change(ramp, spr) == pytest.approx(0.35 / 0.75, rel=0.01)
    assert level_change(steady[:250], spr) == math.inf


# (teeth, immersion, holder, rpm, SD limit mm, depth factor, seed, speed error, truth): held-out
# cuts of the bench that the former 10-revolution interlock judged wrong.
HELD_OUT = [
    (3, "half-down", "B", 5100.0, 5.923296440612552, 1.2, 5130, 0.00026619204551787696, "chatter"),
    (3, "quarter-up", "B", 5100.0, 3.9492531955626293, 1.2, 5148, -0.0025921090025570795,
     "chatter"),
    (4, "half-up", "B", 7300.0, 2.2415557036570872, 1.2, 5208, 0.00022876960030593623, "chatter"),
    (2, "slot", "B", 14000.0, 3.19510927022534, 1.2, 5022, 0.0012396979982137795, "chatter"),
    (4, "slot", "A", 5100.0, 2.443794055859534, 0.5, 5174, 0.0004050971904104822, "stable"),
    (4, "slot", "A", 5100.0, 2.443794055859534, 0.8, 5175, 0.0012398156240230477, "stable"),
]  # fmt: skip


@pytest.mark.parametrize("case", HELD_OUT, ids=lambda c: f"{c[0]}T-{c[1]}-{c[3]:g}-x{c[5]}")
def test_held_out_twin_cuts_the_former_window_judged_wrong(case: tuple[Any, ...]) -> None:
    teeth, imm, holder, rpm, limit, factor, seed, err, expected = case
    cut = Cut(teeth, imm, holder, rpm, factor, limit, seed, err)
    f_true, f_meas, exit_s = simulate(cut)
    says, shares, _ = truth(f_true, rpm * (1 + err), teeth, exit_s)
    assert says == expected, shares  # the twin itself, before any detector
    assert live_before(cut, f_meas).chatter != (says == "chatter")  # the former window: wrong
    alarm_s = _first_alarm_s(f_meas, rpm)
    if says == "chatter":
        assert alarm_s <= exit_s  # while the cutter is still in the block
    else:
        assert alarm_s == math.inf


@pytest.mark.slow
def test_held_out_rates_meet_the_targets_live_as_the_whole_run() -> None:
    """The bench's held-out half (252 cuts at speeds the watch was not tuned on): the live
    watch stops no stable cut (none at a tooth harmonic) and misses at most 5 % of the chatter
    beyond 1.1 x the limit, as the whole-run verdict does."""
    from bench_chatter_live import cases, judge, rates

    judged = [judge(cut, says, f) for cut, says, f in cases("held", None)]
    for kind in ("whole", "now"):
        r = rates(judged, kind)
        assert r["stable"] >= 50 and r["beyond"] >= 50
        assert r["fp"] <= 0.01 * r["stable"] and r["fp_at_tooth"] == 0, (kind, r)
        assert r["missed_beyond"] <= 0.05 * r["beyond"], (kind, r)
