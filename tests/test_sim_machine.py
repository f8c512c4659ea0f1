"""The simulated machine's kinematics, engagement geometry and signal chain against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.config import Dynamometer, DynoChannel, EndMill, FaceMill, Mode
from planning.nc import ARC_CCW
from planning.stock import SteppedBlock
from rig.daq import Calibration
from rig.sim import (
    DynoChain,
    ExecutedSegment,
    MotionTimeline,
    endmill_engagement,
    facemill_engagement,
)
from rig.sim.machine import BlockStock

FACEMILL = FaceMill(
    kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15, axial_rake_deg=7,
    radial_rake_deg=0, nose_radius_mm=0.4,
)  # fmt: skip
FLAT = EndMill(kind="flat", diameter_mm=10, flute_length_mm=22, flutes=3, helix_deg=30)
BALL = EndMill(kind="ball", diameter_mm=30, corner_radius_mm=15, flute_length_mm=30, flutes=2,
               helix_deg=0)  # fmt: skip


def _line(x0, x1, y, z, feed_mm_min, rpm, t0=0.0, block=0, dx=(1.0, 0.0)):
    d = math.hypot(x1 - x0, 0.0) if dx == (1.0, 0.0) else abs(x1 - x0)
    dur = d / (feed_mm_min / 60.0)
    if dx == (1.0, 0.0):
        a, b = (x0, y, z), (x1, y, z)
    else:  # along +Y: x0, x1 are Y values, y is the X position
        a, b = (y, x0, z), (y, x1, z)
    return ExecutedSegment(t0, t0 + dur, a, b, rpm, block, feed_mm_min=feed_mm_min)


def _one_rev_times(t_mid: float, rpm: float, n: int = 20000) -> np.ndarray:
    return t_mid + np.arange(n) / n * 60.0 / rpm


@pytest.mark.parametrize("width", [30.0, 50.0, 80.0])
@pytest.mark.parametrize("along_y", [False, True])
def test_facemill_symmetric_pass_engaged_arc(width: float, along_y: bool) -> None:
    # A 125 mm cutter centred on a block of width W engages 2 asin(W / 2R) per revolution.
    rpm, fz, depth = 600.0, 0.236, 1.5
    feed = fz * rpm
    tl = MotionTimeline()
    dx = (0.0, 1.0) if along_y else (1.0, 0.0)
    tl.add(_line(-70, 100, 0.0, -depth, feed, rpm, dx=dx))
    blk = SteppedBlock(-width / 2, width / 2, (0.0, 80.0), (0.0,))
    if along_y:  # rotate the block with the path

        class _Rot:
            def top_z(self, x, y):
                return blk.top_z(y, -np.asarray(x))

        stock = _Rot()
    else:
        stock = BlockStock(blk)
    # Cutter centre at -20 mm: the whole engaged arc lies inside the block along the feed.
    t_mid = 50.0 / (feed / 60.0)
    eng = facemill_engagement(tl.state(_one_rev_times(t_mid, rpm)), FACEMILL, stock)
    frac = eng.engaged.mean()
    assert frac == pytest.approx(2 * math.asin(width / 125.0) / (2 * math.pi), abs=2e-4)
    assert np.allclose(eng.depth_mm[eng.engaged], depth)
    assert np.allclose(eng.fz_mm, fz)
    th = eng.theta_rad[eng.engaged]
    # Symmetric immersion about the feed direction.
    assert th.mean() == pytest.approx(math.pi / 2, abs=2e-3)


def test_facemill_out_of_block_and_spindle_off_do_not_cut() -> None:
    tl = MotionTimeline()
    tl.add(_line(-200, -100, 0.0, -1.0, 141.6, 600.0))
    tl.add(_line(-100, 20, 0.0, -1.0, 141.6, 0.0, t0=tl.segments[-1].t_end_s))
    stock = BlockStock(SteppedBlock(-25, 25, (0.0, 40.0), (0.0,)))
    t = np.linspace(0, tl.segments[-1].t_end_s, 5000)
    eng = facemill_engagement(tl.state(t), FACEMILL, stock)
    assert not eng.engaged.any()


@pytest.mark.parametrize("width", [1.0, 2.5, 5.0, 8.0, 10.0])
def test_endmill_radial_immersion_matches_closed_form(width: float) -> None:
    # Down-milling a width w with radius R: each tooth is engaged acos(1 - w/R) per revolution,
    # exiting at theta = pi; a full slot (w = D) engages half a revolution.
    rpm, fz = 3000.0, 0.05
    feed = fz * FLAT.flutes * rpm
    r = FLAT.radius_mm
    half = 20.0
    y_path = half + r - width if width < FLAT.diameter_mm else 0.0
    tl = MotionTimeline()
    tl.add(_line(-20, 80, y_path, -2.0, feed, rpm))
    stock = BlockStock(SteppedBlock(-half, half, (0.0, 60.0), (0.0,)))
    t_mid = 50.0 / (feed / 60.0)
    eng = endmill_engagement(tl.state(_one_rev_times(t_mid, rpm, 30000)), FLAT, stock, 2.0, 4)
    frac = eng.engaged.mean()
    expect = math.acos(1 - min(width, FLAT.diameter_mm) / r) / (2 * math.pi)
    if width >= FLAT.diameter_mm:
        expect = 0.5
    assert frac == pytest.approx(expect, abs=1e-3)
    th = eng.theta_rad[eng.engaged]
    assert th.max() == pytest.approx(math.pi, abs=2e-3)
    # Chip thickness follows h = fz sin(theta).
    assert np.allclose(eng.h_mm[eng.engaged], fz * np.sin(th))


def test_ball_endmill_slices_above_depth_do_not_cut() -> None:
    rpm, feed, depth = 2000.0, 1000.0, 0.7
    tl = MotionTimeline()
    tl.add(_line(-20, 80, 0.0, -depth, feed, rpm))
    stock = BlockStock(SteppedBlock(-25, 25, (0.0, 60.0), (0.0,)))
    t_mid = 40.0 / (feed / 60.0)
    eng = endmill_engagement(tl.state(_one_rev_times(t_mid, rpm)), BALL, stock, 1.4, 14)
    cuts = eng.engaged.any(axis=(0, 1))
    assert np.array_equal(cuts, eng.z_mm < depth)
    # On the ball the edge normal tilts: kappa = acos((R - z)/R).
    assert np.allclose(eng.kappa_rad, np.arccos((15 - eng.z_mm) / 15))


def test_timeline_positions_blocks_and_arc() -> None:
    tl = MotionTimeline()
    tl.add(ExecutedSegment(0.0, 1.0, (0, 0, 0), (10, 0, 0), 600.0, 3))
    # Quarter circle CCW about (10, 10) from (10, 0) to (20, 10).
    tl.add(ExecutedSegment(1.0, 2.0, (10, 0, 0), (20, 10, 0), 600.0, 4, ARC_CCW, (10, 10, 0)))
    s = tl.state(np.array([-0.5, 0.5, 1.5, 2.5]))
    assert s.block.tolist() == [-1, 3, 4, 4]
    assert np.allclose(s.position_mm[1], (5, 0, 0))
    p = s.position_mm[2]
    assert math.hypot(p[0] - 10, p[1] - 10) == pytest.approx(10)
    assert np.allclose(s.position_mm[3], (20, 10, 0))
    assert np.allclose(s.velocity_mm_s[3], 0)
    assert np.allclose(s.velocity_mm_s[1], (10, 0, 0))


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(0.01, 2.0), min_size=1, max_size=6), st.floats(100, 3000))
def test_spindle_angle_is_continuous_and_turns_clockwise(durs: list[float], rpm: float) -> None:
    tl = MotionTimeline()
    t = 0.0
    for k, d in enumerate(durs):
        tl.add(ExecutedSegment(t, t + d, (0, 0, 0), (1, 0, 0), rpm * (1 + 0.1 * k), k))
        t += d
    tt = np.linspace(0, t, 4000)
    a = tl.state(tt).spindle_angle_rad
    assert np.all(np.diff(a) < 0)  # M3: clockwise from +Z
    step = np.abs(np.diff(a)).max()
    assert step <= 2 * np.pi * rpm * (1 + 0.1 * len(durs)) / 60 * (tt[1] - tt[0]) * 1.0001


def _dyno(modes=()) -> Dynamometer:
    return Dynamometer(
        model="test",
        channels=(
            DynoChannel(name="Fx", axis="x", sensitivity_pc_n=-7.9, range_n_v=500),
            DynoChannel(name="Fy", axis="y", sensitivity_pc_n=-7.9, range_n_v=500, sign=-1),
            DynoChannel(name="Fz", axis="z", sensitivity_pc_n=-3.7, range_n_v=250),
        ),
        crosstalk=((1.0, 0.01, 0.02), (-0.01, 1.0, 0.01), (0.015, -0.01, 1.0)),
        modes=modes,
    )


def test_chain_round_trips_through_the_daq_calibration() -> None:
    dyno = _dyno()
    chain = DynoChain(dyno, 10_000.0, modes=False)
    rng = np.random.default_rng(1)
    f = rng.normal(0, 300, (1000, 3))
    v = chain.volts(f, 0.0)
    back = Calibration.from_dynamometer(dyno).force_from_volts(v.T)
    assert np.allclose(back, f, rtol=0, atol=1e-9)


def test_mode_has_unit_dc_gain_and_resonant_peak() -> None:
    fn, zeta, rate = 2050.0, 0.02742, 50_000.0  # the filter starts at rest
    dyno = _dyno((Mode(axis="x", frequency_hz=fn, damping_ratio=zeta),))
    chain = DynoChain(dyno, rate)
    n = 50_000
    t = np.arange(n) / rate
    f = np.zeros((n, 3))
    f[:, 0] = 100.0
    out = chain.filtered(f, 0.0)
    assert out[-1000:, 0] == pytest.approx(100.0, rel=1e-6)
    chain2 = DynoChain(dyno, rate)
    f[:, 0] = np.sin(2 * np.pi * fn * t)
    amp = np.abs(chain2.filtered(f, 0.0)[n // 2 :, 0]).max()
    assert amp == pytest.approx(1 / (2 * zeta), rel=0.03)


def test_chain_state_continues_across_reads() -> None:
    dyno = _dyno((Mode(axis="y", frequency_hz=1810, damping_ratio=0.0872),))
    rng = np.random.default_rng(2)
    f = rng.normal(0, 10, (3000, 3))
    whole = DynoChain(dyno, 20_000.0).filtered(f, 0.0)
    c = DynoChain(dyno, 20_000.0)
    parts = [c.filtered(f[i : i + 700], i / 20_000.0) for i in range(0, 3000, 700)]
    assert np.allclose(np.vstack(parts), whole)


def test_noise_drift_and_hum_are_as_configured() -> None:
    dyno = _dyno()
    rate = 10_000.0
    chain = DynoChain(dyno, rate, noise_n=2.0, drift_n_s=0.5, hum_n=0.0, seed=3, modes=False)
    n = 200_000
    v = chain.volts(np.zeros((n, 3)), 0.0)
    f = Calibration.from_dynamometer(dyno).force_from_volts(v.T)  # inverse includes cross-talk
    t = np.arange(n) / rate
    slope = np.polyfit(t, f[:, 0], 1)[0]
    assert slope == pytest.approx(0.5, rel=0.05)
    resid = f[:, 0] - np.polyval(np.polyfit(t, f[:, 0], 1), t)
    assert resid.std() == pytest.approx(2.0, rel=0.05)


def _facemill_machine(width: float, depth: float, rate_hz: float = 20_000.0):
    from analysis.config import get_material
    from rig.sim.machine import SignalSettings, SimMachine

    quiet = SignalSettings(noise_n=0.0, drift_n_s=0.0, hum_n=0.0, modes=False)
    stock = BlockStock(SteppedBlock(-width / 2, width / 2, (0.0, 80.0), (0.0,)))
    return SimMachine(FACEMILL, get_material("al6061-t6"), _dyno(), stock, rate_hz, quiet)


@pytest.mark.parametrize("depth", [0.5, 2.0, 3.0])
def test_facemill_pass_force_equals_the_model_over_a_revolution(depth: float) -> None:
    # The machine decides engagement from geometry; the model from the width. In steady cutting
    # both give the same force at every angle (feed along +X, dynamometer = machine axes).
    from analysis.config import get_material
    from analysis.forces import facemill

    rpm, fz, width = 600.0, 0.236, 50.0
    m = _facemill_machine(width, depth)
    feed = fz * rpm
    m.on_segment(_line(-70, 100, 0.0, -depth, feed, rpm))
    t = _one_rev_times(50.0 / (feed / 60.0), rpm, 4000)
    f_machine = m.cutting_force(t)
    theta = -m.timeline.state(t).spindle_angle_rad + math.pi / 2  # insert angle from +Y, clockwise
    cut = facemill.FaceMillCut(fz_mm=fz, depth_mm=depth, width_mm=width)
    f_model = facemill.facemill_forces(theta, FACEMILL, get_material("al6061-t6").facemill, cut)
    assert np.allclose(f_machine.mean(axis=0), f_model.mean(axis=0), rtol=2e-3, atol=0.5)
    assert np.abs(f_machine - f_model).max() < 0.02 * np.abs(f_model).max() + 1.0


def test_feed_hold_leaves_only_ploughing() -> None:
    # With the feed stopped and the spindle turning, chip thickness is zero: what remains on the
    # dynamometer is the ploughing P * l of the engaged edge, and it does not depend on the feed.
    rpm, fz, depth = 600.0, 0.236, 2.0
    m = _facemill_machine(50.0, depth)
    feed = fz * rpm
    seg = _line(-70, -20, 0.0, -depth, feed, rpm)
    m.on_segment(seg)
    m.on_segment(ExecutedSegment(seg.t_end_s, seg.t_end_s + 5.0, seg.end_mm, seg.end_mm, rpm, 1))
    t_hold = _one_rev_times(seg.t_end_s + 1.0, rpm, 4000)
    t_cut = _one_rev_times(seg.t_end_s - 2.0, rpm, 4000)
    hold = np.linalg.norm(m.cutting_force(t_hold), axis=1).mean()
    cut = np.linalg.norm(m.cutting_force(t_cut), axis=1).mean()
    assert 0 < hold < 0.6 * cut


@pytest.mark.parametrize(("tool", "depth", "width"), [(FLAT, 3.0, 10.0), (FLAT, 2.0, 4.0),
                                                      (BALL, 0.7, 30.0)])  # fmt: skip
def test_endmill_mean_force_equals_the_model(tool: EndMill, depth: float, width: float) -> None:
    # The machine's slices and engagement vs analysis.forces.endmill's own discs and immersion: the
    # per-revolution mean force agrees (both integrate the same edge-force model).
    from analysis.config import get_material
    from analysis.forces import endmill
    from rig.sim.machine import SignalSettings, SimMachine

    mat = get_material("al6061-t6")
    rpm, fz = 2000.0, 0.08
    feed = fz * tool.flutes * rpm
    half = 40.0
    r = tool.radius_mm
    y_path = 0.0 if width >= tool.diameter_mm else half + r - width
    stock = BlockStock(SteppedBlock(-half, half, (0.0, 120.0), (0.0,)))
    quiet = SignalSettings(noise_n=0.0, drift_n_s=0.0, hum_n=0.0, modes=False)
    m = SimMachine(tool, mat, _dyno(), stock, 20_000.0, quiet, n_slices=48)
    m.on_segment(_line(-30, 150, y_path, -depth, feed, rpm))
    t = _one_rev_times(70.0 / (feed / 60.0), rpm, 6000)
    f_machine = m.cutting_force(t).mean(axis=0)
    mode = "slot" if width >= tool.diameter_mm else "down"
    cut = endmill.EndMillCut.from_width(tool, fz, depth, width, mode)
    phi = np.linspace(0, 2 * np.pi, 6000, endpoint=False)
    f_model = endmill.endmill_forces(phi, tool, mat.endmill, cut, n_discs=48).mean(axis=0)
    assert np.allclose(f_machine, f_model, rtol=0.02, atol=0.02 * np.abs(f_model).max())


def test_zmap_stock_remembers_earlier_passes() -> None:
    # Two identical slots along the same line: the second finds the groove empty; a third pass
    # half a diameter aside cuts again, less than a full slot.
    from analysis.config import get_material
    from rig.sim.machine import SignalSettings, SimMachine, ZMapStock

    block = SteppedBlock(-20, 20, (0.0, 40.0), (0.0,))
    stock = ZMapStock(block.to_zmap(FLAT), FLAT)
    quiet = SignalSettings(noise_n=0.0, drift_n_s=0.0, hum_n=0.0, modes=False)
    m = SimMachine(FLAT, get_material("al6061-t6"), _dyno(), stock, 20_000.0, quiet)
    rpm, feed, depth = 3000.0, 450.0, 2.0
    t = 0.0
    means = []
    for y in (0.0, 0.0, 5.0):
        seg = _line(-10, 50, y, -depth, feed, rpm, t0=t)
        m.on_segment(seg)
        tt = _one_rev_times(t + 30.0 / (feed / 60.0), rpm, 4000)
        means.append(float(np.linalg.norm(m.cutting_force(tt), axis=1).mean()))
        t = seg.t_end_s
        m.cutting_force(np.array([t + 1e-6]))  # the clock passes the end: the pass is cut
    full, again, aside = means
    assert full > 50.0
    assert again < 0.02 * full
    assert 0.1 * full < aside < 0.9 * full
    # The first pass removed a 10 mm wide, 2 mm deep slot through the 40 mm block; the second
    # nothing.
    assert stock.removed_mm3[0] == pytest.approx(10.0 * 2.0 * 40.0, rel=0.01)
    assert stock.removed_mm3[1] == pytest.approx(0.0, abs=1.0)


def _slot_machine(tool: EndMill, mat, rpm: float, fz: float, depth: float, **kw):
    from rig.sim.machine import SignalSettings, SimMachine

    feed = fz * tool.flutes * rpm
    stock = BlockStock(SteppedBlock(-40, 40, (0.0, 400.0), (0.0,)))
    quiet = SignalSettings(noise_n=0.0, drift_n_s=0.0, hum_n=0.0, modes=False)
    m = SimMachine(tool, mat, _dyno(), stock, 20_000.0, quiet, **kw)
    m.on_segment(_line(20, 390, 0.0, -depth, feed, rpm))
    return m


def test_chip_breaker_overload_scales_the_cutting_pressures() -> None:
    # A flat end mill's h_ex is fz (kappa = 90 deg): above max_chip_mm the chip terms rise by
    # 1 + gain (fz / max_chip - 1); without edge terms the whole force does.
    from analysis.config import EndMillCoefficients, Material

    coef = EndMillCoefficients(
        Ktc_n_mm2=800, Krc_n_mm2=300, Kac_n_mm2=100, Kte_n_mm=0, Kre_n_mm=0, Kae_n_mm=0
    )
    mat = Material(density_kg_m3=2700, endmill=coef)
    limited = FLAT.model_copy(update={"max_chip_mm": 0.1, "overload_gain": 3.0})
    rpm = 3000.0
    t = 0.5 + np.arange(400) / 20_000.0  # one revolution, well inside the block
    for fz, factor in ((0.08, 1.0), (0.1, 1.0), (0.15, 2.5)):
        free = _slot_machine(FLAT, mat, rpm, fz, 2.0).cutting_force(t)
        lim = _slot_machine(limited, mat, rpm, fz, 2.0).cutting_force(t)
        assert np.allclose(lim, factor * free, atol=1e-9 * np.abs(free).max()), fz


def test_regenerative_kernel_with_a_stiff_tool_is_the_quasi_static_force() -> None:
    # The kernel's own force law and chip against element_forces on the same engagement: a ball
    # (kappa varies over the slices) in a 0.7 mm slot, tool modes so stiff they do not move.
    from analysis.config import ToolMode, get_material

    mat = get_material("gm241")
    stiff = tuple(ToolMode(axis=a, f_hz=1500.0, zeta=0.03, k_N_m=1e9) for a in ("x", "y"))
    rpm, fz = 2000.0, 0.2
    t = 0.3 + np.arange(int(0.1 * 20_000)) / 20_000.0
    ref = _slot_machine(BALL, mat, rpm, fz, 0.7).cutting_force(t)
    m = _slot_machine(BALL, mat, rpm, fz, 0.7, tool_modes=stiff)
    m.cutting_force(np.arange(int(0.3 * 20_000)) / 20_000.0)  # memory filled by the earlier teeth
    got = m.cutting_force(t)
    err = np.abs(got - ref).max(axis=1)
    # Where the teeth switch, the edge forces jump: a sample there may fall on either side.
    jump = np.abs(np.diff(ref[:, 0], prepend=ref[0, 0])) > 0.2 * np.abs(ref).max()
    jump |= np.roll(jump, -1)
    assert err[~jump].max() < 0.01 * np.abs(ref).max() and jump.mean() < 0.01


@pytest.mark.parametrize("max_chip", [0.05, None])
def test_feed_sweep_base_feed_comes_from_the_chip_limit(max_chip: float | None) -> None:
    # Seed 001 4.2 on the twin (quasi-static): phi 30 ball, 0.3 mm slot, 2000 rpm. With the
    # edge's chip limit (h_ex = fz sin kappa = 0.05 mm at 0.255 mm/tooth) the base-feed analysis
    # finds 1000 mm/min from the forces alone; without it there is no change to find.
    from analysis.config import get_material, get_tool
    from analysis.rules.basefeed import SweepRun, find_base_feed

    tool = get_tool("phi30-ball").model_copy(update={"max_chip_mm": max_chip})
    rng = np.random.default_rng(3)
    runs = []
    for feed in range(400, 2201, 200):
        m = _slot_machine(tool, get_material("gm241"), 2000.0, feed / 4000.0, 0.3)
        t = 1.0 + np.arange(int(0.3 * 20_000)) / 20_000.0  # 10 revolutions of steady slot
        f = m.cutting_force(t)[:, :2] + rng.normal(0.0, 2.0, (t.size, 2))
        runs.append(SweepRun(float(feed), f, 20_000.0, 2000.0, 2))
    res = find_base_feed(runs)
    assert res.found == (max_chip is not None), res.message
    if max_chip is not None:
        assert res.base_feed_mm_min == 1000.0


def test_the_stand_in_chatter_keys_are_refused_saying_what_replaced_them(tmp_path) -> None:
    from analysis.config import config_dir
    from analysis.errors import ConfigError
    from rig.campaign import load_campaign

    text = (config_dir() / "campaigns" / "feed-sweep.toml").read_text()
    p = tmp_path / "old.toml"
    p.write_text(text.replace("[sim]\n", "[sim]\nchatter_fz_mm = 0.27\n"))
    with pytest.raises(ConfigError, match="chatter_fz_mm.*tool's modes.*max_chip_mm"):
        load_campaign(p)
