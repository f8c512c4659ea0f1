"""The adaptive controller (issue 29) against a fake GRBL override API and a synthetic plant
(force proportional to the feed override): byte choice, dead band, slew, air reset, and the
safety holds. The end-to-end cases on the simulated GRBL over a pty are in
tests/test_adaptive_twin.py."""

from __future__ import annotations

import threading
import time
from collections import deque
from types import SimpleNamespace

import numpy as np
import pytest

from rig.adaptive import AdaptiveController, AdaptiveSettings, nearest_pocket_rpm
from rig.adaptive.controller import _feed_codes, _spindle_codes

RATE, RPM = 10_000.0, 2000.0
SPR = 300  # samples per revolution at 2000 rpm, 10 kHz


class FakeGrbl:
    """GRBL 1.1's override arithmetic (protocol.c): each byte steps and clamps to 10..200 %."""

    def __init__(self) -> None:
        self.feed = self.spindle = 100
        self.bytes: list[int] = []
        self.held = 0
        self.last_status = None

    def override(self, code: int) -> None:
        self.bytes.append(code)
        step = {0x91: 10, 0x92: -10, 0x93: 1, 0x94: -1}
        sstep = {0x9A: 10, 0x9B: -10, 0x9C: 1, 0x9D: -1}
        if code == 0x90:
            self.feed = 100
        elif code in step:
            self.feed = min(200, max(10, self.feed + step[code]))
        elif code == 0x99:
            self.spindle = 100
        elif code in sstep:
            self.spindle = min(200, max(10, self.spindle + sstep[code]))

    @property
    def overrides(self):
        return (self.feed, 100, self.spindle)

    def feed_hold(self) -> None:
        self.held += 1


def _fewest(cur: int, target: int) -> int:
    """Breadth-first search over GRBL's feed bytes: the independent count."""
    seen, q = {cur: 0}, deque([cur])
    while q:
        p = q.popleft()
        if p == target:
            return seen[p]
        for nxt in (100, min(200, p + 10), max(10, p - 10), min(200, p + 1), max(10, p - 1)):
            if nxt not in seen:
                seen[nxt] = seen[p] + 1
                q.append(nxt)
    raise AssertionError


def test_override_bytes_reach_target_fewest_within_limits() -> None:
    rng = np.random.default_rng(1)
    for cur, target in [(100, 200), (195, 200), (15, 10), (200, 101), (100, 10)] + [
        tuple(rng.integers(10, 201, 2)) for _ in range(300)
    ]:
        g = FakeGrbl()
        g.feed = g.spindle = int(cur)
        codes = _feed_codes(int(cur), int(target))
        for c in codes:
            g.override(c)
        assert g.feed == target
        assert len(codes) == _fewest(int(cur), int(target))
        for c in _spindle_codes(int(cur), int(target)):
            g.override(c)
        assert g.spindle == target


def _rev(force_n: float, rng: np.random.Generator, noise_n: float = 2.0) -> np.ndarray:
    """One revolution of (Fx, Fy, Fz) whose mean |Fxy| is force_n (two teeth' ripple)."""
    a = np.arange(SPR) * 2 * np.pi / SPR
    mag = force_n * (1 + 0.2 * np.cos(2 * a))
    f = np.stack([mag * np.cos(a), mag * np.sin(a), 0.3 * mag], axis=1)
    return f + rng.normal(0, noise_n, f.shape)


def _controller(**kw):
    s = AdaptiveSettings(**{"target_force_n": 500.0, "max_force_n": 2000.0, **kw})
    t = [0.0]
    ctl = AdaptiveController(s, spindle_rpm=RPM, channels=("Fx", "Fy", "Fz"),
                             clock=lambda: t[0])  # fmt: skip
    ctl.on_start(SimpleNamespace(rate_hz=RATE, block_samples=SPR), 0.0)
    g = FakeGrbl()
    ctl.attach(g)
    return ctl, g, t


def _run(ctl, g, t, k_n_per_pct, revs, rng):
    """The plant: a revolution's force = k * feed override %; one block per revolution."""
    forces = []
    for _ in range(revs):
        k = k_n_per_pct(len(forces))
        f = k * g.feed
        forces.append(f)
        t[0] += SPR / RATE
        ctl.push_forces(t[0], _rev(f, rng))
    return np.array(forces)


