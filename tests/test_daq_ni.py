"""NI-DAQmx driver against the real nidaqmx classes under autospec (a wrong call fails here).

A small device model stands behind the autospec'd reader: it counts samples acquired, keeps a
ring buffer's worth of them, raises the real DaqError -200279 when a read asks for overwritten
samples and honours in_stream.relative_to / offset, as DAQmx does.
"""

from __future__ import annotations

from pathlib import Path
from unittest.mock import call, create_autospec

import nidaqmx
import nidaqmx.errors
import numpy as np
import pytest
from nidaqmx.constants import (
    AcquisitionType,
    OverwriteMode,
    ReadRelativeTo,
    TerminalConfiguration,
    VoltageUnits,
)
from nidaqmx.stream_readers import AnalogMultiChannelReader, AnalogUnscaledReader
from nidaqmx.task import InStream, Timing
from nidaqmx.task.channels import AIChannel
from nidaqmx.task.collections import AIChannelCollection

from analysis.config import DaqConfig, load_rig
from analysis.runs import file as rf
from rig.daq import Calibration, DaqError, DaqNotAvailableError
from rig.daq.ni import NiDaq
from rig.log import RunWriter

COEFF = [0.0012, 3.0517578125e-4, 1e-12, 0.0]  # a device's polynomial: volts = sum c_j code^j


def _code(index: np.ndarray, ch: int) -> np.ndarray:
    """The code the model device gives channel ch at device sample index: tells the index."""
    return ((index * 7 + ch * 1000) % 60000 - 30000).astype(np.int16)


class Device:
    """The hardware behind the mocks: samples acquired, ring buffer, read position."""

    def __init__(self, task, channels: int, buffer_samples: int) -> None:
        self.task, self.c, self.buffer = task, channels, buffer_samples
        self.acquired = 0
        self.pos = 0
        self.stream = task.in_stream
        self.stream.relative_to = ReadRelativeTo.CURRENT_READ_POSITION
        self.stream.offset = 0
        self._sync()

    def _sync(self) -> None:
        self.stream.total_samp_per_chan_acquired = self.acquired

    def acquire(self, n: int) -> None:
        self.acquired += n
        self._sync()

    def _where(self) -> int:
        if self.stream.relative_to == ReadRelativeTo.FIRST_SAMPLE:
            return int(self.stream.offset)
        return self.pos + int(self.stream.offset)

    def read(self, data: np.ndarray, number_of_samples_per_channel: int, timeout: float) -> int:
        n = number_of_samples_per_channel
        assert data.flags.c_contiguous and data.shape == (self.c, n)  # as nidaqmx verifies
        start = self._where()
        if start < self.acquired - self.buffer:
            raise nidaqmx.errors.DaqReadError(
                "Attempted to read samples that are no longer available.", -200279, 0
            )
        if start + n > self.acquired:
            raise nidaqmx.errors.DaqReadError("Samples not yet available.", -200284, 0)
        idx = np.arange(start, start + n)
        for ch in range(self.c):
            data[ch] = _code(idx, ch) if data.dtype == np.int16 else _code(idx, ch) * 1e-3
        self.pos = start + n
        return n


def _rig(**kw) -> DaqConfig:
    base = dict(
        device="Dev1",
        channels=("Dev1/ai0", "Dev1/ai1", "Dev1/ai2"),
        rate_hz=10_000.0,
        input_range_v=10.0,
        buffer_s=1.0,
        read_interval_s=0.1,
        raw=True,
    )
    base.update(kw)
    return DaqConfig(**base)


def _mock_nidaqmx(cfg: DaqConfig):
    task_cls = create_autospec(nidaqmx.Task)
    task = task_cls.return_value
    # Task's collections are properties, which autospec leaves unspecced: spec them explicitly.
    task.ai_channels = create_autospec(AIChannelCollection, instance=True)
    task.timing = create_autospec(Timing, instance=True)
    task.in_stream = create_autospec(InStream, instance=True)
    chan = create_autospec(AIChannel, instance=True)
    chan.ai_dev_scaling_coeff = COEFF
    task.ai_channels.__getitem__.return_value = chan
    dev = Device(task, len(cfg.channels), int(cfg.rate_hz * cfg.buffer_s))
    unscaled = create_autospec(AnalogUnscaledReader)
    unscaled.return_value.read_int16.side_effect = dev.read
    scaled = create_autospec(AnalogMultiChannelReader)
    scaled.return_value.read_many_sample.side_effect = dev.read
    return task_cls, task, dev, unscaled, scaled


