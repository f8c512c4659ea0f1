"""Identification from real HDF5 run files written by rig.log.RunWriter, streamed in chunks."""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
import pytest

from analysis.config import FaceMill, FaceMillCoefficients, get_tool, load_rig
from analysis.errors import AnalysisError
from analysis.forces import FaceMillCut, facemill_forces
from analysis.identify import RunConditions, reduce_run, reduce_run_file, synthetic_run
from analysis.identify.facemill import fit_facemill, fit_facemill_runs, synthetic_facemill_run
from analysis.modal import DynamometerFilter
from analysis.runs import SAMPLE_FORMAT_VOLTS
from rig.cli import main
from rig.daq import Calibration, DaqInfo
from rig.log import RunWriter

RATE = 10_000.0
TOOL = FaceMill(kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15,
                axial_rake_deg=7, radial_rake_deg=0, nose_radius_mm=0.4)  # fmt: skip
TRUE = FaceMillCoefficients(
    K_T_n_mm2=405.4, K_R=1.1, P_T_n_mm=39.7, P_R_n_mm=19.6, K_A=0.35, P_A_n_mm=8.0
)


def _write(path, run, rig, conditions=None):
    cal = Calibration.from_rig(rig)
    info = DaqInfo(
        device="Sim1", physical_channels=("ai0", "ai1", "ai2"),
        channel_names=tuple(c.name for c in rig.dynamometer.channels), rate_hz=run.rate_hz,
        sample_format=SAMPLE_FORMAT_VOLTS, input_range_v=10.0, block_samples=4096,
    )  # fmt: skip
    volts = cal.volts_from_force(run.force_n)
    w = RunWriter(path, info, cal, clock=lambda: 0.0, overwrite=True)
    w.on_start(info, 0.0)
    if conditions is None:
        conditions = {**asdict(run.conditions), "tool": "seed003-facemill"}
    w.set_conditions(conditions)
    for a in range(0, len(volts), 4096):
        w.put_block(a, volts[a : a + 4096].T.copy())
    w.close()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    rig = load_rig()
    modes = DynamometerFilter.from_config(rig.dynamometer, RATE, crosstalk=False)
    rng = np.random.default_rng(12)
    out = []
    for d in (0.5, 1.5, 3.0):
        c = RunConditions(spindle_rpm=600, fz_mm=0.236, depth_mm=d, width_mm=100.0)
        run = synthetic_facemill_run(f"d{d}", TOOL, TRUE, c, RATE, cut_s=2.0, dynamometer=modes,
                                     rng=rng, offset_n=(3, -2, 1), phase_rad=d)  # fmt: skip
        p = tmp_path_factory.mktemp("runs") / f"d{d}.h5"
        _write(p, run, rig)
        out.append((p, run))
    return out


def test_streamed_reduction_equals_in_memory(files):
    path, run = files[1]
    streamed = reduce_run_file(path, 1, chunk_samples=7_777)
    direct = reduce_run(run, 1)
    assert streamed.conditions.depth_mm == 1.5
    assert streamed.window == direct.window
    np.testing.assert_allclose(streamed.waveform_n, direct.waveform_n, atol=0.05)
    np.testing.assert_allclose(streamed.tooth_peak_n, direct.tooth_peak_n, rtol=0.05)


def test_fit_from_run_files(files):
    rig = load_rig()
    avgs = [reduce_run_file(p, 1, chunk_samples=50_000) for p, _ in files]
    fit = fit_facemill(avgs, TOOL, rig.dynamometer)
    assert fit.success, fit.message
    assert fit.coefficients.K_T_n_mm2 == pytest.approx(405.4, rel=0.02)
    assert fit.coefficients.P_R_n_mm == pytest.approx(19.6, rel=0.03)


def test_run_file_without_conditions_is_refused(tmp_path):
    rig = load_rig()
    run = synthetic_facemill_run(
        "x", TOOL, TRUE, RunConditions(spindle_rpm=600, fz_mm=0.2, depth_mm=1.0, width_mm=100),
        RATE, cut_s=0.5,
    )  # fmt: skip
    p = tmp_path / "x.h5"
    _write(p, run, rig, conditions={"fz_mm": 0.2, "depth_mm": 1.0})
    with pytest.raises(AnalysisError, match=r"x.h5: missing condition 'spindle_rpm'"):
        reduce_run_file(p, 1)


# --- A face mill crossing a block: tens of partly engaged revolutions at entry and exit ---------

BLOCK_RATE = 5000.0
BLOCK_MM, BLOCK_WIDTH_MM = 20.0, 50.0


