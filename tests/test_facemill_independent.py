"""Seed 003 judged by data its model did not make: rig/sim/facemill_independent.py (the edge
sliced axially, each slice at its own radius and angle, exact circles for the chip, per-insert
runout, the block's edges, the dynamometer's modes) against a hand calculation of one insert's
chip, beside ``analysis.forces.facemill``, and through ``cutlab analyze forces`` on run files
written by the run writer, as a user would.

What the independent data showed (issue 33, measured here):

- Steady cutting away from the entry and exit: the two models agree within 0.4 % of the peak (the
  rest is the rake's angular lag of the upper slices, which seed 003's point insert leaves out;
  without it 0.02 %).
- Before issue 33's fixes the identification was not within 2 % on it (three feeds: K_T -1.5 %,
  P_R -5.0 %, P_A -4.5 %): an insert's edge enters the workpiece over 0.3-1 deg (the top of a
  2 mm cut on a 15 deg lead sits 0.54 mm further out than the nose: it enters at acos(50 / 63.04)
  = 37.5 deg, the nose at acos(50 / 62.5) = 36.9 deg, 1.8 samples later at 10 kHz and 600 rpm),
  while the model took the whole insert in at once at the nose's radius, and the fit filtered its
  regressors at the sample rate, where the dynamometer answers to an entry between samples.
  Both were cutlab's side: the model now takes each height in on its own ray
  (``analysis.forces._facemill_geometry.partial_fraction``) and the fit filters on a grid 64 x
  finer than the bins. Three feeds, symmetric: every coefficient within 0.7 %.
- The simulator's own slip, found on the offset cut: its candidate samples cut off the upper
  slices, which lag the nose by the rake (0.36 deg at 3 mm), near 90 deg (fixed).
- The offset cut (20 mm off a 50 mm block's centre) then still missed (K_T +3.6 %, P_R -29 %,
  residuals 3.5-14 N rms at 0.1 mm/tooth): not the engagement angles or the up/down sides (with
  the window fixed the offset fit matches the centred one within 0.1 %) but the steady window.
  Fed at 1 mm/s the cutter is wholly over the block 19.9 s after its first touch, and the last
  3-4 s of that entry lie within 2 % of the steady level: the force level took them as steady.
  The window now starts at the first touch plus the geometry's entry time
  (``analysis.identify.facemill.entry_s``): offset and centred cuts identify all six within
  0.7 %, residuals 0.13-0.46 N rms.
- At one feed K_R and K_A miss by about 2 % (the demo: +2.3 %, +2.8 %) while the force per mm
  of depth at that feed is within 0.5 %: the design cannot split K from P (only the nose's cusp
  tells the edge length from the chip area at a fixed feed), not a bias of either model; on
  records 16 x finer (the twin's grid ruled out) K_R +2.0 %, K_A +2.3 %.
"""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
import pytest

from analysis.config import FaceMill, FaceMillCoefficients, load_rig
from analysis.identify import RunConditions
from analysis.runs import SAMPLE_FORMAT_VOLTS
from rig.cli import main
from rig.daq import Calibration, DaqInfo
from rig.log import RunWriter
from rig.sim import facemill_independent as fi

RATE = 10_000.0
TOOL = FaceMill(kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15, axial_rake_deg=7,
                radial_rake_deg=0, nose_radius_mm=0.4)  # fmt: skip
TRUE = FaceMillCoefficients(
    K_T_n_mm2=405.4, K_R=1.1, P_T_n_mm=39.7, P_R_n_mm=19.6, K_A=0.35, P_A_n_mm=8.0
)
NAMES = ("K_T_n_mm2", "K_R", "P_T_n_mm", "P_R_n_mm", "K_A", "P_A_n_mm")
DEPTHS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)


def test_insert_axes_solve_the_projected_angles():
    """theta_1..3 from the orthogonality conditions: orthonormal, and the projections of A' on
    RA, R' on TR, T' on TA make the tool angles (seed 003 2.2.2)."""
    m = fi.insert_axes(15.0, 0.0, 7.0)
    np.testing.assert_allclose(m.T @ m, np.eye(3), atol=1e-12)
    tp, rp, ap = m[:, 0], m[:, 1], m[:, 2]
    assert np.degrees(np.arctan2(ap[1], ap[2])) == pytest.approx(15.0)  # lead: A' in RA
    assert np.degrees(np.arctan2(rp[0], rp[1])) == pytest.approx(0.0, abs=1e-12)  # TR
    assert np.degrees(np.arctan2(tp[2], tp[0])) == pytest.approx(7.0)  # axial rake: T' in TA