def _daq(cfg: DaqConfig, names=("Fx", "Fy", "Fz")):
    task_cls, task, dev, unscaled, scaled = _mock_nidaqmx(cfg)
    daq = NiDaq(cfg, names, clock=lambda: 100.0, task_factory=task_cls,
                unscaled_reader=unscaled, scaled_reader=scaled)  # fmt: skip
    return daq, task, dev, unscaled, scaled


def _callback(task):
    args = task.register_every_n_samples_acquired_into_buffer_event.call_args_list[0].args
    return args[1]


def test_task_configuration_uses_the_real_api(tmp_path: Path) -> None:
    cfg = _rig()
    daq, task, dev, unscaled, _ = _daq(cfg)
    rec = RunWriter(tmp_path / "run.h5", _raw_info(daq), flush_interval_s=0.1)
    daq.start(rec)
    assert task.ai_channels.add_ai_voltage_chan.call_args_list == [
        call(
            f"Dev1/ai{i}",
            name_to_assign_to_channel=n,
            terminal_config=TerminalConfiguration.DIFF,
            min_val=-10.0,
            max_val=10.0,
            units=VoltageUnits.VOLTS,
        )
        for i, n in enumerate(("Fx", "Fy", "Fz"))
    ]
    task.timing.cfg_samp_clk_timing.assert_called_once_with(
        10_000.0, sample_mode=AcquisitionType.CONTINUOUS, samps_per_chan=10_000
    )
    assert task.in_stream.over_write == OverwriteMode.OVERWRITE_UNREAD_SAMPLES
    assert task.in_stream.input_buf_size == 10_000
    unscaled.assert_called_once_with(task.in_stream)
    task.register_every_n_samples_acquired_into_buffer_event.assert_called_once()
    assert task.register_every_n_samples_acquired_into_buffer_event.call_args.args[0] == 1000
    task.start.assert_called_once_with()
    np.testing.assert_array_equal(daq.info.scaling_coeff, [COEFF] * 3)
    daq.close()
    rec.close()
    task.stop.assert_called_once_with()
    task.close.assert_called_once_with()


def _raw_info(daq: NiDaq):
    from rig.daq import DaqInfo

    return DaqInfo(
        device="Dev1",
        physical_channels=daq.info.physical_channels,
        channel_names=daq.info.channel_names,
        rate_hz=daq.info.rate_hz,
        sample_format="raw_int16",
        input_range_v=10.0,
        block_samples=daq.block_samples,
        scaling_coeff=np.array([COEFF] * 3),
    )