def test_holds_target_through_a_step_dead_band_and_slew() -> None:
    rng = np.random.default_rng(2)
    ctl, g, t = _controller()
    # 700 N at 100 % for 60 revolutions, then a light step (300 N at 100 %)
    forces = _run(ctl, g, t, lambda i: 7.0 if i < 60 else 3.0, 160, rng)
    # settles within the dead band in a few revolutions after each change
    assert abs(forces[20:60].mean() / 500 - 1) < 0.05
    assert abs(forces[120:160].mean() / 500 - 1) < 0.05
    # up by at most 10 % per revolution: the commanded feed per revolution
    feeds = np.array([r.feed_pct for r in ctl.trace])
    assert np.diff(feeds).max() <= 10
    assert feeds.min() >= 10 and feeds.max() <= 200
    # the same figure the fake GRBL reached
    assert g.feed == ctl.feed_pct
    # inside the dead band nothing is sent: the last 30 revolutions send no byte
    n_before = len(g.bytes)
    _run(ctl, g, t, lambda i: 3.0, 30, rng)
    assert len(g.bytes) == n_before
    assert g.held == 0


class _Notes:
    """A run writer that keeps the controller's events (kind, text, time)."""

    def __init__(self) -> None:
        self.events: list[tuple[str, str, float]] = []

    def event(self, kind: str, message: str = "", *, time_s: float | None = None) -> None:
        self.events.append((kind, message, time_s))


def test_saturation_is_reported_and_timed() -> None:
    """A step whose load is the edge's (force independent of the feed, as seed 001's 0.1 mm
    step on the twin: 74 N at 17 % and at 200 %) cannot reach the target at any override: the
    controller sits at 200 %, says so once, and counts the revolutions and time at the limit;
    a reachable step after it ends the span."""
    rng = np.random.default_rng(7)
    ctl, g, t = _controller(slew_up_pct=50)
    ctl.writer = _Notes()
    # 40 revolutions of 150 N whatever the feed, then 40 of 7 N per % (reachable at ~71 %)
    forces = []
    for i in range(80):
        f = 150.0 if i < 40 else 7.0 * g.feed
        forces.append(f)
        t[0] += SPR / RATE
        ctl.push_forces(t[0], _rev(f, rng))
    ctl.close()
    sat = [r.saturated for r in ctl.trace]
    # 100 -> 150 % after the 1st revolution; GRBL runs it 50 ms (1.7 revolutions) later
    # (grbl_codes.APPLY_DELAY_S), so the 2nd and 3rd are not judged; 200 % after the 4th, run
    # from within the 5th: from the 7th revolution on, every one of the edge step is cut at
    # 200 % and saturated (the 5th and 6th began at 150 %)
    assert not any(sat[:6]) and all(sat[6:40]) and not any(sat[40:])
    (span,) = ctl.saturated_spans
    assert span[2] == 34
    assert span[1] - span[0] == pytest.approx(34 * 60 / RPM, abs=1e-9)
    m = ctl.summary()
    assert m["saturated_revolutions"] == 34
    assert m["saturated_s"] == pytest.approx(34 * 60 / RPM)
    notes = [x for _, x, _ in ctl.writer.events]
    assert sum("saturated: feed at the 200 % limit" in x for x in notes) == 1
    assert sum("saturation ended: 34 revolutions at the limit" in x for x in notes) == 1
    # a target out of reach below: 10 % cannot bring 800 N to 500 N when the load is the edge's
    ctl2, g2, t2 = _controller(slew_down_pct=90)
    _run(ctl2, g2, t2, lambda i: 800.0 / g2.feed, 25, rng)  # 100 -> 10 % in two changes
    assert g2.feed == 10 and ctl2.trace[-1].saturated
    ctl2.close()
    assert ctl2.summary()["saturated_revolutions"] >= 10