def test_one_inserts_chip_by_hand():
    """Zero rakes, lead 15 deg: the rake face is the RA plane, R' and A' are the minor and major
    edges turned 15 deg. At theta = 90 deg the chip is exactly f (eq 1 with cos = 0), X' = F_R,
    Y' = -F_T, Z' = F_A. Above the cusp one more millimetre of depth adds f mm^2 of chip and
    1 / cos 15 mm of major edge, so per mm of depth (eqs 3-4):
    dF_T = P_T / cos 15 + K_T f, dF_R = cos 15 dF_R' + sin 15 dF_A', dF_A = -sin 15 dF_R' +
    cos 15 dF_A' with dF_R' = P_R / cos 15 + K_R K_T f, dF_A' = P_A / cos 15 + K_A K_T f."""
    tool = TOOL.model_copy(update={"axial_rake_deg": 0.0})
    f, c15, s15 = 0.236, np.cos(np.radians(15)), np.sin(np.radians(15))
    k = TRUE
    d_ft = k.P_T_n_mm / c15 + k.K_T_n_mm2 * f
    d_frp = k.P_R_n_mm / c15 + k.K_R * k.K_T_n_mm2 * f
    d_fap = k.P_A_n_mm / c15 + k.K_A * k.K_T_n_mm2 * f
    want = np.array([c15 * d_frp + s15 * d_fap, -d_ft, -s15 * d_frp + c15 * d_fap])
    one = np.zeros(2, int)
    got = fi.insert_forces(np.full(2, np.pi / 2), one, np.full(2, f), np.array([1.0, 2.5]),
                           tool, TRUE, exact=True)  # fmt: skip
    np.testing.assert_allclose((got[1] - got[0]) / 1.5, want, rtol=2e-4)
    # the whole chip at 2.5 mm: f x 2.5 less what the cusp leaves (a sliver, < 1 %)
    tab = fi._edge(tool)
    assert tab.cos_nu == pytest.approx(1.0)
    # the radial chip at theta = 60 deg, from eq 1's exact form, through the tabulated twin path
    th = np.radians(60.0)
    h = 62.5 + f * np.sin(th) - np.sqrt(62.5**2 - (f * np.cos(th)) ** 2)
    g = fi.insert_forces(np.full(2, th), one, np.full(2, f), np.array([1.0, 2.5]), tool, TRUE)
    d_ft60 = k.P_T_n_mm / c15 + k.K_T_n_mm2 * h
    d_fr60 = c15 * (k.P_R_n_mm / c15 + k.K_R * k.K_T_n_mm2 * h) + s15 * (
        k.P_A_n_mm / c15 + k.K_A * k.K_T_n_mm2 * h
    )
    c, s = np.cos(th), np.sin(th)
    want60 = np.array([c * d_ft60 + s * d_fr60, -s * d_ft60 + c * d_fr60])
    np.testing.assert_allclose((g[1, :2] - g[0, :2]) / 1.5, want60, rtol=1e-3)


def test_radial_runout_changes_each_inserts_chip_by_hand():
    """Three inserts, zero rakes, an eccentricity e (insert k at R + e cos a_k): at theta = 90 deg
    insert k cuts the surface left by the insert ahead of it in angle (it passed there a pitch
    earlier), so its chip is f + e cos a_k - e cos a_(k+1) and its Y' force grows with depth by
    P_T / cos 15 + K_T h_k per mm."""
    e, f = 0.02, 0.1
    tool = TOOL.model_copy(update={"axial_rake_deg": 0.0, "inserts": 3, "runout_mm": e})
    a = np.radians([0.0, 120.0, 240.0])
    for k in range(3):
        h = f + e * np.cos(a[k]) - e * np.cos(a[(k + 1) % 3])
        ins = np.full(2, k)
        got = fi.insert_forces(np.full(2, np.pi / 2), ins, np.full(2, f), np.array([1.0, 2.5]),
                               tool, TRUE, exact=True)  # fmt: skip
        slope = -(got[1, 1] - got[0, 1]) / 1.5
        assert slope == pytest.approx(TRUE.P_T_n_mm / np.cos(np.radians(15)) +
                                      TRUE.K_T_n_mm2 * h, rel=2e-4), k  # fmt: skip


