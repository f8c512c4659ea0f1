"""Calibration: force -> charge -> volts and back, cross-talk, zeroing, linear drift."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.config import Dynamometer, DynoChannel, load_rig
from analysis.errors import ConfigError
from rig.daq.calibration import Calibration, CalibrationError, compensate, fit_drift


def _cal(**kw) -> Calibration:
    base = dict(
        channel_names=("Fx", "Fy", "Fz"),
        sensitivity_pc_n=[-7.9, -7.8, -3.7],
        range_n_v=[500.0, 250.0, 1000.0],
        sign=[1, -1, 1],
        crosstalk=[[1.0, 0.01, 0.02], [-0.01, 1.0, 0.01], [0.015, -0.01, 1.0]],
        amp_sensitivity_pc_n=[-7.9, -7.8, -3.7],
    )
    base.update(kw)
    return Calibration(**base)


def test_closed_form_without_crosstalk() -> None:
    # Identity cross-talk, amplifier set to the sheet sensitivity: V = sign F / R, q = S sign F.
    cal = _cal(crosstalk=np.eye(3))
    f = np.array([[100.0, 200.0, -300.0]])
    np.testing.assert_allclose(cal.charge_pc(f), [[-790.0, 7.8 * 200.0, 1110.0]])
    np.testing.assert_allclose(cal.volts_from_force(f), [[0.2, -0.8, -0.3]])
    # Amplifier dialled to twice the sensor sensitivity halves the output.
    cal2 = _cal(crosstalk=np.eye(3), amp_sensitivity_pc_n=[-15.8, -15.6, -7.4])
    np.testing.assert_allclose(cal2.volts_from_force(f), [[0.1, -0.4, -0.15]])
    np.testing.assert_allclose(cal2.force_from_volts(cal2.volts_from_force(f)), f)


def test_known_force_round_trip_within_float_precision() -> None:
    rng = np.random.default_rng(1)
    cal = _cal(amp_sensitivity_pc_n=[-8.0, -7.5, -3.9])
    f = rng.normal(0, 800.0, (10_000, 3))
    back = cal.force_from_volts(cal.volts_from_force(f))
    np.testing.assert_allclose(back, f, rtol=0, atol=1e-12 * np.abs(f).max())
    # Cross-talk is really applied: without inverting it the forces differ by ~1-2 %.
    naive = cal.volts_from_force(f) * cal.range_n_v * cal.sign
    assert np.abs(naive - f).max() > 5.0


@settings(max_examples=60, deadline=None)
@given(
    sens=st.lists(st.floats(-20, -0.5), min_size=3, max_size=3),
    rng_nv=st.lists(st.floats(1.0, 5000.0), min_size=3, max_size=3),
    off=st.lists(st.floats(-0.05, 0.05), min_size=6, max_size=6),
    signs=st.lists(st.sampled_from([1, -1]), min_size=3, max_size=3),
)
def test_round_trip_property(sens, rng_nv, off, signs) -> None:
    c = np.eye(3)
    c[np.triu_indices(3, 1)] = off[:3]
    c[np.tril_indices(3, -1)] = off[3:]
    cal = _cal(
        sensitivity_pc_n=sens,
        amp_sensitivity_pc_n=sens,
        range_n_v=rng_nv,
        sign=signs,
        crosstalk=c,
    )
    f = np.array([[123.0, -456.0, 789.0], [0.0, 0.0, 0.0], [-1e4, 3e3, 2e2]])
    np.testing.assert_allclose(cal.force_from_volts(cal.volts_from_force(f)), f, atol=1e-9)


def test_zeroing_removes_offset() -> None:
    cal = _cal(zero_v=[0.05, -0.02, 0.1])
    rest = cal.volts_from_force(np.zeros((200, 3)))
    raw = _cal()  # not zeroed: the offset shows as force
    assert np.abs(raw.force_from_volts(rest)).max() > 1.0
    zeroed = raw.zeroed(rest, time_s=3.0)
    assert zeroed.zero_time_s == 3.0
    np.testing.assert_allclose(zeroed.force_from_volts(rest), 0.0, atol=1e-9)


def test_drift_compensation_removes_known_linear_drift() -> None:
    rng = np.random.default_rng(7)
    rate_hz, n = 1000.0, 20_000
    t = 5.0 + np.arange(n) / rate_hz
    truth = np.zeros((n, 3))
    cut = (t > 7.0) & (t < 23.0)  # rest before and after the cut
    truth[cut] = [300.0, -150.0, 80.0] + rng.normal(0, 20.0, (cut.sum(), 3))
    drift_v_s = np.array([2e-3, -1e-3, 5e-4])
    zero_v = np.array([0.01, -0.03, 0.02])
    amp = _cal(zero_v=zero_v, zero_time_s=5.0, drift_v_s=drift_v_s)
    volts = amp.volts_from_force(truth, t)
    plain = _cal().zeroed(volts[:100], time_s=5.0)
    err_plain = np.abs(plain.force_from_volts(volts) - truth).max()
    fit = fit_drift(t, volts, ~cut)
    np.testing.assert_allclose(fit.drift_v_s, drift_v_s, rtol=1e-9)
    fixed = compensate(_cal(), fit)
    err_fixed = np.abs(fixed.force_from_volts(volts, t) - truth).max()
    assert err_plain > 10.0  # 2 mV/s over 20 s at 500 N/V: ~20 N of drift left by zeroing alone
    assert err_fixed < 1e-6


def test_drift_fit_with_noise_is_unbiased() -> None:
    rng = np.random.default_rng(3)
    t = np.linspace(0, 60, 60_000)
    rest = (t < 5) | (t > 55)
    v = 0.02 + 1e-3 * t[:, None] + rng.normal(0, 1e-3, (len(t), 3))
    fit = fit_drift(t, v, rest)
    np.testing.assert_allclose(fit.drift_v_s, 1e-3, atol=3e-6)
    assert np.all(fit.residual_rms_v < 1.1e-3)


def test_drift_needs_rest_at_two_times() -> None:
    t = np.arange(10.0)
    with pytest.raises(CalibrationError, match="rest before and after"):
        fit_drift(t, np.zeros((10, 3)), t == 3)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"crosstalk": [[1.0, 0.0], [0.0, 1.0]]}, "crosstalk matrix is 2x2: expected 3x3"),
        ({"crosstalk": np.ones((3, 3))}, "singular"),
        ({"range_n_v": [500.0, 0.0, 1.0]}, "range_n_v"),
        ({"sign": [1, 2, 1]}, "sign"),
        ({"sensitivity_pc_n": [-7.9, -7.8]}, r"sensitivity_pc_n has shape \(2,\)"),
    ],
)
def test_bad_calibration_is_a_clear_error(kw, match) -> None:
    with pytest.raises(CalibrationError, match=match):
        _cal(**kw)


def test_calibration_must_match_daq_channels() -> None:
    rig = load_rig()
    with pytest.raises(ConfigError, match="dynamometer.channels has 3 channels .* has 6"):
        Calibration.from_dynamometer(rig.dynamometer, 6, "configs/rig.toml")
    cal = Calibration.from_rig(rig)
    assert cal.channel_names == ("Fx", "Fy", "Fz")
    assert cal.calibration_id == rig.dynamometer.calibration_id


def test_volts_shape_checked() -> None:
    with pytest.raises(CalibrationError, match=r"expected \(n, 3\)"):
        _cal().force_from_volts(np.zeros((10, 2)))


def test_config_without_crosstalk_uses_identity() -> None:
    dyno = Dynamometer(
        model="x",
        channels=(
            DynoChannel(name="Fx", axis="x", sensitivity_pc_n=-7.5, range_n_v=100.0),
            DynoChannel(name="Fz", axis="z", sign=-1, sensitivity_pc_n=-3.7, range_n_v=200.0),
        ),
    )
    cal = Calibration.from_dynamometer(dyno, 2)
    np.testing.assert_allclose(cal.volts_to_n, np.diag([100.0, -200.0]))