def test_air_resets_overrides_to_100() -> None:
    rng = np.random.default_rng(3)
    ctl, g, t = _controller()
    _run(ctl, g, t, lambda i: 2.0, 40, rng)  # 200 N at 100 %: feed goes up
    assert g.feed > 150
    _run(ctl, g, t, lambda i: 0.0, 3, rng)  # the cut ends
    assert g.feed == 100 and ctl.feed_pct == 100
    assert g.bytes[-1] == 0x90 or g.feed == 100


def test_over_force_holds_within_the_block() -> None:
    rng = np.random.default_rng(4)
    ctl, g, t = _controller(max_force_n=1500.0)
    _run(ctl, g, t, lambda i: 5.0, 10, rng)
    assert g.held == 0
    # a block of half a revolution crossing the limit: held in that very block
    f = _rev(1700.0, rng)[: SPR // 2]
    t[0] += 0.015
    ctl.push_forces(t[0], f)
    assert g.held == 1 and ctl.state == "hold"
    assert "above max_force_n" in ctl.hold_reason
    # nothing more is sent after a hold
    n = len(g.bytes)
    _run(ctl, g, t, lambda i: 2.0, 10, rng)
    assert len(g.bytes) == n and g.held == 1


def test_signal_loss_resets_and_holds() -> None:
    rng = np.random.default_rng(5)
    ctl, g, t = _controller(stall_revs=3.0)
    ctl.arm()
    try:
        _run(ctl, g, t, lambda i: 2.0, 30, rng)  # feed raised above 100 %
        assert g.feed > 100 and g.held == 0
        # the clock runs on, no block comes: held once the run clock passes one read (1 rev)
        # plus 3 revolutions (0.12 s at 2000 rpm)
        t[0] += 0.1
        time.sleep(0.05)
        assert g.held == 0
        t[0] += 0.05
        deadline = time.monotonic() + 5.0
        while g.held == 0 and time.monotonic() < deadline:
            time.sleep(0.005)
        assert g.held == 1
        assert "signal lost" in ctl.hold_reason
        assert g.feed == 100  # overrides reset after the hold
    finally:
        ctl.close()


def _lobes() -> SimpleNamespace:
    """Pockets from 1600 to 1800, 2600 to 2800 ... rpm, 25 rpm apart: triangular, 5 mm at
    their peaks (1700, 2700 ...) and 3 mm at their edges; 0.5 mm elsewhere."""
    rpm = np.arange(1000, 5001, 25.0)
    r = rpm % 1000
    pocket = (r >= 600) & (r <= 800)
    return SimpleNamespace(spindle_rpm=rpm, depth_limit_mm=np.where(
        pocket, 5.0 - 2.0 * np.abs(r - 700) / 100, 0.5))  # fmt: skip


def test_nearest_pocket() -> None:
    lobes = _lobes()
    # the pocket's peak, not its edge nearest 2000 rpm (1800)
    assert nearest_pocket_rpm(lobes, 2000, 1.0) == 1700
    assert nearest_pocket_rpm(lobes, 2000, 1.0, min_pct=90, max_pct=200) == 2700
    assert nearest_pocket_rpm(lobes, 2000, 1.0, min_pct=95, max_pct=105) is None
    assert nearest_pocket_rpm(lobes, 2000, 5.0) is None  # no pocket deep enough
    # a plateau (stable at any depth): its middle
    flat = SimpleNamespace(spindle_rpm=np.arange(1000, 3001, 100.0),
                           depth_limit_mm=np.r_[np.full(10, 0.5), np.full(11, np.inf)])  # fmt: skip
    assert nearest_pocket_rpm(flat, 1500, 1.0) == 2500


def test_settings_refuse_nonsense() -> None:
    with pytest.raises(ValueError, match="mode"):
        AdaptiveSettings(mode="torque")
    with pytest.raises(ValueError, match="target"):
        AdaptiveSettings(target_force_n=3000, max_force_n=2000)


def test_threads_left() -> None:
    # the watchdog thread ends with close()
    ctl, g, t = _controller()
    ctl.arm()
    ctl.close()
    assert not any(th.name == "adaptive-watch" and th.is_alive() for th in threading.enumerate())


def _chatter_block(t0: float, n: int, rpm: float, amp_n: float, rng) -> np.ndarray:
    """n samples from t0 of a two-tooth rotating 200 N force at ``rpm`` plus ``amp_n`` at
    750 Hz (between the 22nd and 23rd harmonic of 2000 rpm: off the tooth harmonics)."""
    t = t0 + np.arange(n) / RATE
    a = 2 * np.pi * rpm / 60 * t
    mag = 200 * (1 + 0.3 * np.cos(2 * a))
    ch = amp_n * np.sin(2 * np.pi * 750 * t)
    f = np.stack([mag * np.cos(a) + ch, mag * np.sin(a) + 0.7 * ch, 0.3 * mag], axis=1)
    return f + rng.normal(0, 2.0, f.shape)


def _chatter_run(ctl, g, t, revs: int, rng, stable_after_change: bool = True) -> None:
    for _ in range(revs):
        rpm = RPM * g.spindle / 100
        # chatter at the commanded speed; gone once the spindle left it (the pocket is stable)
        amp = 0.0 if (g.spindle != 100 and stable_after_change) else 200.0
        ctl.push_forces(t[0] + (SPR - 1) / RATE, _chatter_block(t[0], SPR, rpm, amp, rng))
        t[0] += SPR / RATE


def test_chatter_moves_the_spindle_to_the_nearest_pocket() -> None:
    rng = np.random.default_rng(6)
    ctl, g, t = _controller(mode="spindle", target_force_n=150.0)
    ctl.lobes, ctl.depth_mm = _lobes(), 1.0
    # the live watch (analysis.chatter.live): a verdict when its 20 revolutions are full and then
    # every 0.1 s of samples (1000 here, 3.3 revolutions of 300)
    _chatter_run(ctl, g, t, 23, rng)
    assert g.spindle == 100  # one chattering verdict (at the 20th revolution) is not acted on
    _chatter_run(ctl, g, t, 1, rng)  # ... the next, 0.1 s of samples later, confirms
    assert g.spindle == 85 and g.held == 0  # 1700 rpm, the nearest pocket's peak
    assert g.feed == 100  # spindle mode leaves the feed alone
    # the new window starts once GRBL turns at the new speed (grbl_codes.APPLY_DELAY_S, 1.7
    # revolutions), then 20 revolutions and a verdict
    _chatter_run(ctl, g, t, 28, rng)
    assert ctl.chatter_cleared_s is not None and g.held == 0


@pytest.mark.faults
def test_chatter_without_a_pocket_holds() -> None:
    rng = np.random.default_rng(7)
    for mode in ("feed", "spindle"):  # feed: no spindle to move; spindle: no lobes
        ctl, g, t = _controller(mode=mode, target_force_n=150.0)
        _chatter_run(ctl, g, t, 24, rng)
        assert g.held == 1 and "chatter" in ctl.hold_reason


@pytest.mark.faults
def test_cli_refuses_adaptive_without_grbl_or_table(tmp_path, capsys) -> None:
    """`campaign run --adaptive`: one line naming the file, exit 2, before anything runs."""
    from pathlib import Path

    from rig.cli import main

    root = Path(__file__).resolve().parent.parent / "configs" / "campaigns"
    assert main(["campaign", "run", str(root / "afc-step-depth.toml"), "--adaptive", "feed",
                 "--out", str(tmp_path)]) == 2  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cutlab: error: ")
    assert "afc-step-depth.toml" in err[0] and "[adaptive]" in err[0]
    # an [adaptive] table on a Fanuc drip feed: refused naming the controller
    text = (root / "adaptive-step.toml").read_text().replace('protocol = "grbl"\n', "")
    text = text.replace('machine = "lab-grbl"', 'machine = "ace-h63"')
    p = tmp_path / "fanuc.toml"
    p.write_text(text)
    assert main(["campaign", "run", str(p), "--adaptive", "feed", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fanuc controller of machine 'ace-h63' has no override path" in err[0]
    assert not (tmp_path / "adaptive-step").exists()


def test_dnc_send_loop_zeroes_judges_and_sends(tmp_path) -> None:
    """`dnc send --adaptive`'s loop on a simulated GRBL over a pty, with a simulated DAQ in
    place of the NI device (its synthetic signal, not the cut's): zeroed before the send, every
    revolution judged, its bytes through the streamer, the DAQ stopped at the end."""
    from analysis.config import load_rig
    from rig.adaptive.send import SendLoop
    from rig.dnc import prepare_send
    from rig.sim import SimClock, SimDaq, SimGrbl

    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG1 X5 F600\nM30\n")  # 0.5 s of feed
    ctl = SimGrbl(clock=SimClock(1.0))
    port = ctl.start()
    try:
        job = prepare_send(str(prog), "grbl", port=port, progress=False, guard=False)
        daq = SimDaq.from_rig(load_rig(), rate_hz=10_000.0, seconds=30.0, speed=1.0)
        # the watchdog counts wall time here (the DAQ's arrivals): 30 revolutions (0.9 s) beyond
        # the DAQ's 0.1 s reads, so a busy host's scheduling is not a lost signal
        settings = AdaptiveSettings(target_force_n=100.0, max_force_n=500.0, stall_revs=30.0)
        with SendLoop(job, settings, 2000.0, daq=daq) as loop:
            job.send()  # a fault would raise StreamFault
        m = loop.summary
        assert m["revolutions"] >= 10 and m["hold"] is None, m
        # every byte the loop decided went through the streamer (its own record)
        assert [c for _, c in job.streamer.override_log] == [c for _, c in loop.ctl.bytes_sent]
        assert daq.wait(5.0)  # stopped by the loop's exit
    finally:
        ctl.stop()


def test_twin_stock_split_by_an_override_cuts_no_false_dip() -> None:
    """A GRBL override splits the running line where the tool is (the timeline ends the first
    part there): the Z-map stock must not be cut to the tool's whole envelope at the split, or
    the teeth meet stock already gone in front of them (a false dip after every override). The
    revolution after a split at the same feed cuts what the unsplit line does."""
    from analysis.config import EndMill, get_material, load_rig
    from planning.stock import SteppedBlock
    from rig.sim import ExecutedSegment
    from rig.sim.machine import SignalSettings, SimMachine, ZMapStock

    ball = EndMill(kind="ball", diameter_mm=30, corner_radius_mm=15, flute_length_mm=30,
                   flutes=2, helix_deg=0)  # fmt: skip
    rpm, feed, depth = 2000.0, 1000.0, 0.4
    quiet = SignalSettings(noise_n=0.0, drift_n_s=0.0, hum_n=0.0, modes=False)
    rev_s = 60.0 / rpm
    t_split = 30.0 / (feed / 60.0)  # 30 mm into the line

    def rev_mean(split: bool) -> float:
        stock = ZMapStock(SteppedBlock(-30, 30, (0.0, 100.0), (0.0,)).to_zmap(ball), ball)
        m = SimMachine(ball, get_material("gm241"), load_rig().dynamometer, stock,
                       10_000.0, quiet)  # fmt: skip
        a, b = (-20.0, 0.0, -depth), (120.0, 0.0, -depth)
        m.on_segment(ExecutedSegment(0.0, 140.0 / (feed / 60.0), a, b, rpm, 0, feed_mm_min=feed))
        t = np.arange(0.0, t_split - 0.01, 0.01)
        for t0 in t:  # the run's reads up to the split
            m.cutting_force(t0 + np.arange(100) / 10_000.0)
        if split:  # as SimGrbl._replan: the same line goes on from the tool's place, here
            # three times at once (three override bytes taken together: two parts of no length)
            x = a[0] + (feed / 60.0) * t_split
            for _ in range(3):
                m.on_segment(ExecutedSegment(t_split, 140.0 / (feed / 60.0), (x, 0.0, -depth), b,
                                             rpm, 0, feed_mm_min=feed))  # fmt: skip
        tt = t[-1] + 0.01 + np.arange(int(round(2 * rev_s * 10_000))) / 10_000.0
        f = m.cutting_force(tt)
        late = tt >= t_split + 1e-3
        return float(np.linalg.norm(f[late][: int(rev_s * 10_000)], axis=1).mean())

    whole, split = rev_mean(False), rev_mean(True)
    assert whole > 50.0
    assert split == pytest.approx(whole, rel=0.01)
