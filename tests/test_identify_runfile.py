"""Identification from real HDF5 run files written by rig.logger.RunWriter, streamed in chunks."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np
import pytest

from analysis._identify import RunConditions, reduce_run, reduce_run_file
from analysis.config import FaceMill, FaceMillCoefficients, load_rig
from analysis.dynamics import DynamometerFilter
from analysis.errors import AnalysisError
from analysis.identify_facemill import fit_facemill, synthetic_facemill_run
from analysis.runfile import SAMPLE_FORMAT_VOLTS
from rig.calibration import Calibration
from rig.daq.base import DaqInfo
from rig.logger import RunWriter

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