def _block_run(name, tool, depth_mm, modes, rng, air_s=0.5):
    """Seed 003's cut (600 rpm, 0.236 mm/tooth) across a 20 mm block 50 mm wide: an insert cuts
    only while it is over the block (0 <= x <= 20 mm), so the cutter enters and leaves it over
    ~23 revolutions each, whose mean force creeps up to (and down from) the steady level."""
    c = RunConditions(spindle_rpm=600, fz_mm=0.236, depth_mm=depth_mm, width_mm=BLOCK_WIDTH_MM)
    cut = FaceMillCut(fz_mm=c.fz_mm, depth_mm=depth_mm, width_mm=BLOCK_WIDTH_MM)
    r_mm = tool.diameter_mm / 2
    v_mm_s = c.fz_mm * tool.inserts * c.spindle_rpm / 60.0
    omega = 2 * np.pi * c.spindle_rpm / 60.0
    # From the first touch (insert tip at x = 0) until the engaged arc has left the block.
    travel_mm = BLOCK_MM + r_mm - np.sqrt(r_mm**2 - (BLOCK_WIDTH_MM / 2) ** 2) + 1.0

    def forces(theta):
        t = (theta - depth_mm) / omega - air_s  # since the first touch (phase_rad = depth)
        x_insert = -r_mm + v_mm_s * t + r_mm * np.sin(theta)
        over = (x_insert >= 0) & (x_insert <= BLOCK_MM)
        return facemill_forces(theta, tool, TRUE, cut) * over[:, None]

    return synthetic_run(
        name, c, forces, BLOCK_RATE, travel_mm / v_mm_s, air_s=air_s, noise_frac=0.003,
        dynamometer=modes, rng=rng, phase_rad=depth_mm,
    )  # fmt: skip


@pytest.fixture(scope="module")
def block_files(tmp_path_factory):
    rig = load_rig()
    tool = get_tool("seed003-facemill")
    modes = DynamometerFilter.from_config(rig.dynamometer, BLOCK_RATE, crosstalk=False,
                                          drop_above_nyquist=True)  # fmt: skip
    rng = np.random.default_rng(3)
    folder = tmp_path_factory.mktemp("block")
    out = []
    for d in (0.5, 1.5, 3.0):
        run = _block_run(f"block-d{d}", tool, d, modes, rng)
        p = folder / f"block-d{d}.h5"
        _write(p, run, rig)
        out.append((p, run))
    return out


def _errors_pct(coefficients: dict) -> dict[str, float]:
    return {k: 100 * (coefficients[k] / getattr(TRUE, k) - 1) for k in coefficients}


@pytest.mark.long
def test_cli_default_steady_window_recovers_the_truth_across_block_entry(block_files, capsys):
    # The bound the demo's report meets (tests/test_campaign_report.py): 2 % on K_T, K_R, P_T,
    # P_R. At the old 5 % window the entry revolutions at 95-98 % of the level bias P_R by ~14 %.
    rc = main(["analyze", "forces", *(str(p) for p, _ in block_files), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0, out["message"]
    err = _errors_pct(out["coefficients"])
    for name in ("K_T_n_mm2", "K_R", "P_T_n_mm", "P_R_n_mm"):
        assert abs(err[name]) < 2.0, (name, err)
    # The axial pair from one feed at 5 kHz: this data's dynamometer is filtered on a grid 16 x
    # the rate (synthetic_run), the fit's model on one 64 x finer than its bins; K_A reads
    # -4.7 % (0.25 % with 64 x data, too slow for the default run)
    assert abs(err["K_A"]) < 6.0, err
    # and P_A, whose value this design cannot pin (+16 %), must not read as identified
    assert out["statistics"]["P_A_n_mm"]["identified"] is False, out["statistics"]["P_A_n_mm"]
    assert "measurement noise only" in out["statistics_note"]
    # The report's library call (fit_facemill_runs' default) agrees with the CLI's streamed path.
    fit = fit_facemill_runs([r for _, r in block_files], get_tool("seed003-facemill"),
                            load_rig().dynamometer)  # fmt: skip
    assert fit.success, fit.message
    for name, v in out["coefficients"].items():
        assert getattr(fit.coefficients, name) == pytest.approx(v, rel=2e-3), name


def test_cli_steady_tolerance_flag_sets_the_window(block_files, capsys):
    files = [str(p) for p, _ in block_files]
    rc = main(["analyze", "forces", *files, "--steady-tolerance", "0.05", "--json"])
    loose = json.loads(capsys.readouterr().out)
    assert rc == 0, loose["message"]
    # The looser window takes in more, partly engaged revolutions (it used to bias P_R by
    # -3 % and more; the model now takes each height of an insert into the block on its own
    # ray, so they bias it less): the window is what the flag sets.
    rc = main(["analyze", "forces", *files, "--json"])
    default = json.loads(capsys.readouterr().out)
    assert [r["revolutions"] for r in loose["per_run"]] > [0, 0, 0]
    assert sum(r["revolutions"] for r in loose["per_run"]) > sum(
        r["revolutions"] for r in default["per_run"]
    )
    with pytest.raises(SystemExit) as exc:  # refused when the options are parsed
        main(["analyze", "forces", *files, "--steady-tolerance", "5"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--steady-tolerance" in err and "fraction" in err


def test_cli_refuses_runs_cut_with_another_tool(block_files, capsys):
    files = [str(p) for p, _ in block_files]
    rc = main(["analyze", "forces", *files, "--tool", "phi10-flat"])
    err = capsys.readouterr().err
    assert rc == 2 and "Traceback" not in err
    assert "block-d0.5.h5" in err and "'seed003-facemill'" in err and "'phi10-flat'" in err
    # Naming the recorded tool is fine.
    rc = main(["analyze", "forces", *files, "--tool", "seed003-facemill", "--json"])
    assert rc == 0 and json.loads(capsys.readouterr().out)["model"] == "facemill"