def test_steady_forces_beside_the_seed003_model():
    """Away from entry and exit the two agree within 0.5 % of the peak (the upper slices' lag
    behind the nose, which the point insert leaves out, is most of it); not a reference for the
    model, the hand calculation above is."""
    from analysis.forces.facemill import FaceMillCut, facemill_forces

    th = np.radians(np.arange(20.0, 161.0, 10.0))
    n = len(th)
    for fz in (0.05, 0.236, 0.345):
        for d in (0.5, 3.0):
            a = fi.insert_forces(th, np.zeros(n, int), np.full(n, fz), np.full(n, d), TOOL, TRUE,
                                 exact=True)  # fmt: skip
            b = facemill_forces(th, TOOL, TRUE, FaceMillCut(fz, d, entry_deg=0, exit_deg=180))
            assert np.abs(a - b).max() < 0.005 * np.abs(b).max(), (fz, d)


def test_twin_tables_match_the_direct_computation():
    th = np.random.default_rng(1).uniform(0.02, np.pi - 0.02, 500)
    n = len(th)
    args = (th, np.zeros(n, int), np.full(n, 0.236), np.full(n, 2.0), TOOL, TRUE)
    a, b = fi.insert_forces(*args), fi.insert_forces(*args, exact=True)
    assert np.abs(a - b).max() < 2e-3 * np.abs(b).max()


def test_entry_of_a_leaning_edge_takes_part_of_a_sample():
    """The hand figure of the module docstring: a 2 mm cut over a 100 mm block enters over
    about 0.6 deg (the top of the cut 2 tan 15 mm further out than the nose, less the rake's lag),
    where the point insert enters at once at the nose's acos(50 / 62.5). The chip's first corner
    (the earlier pass's surface, f sin(theta) inside the nose's circle) meets the block first."""
    nose = np.degrees(np.arccos(50 / 62.5))
    top = np.degrees(np.arccos(50 / (62.5 + 2.0 * np.tan(np.radians(15)))))
    psi = np.radians(np.arange(36.0, 39.0, 0.01))
    n = len(psi)
    one = np.ones(n)
    window = (-50 * one, 50 * one, -1e6 * one, 1e6 * one, 0 * one)
    f = fi._forces(fi._edge(TOOL), fi._coef(TRUE), psi, 2.0 * one, np.array([[0.236, 0.472]] * n),
                   np.zeros((n, 2)), np.zeros((n, 2)), window, one)  # fmt: skip
    mag = np.abs(f[:, 1])
    deg = np.degrees(psi)
    first, full = deg[mag > 0].min(), deg[mag > 0.99 * mag.max()].min()
    chip = np.degrees(np.arccos(50 / (62.5 - 0.236 * np.sin(np.radians(nose)))))
    assert chip - 0.02 <= first <= nose
    # the chip's own width (f sin) and the rake's lag add to the lean: 1.2 deg here, 3 samples
    assert top - nose < full - first < 2.5 * (top - nose)


# --- through `cutlab analyze forces`, run files from the run writer -------------------------


def _modes():
    rig = load_rig()
    by_axis = {m.axis: (m.frequency_hz, m.damping_ratio) for m in rig.dynamometer.modes}
    return rig, tuple(by_axis[a] for a in "xyz")


def _write(path, t, force, rig, conditions):
    cal = Calibration.from_rig(rig)
    info = DaqInfo(
        device="Sim1", physical_channels=("ai0", "ai1", "ai2"),
        channel_names=tuple(c.name for c in rig.dynamometer.channels), rate_hz=RATE,
        sample_format=SAMPLE_FORMAT_VOLTS, input_range_v=10.0, block_samples=4096,
    )  # fmt: skip
    volts = cal.volts_from_force(force)
    w = RunWriter(path, info, cal, clock=lambda: 0.0, overwrite=True)
    w.on_start(info, 0.0)
    w.set_conditions(conditions)
    for a in range(0, len(volts), 4096):
        w.put_block(a, volts[a : a + 4096].T.copy())
    w.close()


def _campaign(folder, tool=TOOL, tool_name="seed003-facemill", feeds=(0.236,), depths=DEPTHS,
              width=50.0, offset=0.0, oversample=4, steady_s=2.0, **run):  # fmt: skip
    """Run files of a campaign made by the independent simulator: the modes of configs/rig.toml
    (the dynamometer answers between samples: ``oversample`` x), offsets, drift, 0.5 N noise."""
    rig, modes = _modes()
    files = []
    for i, (fz, d) in enumerate((fz, d) for fz in feeds for d in depths):
        rec = fi.Record(rate_hz=RATE, modes=modes, offset_n=(3.0, -2.0, 1.0),
                        drift_n_s=(0.05, 0.0, 0.0), noise_n=0.5, seed=i, phase_rad=0.37 * i,
                        oversample=oversample)  # fmt: skip
        r = fi.Run(fz_mm=fz, depth_mm=d, width_mm=width, center_offset_mm=offset,
                   steady_s=steady_s, **run)  # fmt: skip
        t, f, _ = fi.simulate(tool, TRUE, r, rec)
        c = RunConditions(spindle_rpm=600, fz_mm=fz, depth_mm=d, width_mm=width,
                          center_offset_mm=offset)  # fmt: skip
        p = folder / f"{i:03d}-fz{fz}-d{d}.h5"
        _write(p, t, f, rig, {**asdict(c), "tool": tool_name})
        files.append(str(p))
    return files


