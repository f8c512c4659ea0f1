"""Paths the type checker found in rig/ that no test took (issue 30 item 4): a volts-only run in
the AFC report, a stability sweep of a material without end-mill coefficients, a dynamometer's
calibration arrays."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from analysis.config import load_rig
from analysis.errors import AnalysisError
from analysis.runs import file as rf
from rig.campaign import load_campaign
from rig.daq import Calibration, DaqInfo
from rig.log import RunWriter
from rig.report.afc import cutting_revolutions
from rig.report.base import LoadedRun
from rig.report.stability import stability_sweep_section

ROOT = Path(__file__).resolve().parents[1]


def _volts_run(tmp_path: Path) -> LoadedRun:
    """A run file recorded without a calibration: volts, no forces."""
    info = DaqInfo(
        device="test", physical_channels=("t/ai0", "t/ai1", "t/ai2"),
        channel_names=("Fx", "Fy", "Fz"), rate_hz=1000.0, sample_format="volts_float64",
        input_range_v=10.0, block_samples=500,
    )  # fmt: skip
    p = tmp_path / "volts.h5"
    with RunWriter(p, info) as w:
        w.set_conditions({"spindle_rpm": 3000.0})
        w.on_start(info, 0.0)
        w.on_block(0, np.zeros((3, 500)))
    return LoadedRun(0, "volts", "g", p, rf.load_run(p))


def test_afc_refuses_a_run_without_forces(tmp_path: Path) -> None:
    """One clear line naming the file, not a TypeError on None."""
    lr = _volts_run(tmp_path)
    assert lr.run.force_n is None
    with pytest.raises(AnalysisError, match=r"volts\.h5: no forces"):
        cutting_revolutions(lr)


def test_stability_sweep_refuses_a_material_without_endmill_coefficients(tmp_path: Path) -> None:
    """A real rig's campaign is not checked for them (the twin's is): the report says so in one
    line before it reads the tap records, not an AttributeError on None."""
    c = load_campaign(ROOT / "configs" / "campaigns" / "stability-sweep.toml")
    bare = dataclasses.replace(c, material=c.material.model_copy(update={"endmill": None}))
    with pytest.raises(AnalysisError, match=r"stability sweep: material .* no \[endmill\]"):
        stability_sweep_section(bare, [_volts_run(tmp_path)], tmp_path / "report", tmp_path)
    assert not (tmp_path / "report").exists()


def test_dynamometer_calibration_has_its_own_arrays() -> None:
    """from_dynamometer's vectors: float arrays, the amplifier's sensitivity a copy of the
    sheet's (one array each, as two lists gave), zero and drift zeros."""
    dyno = load_rig().dynamometer
    cal = Calibration.from_dynamometer(dyno)
    n = len(dyno.channels)
    sheet = [c.sensitivity_pc_n for c in dyno.channels]
    np.testing.assert_array_equal(cal.sensitivity_pc_n, sheet)
    np.testing.assert_array_equal(cal.amp_sensitivity_pc_n, cal.sensitivity_pc_n)
    assert cal.amp_sensitivity_pc_n is not cal.sensitivity_pc_n
    assert cal.sign.dtype == np.float64 and cal.zero_v.tolist() == [0.0] * n
    assert cal.drift_v_s.tolist() == [0.0] * n
    zeroed = cal.with_drift(np.ones(n)).zeroed(np.ones((4, n)), 2.0)
    assert zeroed.drift_v_s.tolist() == [0.0] * n and zeroed.zero_v.tolist() == [1.0] * n