def test_continuous_blocks_overflow_and_stop_into_a_run_file(tmp_path: Path) -> None:
    """Every-N reads land in the file at their device index; an overflow is recovered with an
    exact count; stop drains the partial last block."""
    cfg = _rig()
    cal = Calibration.from_rig(load_rig())
    daq, task, dev, _, _ = _daq(cfg)
    w = RunWriter(tmp_path / "run.h5", _raw_info(daq), cal, flush_interval_s=0.1)
    daq.start(w)
    cb = _callback(task)
    for _ in range(5):  # 5 normal blocks
        dev.acquire(1000)
        assert cb(0, 1, 1000, None) == 0
    dev.acquire(12_500)  # the host stalls for 1.25 s: the 1 s buffer overwrote 2 500 samples
    assert cb(0, 1, 1000, None) == 0
    assert daq.samples_read == 17_500  # the late callback read every whole block waiting
    for _ in range(3):
        cb(0, 1, 1000, None)  # queued callbacks find nothing new: no read, no error
    assert daq.samples_read == 17_500
    dev.acquire(700)
    daq.stop()
    daq.close()
    w.close()
    assert daq.error is None
    run = rf.load_run(tmp_path / "run.h5")
    ov = run.events[run.events["kind"] == "overflow"]
    assert ov["sample"].tolist() == [5000]
    assert "-200279" in ov["message"].iloc[0]
    # Oldest sample still buffered was 17 500 - 10 000 = 7 500; one block of margin: 8 500.
    gap = run.events[run.events["kind"] == "gap"]
    assert gap[["sample", "lost"]].values.tolist() == [[5000, 3500]]
    assert run.samples_acquired == dev.acquired == 18_200
    expect = np.r_[0:5000, 8500:18_200]
    np.testing.assert_array_equal(run.sample_index, expect)
    for ch in range(3):
        np.testing.assert_array_equal(run.raw[:, ch], _code(expect, ch))
    x = run.raw.astype(float)
    np.testing.assert_allclose(run.volts, COEFF[0] + COEFF[1] * x + COEFF[2] * x**2)
    assert run.events["kind"].iloc[-1] == "stop"
    assert run.events["sample"].iloc[-1] == 18_200
    # The read position was restored after the recovery read.
    assert task.in_stream.relative_to == ReadRelativeTo.CURRENT_READ_POSITION
    assert task.in_stream.offset == 0
    # Stop unregistered the event before draining.
    last = task.register_every_n_samples_acquired_into_buffer_event.call_args
    assert last == call(1000, None)


def test_codes_at_the_adc_limits_are_a_saturation_event(tmp_path: Path) -> None:
    cfg = _rig()
    daq, task, dev, unscaled, _ = _daq(cfg)
    w = RunWriter(tmp_path / "s.h5", _raw_info(daq))
    daq.start(w)
    read = dev.read

    def clipped(data, number_of_samples_per_channel, timeout):
        got = read(data, number_of_samples_per_channel, timeout)
        data[1, 417:420] = 32767
        return got

    unscaled.return_value.read_int16.side_effect = clipped
    dev.acquire(2000)
    cb = _callback(task)
    cb(0, 1, 1000, None)
    cb(0, 1, 1000, None)
    daq.close()
    w.close()
    run = rf.load_run(tmp_path / "s.h5")
    sat = run.events[run.events["kind"] == "saturation"]
    assert sat["sample"].tolist() == [417, 1417]


def test_volts_mode_uses_the_multichannel_reader(tmp_path: Path) -> None:
    cfg = _rig(raw=False, channels=("Dev1/ai0", "Dev1/ai1"))
    daq, task, dev, unscaled, scaled = _daq(cfg, names=None)
    w = RunWriter(tmp_path / "v.h5", daq.info)
    daq.start(w)
    assert daq.info.sample_format == "volts_float64" and daq.info.scaling_coeff is None
    scaled.assert_called_once_with(task.in_stream)
    unscaled.assert_not_called()
    dev.acquire(1000)
    _callback(task)(0, 1, 1000, None)
    daq.close()
    w.close()
    run = rf.load_run(tmp_path / "v.h5")
    assert run.channel_names == ("Dev1/ai0", "Dev1/ai1")
    np.testing.assert_allclose(run.volts[:, 1], _code(np.arange(1000), 1) * 1e-3)


def test_other_daq_error_is_a_fault_not_a_crash(tmp_path: Path) -> None:
    cfg = _rig()
    daq, task, dev, unscaled, _ = _daq(cfg)
    w = RunWriter(tmp_path / "e.h5", _raw_info(daq))
    daq.start(w)
    unscaled.return_value.read_int16.side_effect = nidaqmx.errors.DaqError(
        "The specified resource is reserved.", -50103
    )
    dev.acquire(1000)
    assert _callback(task)(0, 1, 1000, None) == 0  # callbacks never raise into DAQmx
    assert daq.done and isinstance(daq.error, nidaqmx.errors.DaqError)
    daq.close()
    w.close("fail", str(daq.error))
    run = rf.load_run(tmp_path / "e.h5")
    assert (run.events["kind"] == "fault").sum() == 1 and run.status == "fail"