def _analyze(files, capsys, *extra):
    rc = main(["analyze", "forces", *files, "--json", *extra])
    out = json.loads(capsys.readouterr().out)
    got = out.get("coefficients") or {}
    err = {k: 100 * (got[k] / getattr(TRUE, k) - 1) if k in got else np.inf for k in NAMES}
    return rc, out, err


def test_one_feed_never_reports_the_ploughing_pair_as_identified(tmp_path, capsys):
    """Seed 003's own design (one feed per tooth, several depths), a short campaign: the output
    either refuses the fit with its reason (here: a negative P_R, exit 1) or says the ploughing
    coefficients are not identified at one feed; never a confident ploughing pair."""
    files = _campaign(tmp_path, depths=(0.5, 1.5, 3.0), oversample=1, steady_s=1.0)
    rc, out, err = _analyze(files, capsys)
    if rc == 0:
        assert "not identified" in out["message"] and "1 feed" in out["message"], out["message"]
    else:
        assert rc == 1 and not out["success"] and "out of range" in out["message"]


@pytest.fixture(scope="module")
def one_feed(tmp_path_factory):
    return _campaign(tmp_path_factory.mktemp("indep"))


def _per_mm_of_depth(c, fz):
    """dF_T', dF_R', dF_A' per mm of depth above the cusp at feed fz (the hand calculation's)."""
    c15 = np.cos(np.radians(15))
    k = c["K_T_n_mm2"] * fz
    return np.array([c["P_T_n_mm"] / c15 + k, c["P_R_n_mm"] / c15 + c["K_R"] * k,
                     c["P_A_n_mm"] / c15 + c["K_A"] * k])  # fmt: skip


@pytest.mark.slow
def test_one_feed_campaign_force_per_depth_within_1_percent(one_feed, capsys):
    """Seed 003's campaign (0.236 mm/tooth, depth 0.5..3 mm, 50 mm wide, the dynamometer
    answering between samples): at one feed the edge length and the chip area both grow with
    depth, so the fit holds the force per mm of depth at that feed, and K_T within 2 %; the split
    into K and P rests on the nose's cusp alone and the output says so. Measured (the steady
    window bounded by the geometry): K_T -1.04 %, K_R +2.21 %, P_T +1.23 %, P_R -3.96 %, K_A
    +2.50 %, P_A -3.75 %; per mm of depth -0.36, +0.32, +0.40 % (before the bound K_R +1.8 %:
    the split moves with the window)."""
    rc, out, err = _analyze(one_feed, capsys)
    print("one feed, error %:", {k: round(v, 2) for k, v in err.items()})
    print("one feed, split:", out["split"]["inflation"], out["split"]["correlation"])
    assert rc == 0 and "not identified" in out["message"] and "1 feed" in out["message"]
    assert "K_T, K_R, K_A identified as force per depth only (one feed" in out["message"]
    # the design says so per coefficient, on each number's line (text) and row (JSON)
    assert min(out["split"]["inflation"].values()) > out["split"]["inflation_limit"]
    for k in NAMES:
        row = out["statistics"][k]
        want = "not identified" if k.startswith("P_") else "identified as force per depth only"
        assert row["status"].startswith(want) and row["identified"] is False, (k, row)
    got = _per_mm_of_depth(out["coefficients"], 0.236)
    want = _per_mm_of_depth({k: getattr(TRUE, k) for k in NAMES}, 0.236)
    print("per mm of depth, error %:", np.round(100 * (got / want - 1), 2))
    np.testing.assert_allclose(got, want, rtol=0.01)
    assert abs(err["K_T_n_mm2"]) < 2.0 and max(abs(err["K_R"]), abs(err["K_A"])) < 4.0, err


@pytest.mark.slow
@pytest.mark.timeout(1800)  # the offset case: 225 s alone on a loaded 2-core host, over 300 beside
@pytest.mark.parametrize("offset", [0.0, 20.0])
def test_three_feeds_identify_all_six_within_2_percent(tmp_path, capsys, offset):
    """0.1, 0.236, 0.345 mm/tooth x 0.5, 1.5, 3 mm, measured in memory on the same data:
    symmetric K_T -0.40 %, K_R +0.61 %, P_T -0.09 %, P_R +0.25 %, K_A +0.70 %, P_A +0.21 %;
    20 mm offset K_T -0.48 %, K_R +0.60 %, P_T -0.14 %, P_R +0.24 %, K_A +0.69 %, P_A +0.21 %
    (before issue 33's fixes, symmetric K_T -1.5 %, P_R -5.0 %, P_A -4.5 %; before the
    geometry's entry bound, offset K_T +3.6 %, P_R -29 %: the steady window took in 3-4 s of the
    offset entry, whose force was already within 2 % of the steady level)."""
    files = _campaign(tmp_path, feeds=(0.1, 0.236, 0.345), depths=(0.5, 1.5, 3.0), offset=offset)
    rc, out, err = _analyze(files, capsys)
    print(f"three feeds, offset {offset} mm, error %:", {k: round(v, 2) for k, v in err.items()})
    print("three feeds, split:", out["split"]["inflation"])
    assert rc == 0 and max(abs(v) for v in err.values()) < 2.0, err
    # the design splits every direction; the edge terms' status is the adequacy check's
    assert max(out["split"]["inflation"].values()) < out["split"]["inflation_limit"]
    for k in ("K_T_n_mm2", "K_R", "K_A"):
        assert out["statistics"][k]["status"] == "identified", out["statistics"][k]


# --- the steady window of a face mill fed into a block (issue 33's offset cut) ---------------


def test_entry_time_by_hand():
    """The cutter touches first with the top of the cut on its line (62.5 + 3 tan 15 mm out)
    and is wholly over the block once the arc's ends, 45 mm off its line (20 mm offset, 50 mm
    wide), are past the front: sqrt(62.5^2 - 45^2) = 43.37 mm; at 1 mm/s 19.93 s. Centred, the
    ends are 25 mm off: 63.30 - 57.28 = 6.02 s. A block beside the line (offset 40 mm) is first
    touched 15 mm off it."""
    from analysis.identify.facemill import entry_s

    def c(off, width=50.0):
        return RunConditions(spindle_rpm=600, fz_mm=0.1, depth_mm=3.0, width_mm=width,
                             center_offset_mm=off)  # fmt: skip

    reach = 62.5 + 3.0 * np.tan(np.radians(15))
    assert entry_s(TOOL, c(20.0)) == pytest.approx(reach - np.sqrt(62.5**2 - 45**2))
    assert entry_s(TOOL, c(0.0)) == pytest.approx(reach - np.sqrt(62.5**2 - 25**2))
    want = np.sqrt(reach**2 - 15**2) - 0.0  # the far end beyond the radius: the arc's half
    assert entry_s(TOOL, c(40.0)) == pytest.approx(want)


def test_steady_window_waits_for_full_engagement():
    """A record whose force creeps the last 1.5 % over 4 s of its entry (as an offset cut's
    does): by level alone those seconds count as steady; with the geometry's entry time the
    window starts after it. A record steady at once (no entry in it) keeps its window."""
    from analysis.runs.steady import find_steady

    rate, rpm = 2000.0, 600.0
    t = np.arange(int(12.0 * rate)) / rate
    touch, entry = 1.0, 8.0  # a second of air before: the offset
    u = np.clip((t - touch) / entry, 0.0, 1.0)
    level = np.where(t < touch, 0.0, 0.985 * np.minimum(u / 0.5, 1.0) + 0.015 * u)
    level = np.where(t > 10.5, 0.0, level)
    wave = 100.0 * level * (1.0 + 0.5 * np.sin(2 * np.pi * rpm / 60.0 * t))
    f = np.stack([wave, 0.3 * wave, 0.1 * wave], axis=1)
    f += np.random.default_rng(0).normal(0.0, 0.05, f.shape)
    plain = find_steady(f, rate, rpm, tolerance=0.02)
    bound = find_steady(f, rate, rpm, tolerance=0.02, engaged_after_s=entry)
    assert plain.window.start / rate < touch + entry - 2.0
    assert touch + entry <= bound.window.start / rate <= touch + entry + 0.3
    on = ((t > touch) & (t < 10.5)) * 100.0 * (1.0 + 0.5 * np.sin(2 * np.pi * rpm / 60.0 * t))
    at_once = np.stack([on, 0.3 * on, 0.1 * on], axis=1)
    at_once += np.random.default_rng(0).normal(0.0, 0.05, f.shape)
    a = find_steady(at_once, rate, rpm, tolerance=0.02)
    b = find_steady(at_once, rate, rpm, tolerance=0.02, engaged_after_s=entry)
    assert a.window == b.window