def test_driver_not_installed_says_what_to_do() -> None:
    def no_driver():
        raise nidaqmx.errors.DaqNotFoundError("Could not find an installation of NI-DAQmx.")

    # nidaqmx's driver-not-found error is not a DaqError: the driver must catch it by name.
    assert not issubclass(nidaqmx.errors.DaqNotFoundError, nidaqmx.errors.DaqError)
    daq = NiDaq(_rig(), task_factory=no_driver)
    with pytest.raises(DaqNotAvailableError) as exc:
        daq.start(None)  # type: ignore[arg-type]
    msg = str(exc.value)
    assert "NI-DAQmx driver not found" in msg and "configs/rig.toml" in msg and "--sim" in msg


def test_device_missing_says_what_to_do() -> None:
    cfg = _rig(device="Dev7", channels=("Dev7/ai0",))
    task_cls, task, dev, unscaled, scaled = _mock_nidaqmx(cfg)
    task.ai_channels.add_ai_voltage_chan.side_effect = nidaqmx.errors.DaqError(
        "Device identifier is invalid.", -200220
    )
    daq = NiDaq(cfg, task_factory=task_cls, unscaled_reader=unscaled)
    with pytest.raises(DaqNotAvailableError, match="NI device 'Dev7'.*not found.*-200220"):
        daq.start(None)  # type: ignore[arg-type]
    task.close.assert_called_once_with()


def test_channel_names_must_match() -> None:
    with pytest.raises(DaqError, match="2 channel names .* for 3 DAQ channels"):
        NiDaq(_rig(), ("Fx", "Fy"))


def test_from_rig_takes_the_command_overrides_and_the_calibration() -> None:
    """What `cutlab daq record` (no --sim) builds: --rate-hz and --channels over the config."""
    rig = load_rig()
    daq = NiDaq.from_rig(rig, rate_hz=5000.0, channels=len(rig.daq.channels))
    assert daq.config.rate_hz == 5000.0 and daq.info.channel_names == ("Fx", "Fy", "Fz")
    assert daq.calibration is not None and daq.run_clock is daq.clock
    assert daq.rig_meta == {"daq": daq.config.model_dump(), "dynamometer": rig.dynamometer.model,
                            "calibration_id": rig.dynamometer.calibration_id}  # fmt: skip
    assert NiDaq.from_rig(rig).config == rig.daq
    with pytest.raises(DaqError, match="--channels = 9: where.toml lists only 3 daq.channels"):
        NiDaq.from_rig(rig, channels=9, where="where.toml")


def test_real_nidaqmx_without_driver_is_reported() -> None:
    """On a machine without NI-DAQmx (CI) the real package's error becomes our clear one."""
    daq = NiDaq(_rig())
    try:
        daq.start(None)  # type: ignore[arg-type]
    except DaqNotAvailableError as exc:
        assert "NI-DAQmx" in str(exc)
    except DaqError:
        pytest.skip("an NI-DAQmx driver is installed here; see the hardware test")
    else:  # pragma: no cover - a device answered: nothing to check without a sink
        daq.close()
        pytest.skip("a device is present; see the hardware test")


@pytest.mark.hardware
def test_hardware_acquires_continuously(tmp_path: Path) -> None:
    """Needs NI-DAQmx and the device of configs/rig.toml (run: pytest -m hardware)."""
    rig = load_rig()
    daq = NiDaq(rig.daq, Calibration.from_rig(rig).channel_names)
    try:
        from rig.log import record

        res = record(daq, tmp_path / "hw.h5", 2.0, calibration=Calibration.from_rig(rig))
    except DaqNotAvailableError as exc:
        pytest.skip(
            f"no NI hardware: {exc} -- to run this test install NI-DAQmx, connect the device "
            "named in configs/rig.toml [daq] and run `pytest -m hardware tests/test_daq_ni.py`"
        )
    run = rf.load_run(res.path)
    assert run.samples_lost == 0 and run.samples_acquired >= 2 * rig.daq.rate_hz - 1
