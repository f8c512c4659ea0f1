"""Simulated DAQ: delivery through the sink path, injected faults with exact sample indices."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

from analysis.runs import file as rf
from rig.daq import DaqError, DaqEvent, DaqInfo
from rig.log import RunWriter
from rig.sim import SimClock
from rig.sim.daq import PushedSource, SimDaq, ramp_source, sine_source


class Recorder:
    """A DaqSink that keeps copies of everything (checks the sink contract directly)."""

    def __init__(self) -> None:
        self.blocks: list[tuple[int, np.ndarray]] = []
        self.events: list[DaqEvent] = []
        self.t0_s = None

    def on_start(self, info: DaqInfo, t0_s: float) -> None:
        self.t0_s = t0_s

    def on_block(self, first_sample: int, data: np.ndarray) -> None:
        self.blocks.append((first_sample, data.copy()))

    def on_event(self, event: DaqEvent) -> None:
        self.events.append(event)


def _record(tmp_path: Path, daq: SimDaq, name: str = "run.h5") -> rf.Run:
    p = tmp_path / name
    w = RunWriter(p, daq.info, flush_interval_s=0.1)
    daq.run(w, timeout_s=60)
    w.close()
    return rf.load_run(p)


def test_blocks_in_order_with_exact_values() -> None:
    rec = Recorder()
    daq = SimDaq(ramp_source(3, 1.0), rate_hz=1000.0, seconds=1.05, read_interval_s=0.1)
    daq.run(rec)
    firsts = [b[0] for b in rec.blocks]
    assert firsts == list(range(0, 1100, 100))
    assert [b[1].shape for b in rec.blocks][-1] == (3, 50)  # the last block is the remainder
    data = np.concatenate([b[1] for b in rec.blocks], axis=1)
    t = np.arange(1050) / 1000.0
    np.testing.assert_allclose(data, np.outer([1.0, 2.0, 3.0], t))
    assert rec.events[-1].kind == "stop" and rec.events[-1].sample == 1050


def test_injected_overflow_has_exact_indices(tmp_path: Path) -> None:
    daq = SimDaq(
        ramp_source(3, 1.0),
        rate_hz=2000.0,
        seconds=2.0,
        read_interval_s=0.05,
        sim_overflow_at=[1234, 3001],
        sim_overflow_samples=321,
    )
    run = _record(tmp_path, daq)
    ov = run.events[run.events["kind"] == "overflow"]
    assert ov["sample"].tolist() == [1234, 3001]
    gaps = run.events[run.events["kind"] == "gap"]
    assert gaps[["sample", "lost"]].values.tolist() == [[1234, 321], [3001, 321]]
    expect = np.r_[0:1234, 1555:3001, 3322:4000]
    np.testing.assert_array_equal(run.sample_index, expect)
    np.testing.assert_allclose(run.volts[:, 0], expect / 2000.0, atol=1e-12)
    assert run.samples_acquired == 4000 and run.samples_lost == 642


def test_silently_dropped_block_is_caught_by_the_logger(tmp_path: Path) -> None:
    daq = SimDaq(ramp_source(2, 1.0), rate_hz=1000.0, channels=("a", "b"), seconds=1.0,
                 read_interval_s=0.1, sim_drop_blocks=[3, 4, 9])  # fmt: skip
    run = _record(tmp_path, daq)
    gaps = run.events[run.events["kind"] == "gap"]
    # The last block is missing too: the stop event's sample count gives it away.
    assert gaps[["sample", "lost"]].values.tolist() == [[300, 200], [900, 100]]
    assert (run.events["kind"] == "overflow").sum() == 0  # the DAQ itself said nothing
    assert run.samples_stored == 700 and run.sample_index[-1] == 899
    assert run.samples_acquired == 1000 and run.samples_lost == 300


def test_saturation_drift_offset_noise() -> None:
    rec = Recorder()
    daq = SimDaq(
        sine_source(amplitude_v=[12.0, 0.0, 0.0], frequency_hz=1.0, channels=3),
        rate_hz=1000.0,
        seconds=1.0,
        input_range_v=10.0,
        sim_drift_v_s=[0.0, 0.5, 0.0],
        sim_offset_v=[0.0, 0.1, 0.0],
        sim_noise_v=0.01,
        sim_seed=5,
    )
    daq.run(rec)
    data = np.concatenate([b[1] for b in rec.blocks], axis=1)
    t = np.arange(1000) / 1000.0
    assert data[0].max() == 10.0 and data[0].min() == -10.0  # clipped at the range
    sat = [e for e in rec.events if e.kind == "saturation"]
    first_over = int(np.argmax(12.0 * np.sin(2 * np.pi * t) > 10.0))
    assert sat[0].sample == first_over
    resid = data[1] - (0.1 + 0.5 * t)
    assert abs(resid.mean()) < 2e-3 and 0.008 < resid.std() < 0.012
    np.testing.assert_allclose(data[2].std(), 0.01, rtol=0.1)


def test_raw_codes_of_an_ideal_adc(tmp_path: Path) -> None:
    daq = SimDaq(ramp_source(3, 2.0), rate_hz=1000.0, seconds=1.0, sample_format="raw_int16")
    run = _record(tmp_path, daq)
    assert run.raw.dtype == np.int16
    lsb = 10.0 / 32768
    np.testing.assert_allclose(run.volts, np.outer(run.time_s, [2.0, 4.0, 6.0]), atol=lsb / 2)


def test_real_time_on_the_shared_clock(tmp_path: Path) -> None:
    clock = SimClock(speed=20.0)
    daq = SimDaq(ramp_source(3, 1.0), rate_hz=1000.0, seconds=1.0, clock=clock)
    run = _record(tmp_path, daq)
    assert run.samples_stored == 1000
    assert clock.now() >= run.t0_s + 1.0  # blocks never come before their time
    np.testing.assert_allclose(run.volts[:, 0], run.time_s, atol=1e-12)


def test_stop_mid_run_is_clean() -> None:
    rec = Recorder()
    clock = SimClock(speed=10.0)
    daq = SimDaq(ramp_source(3, 1.0), rate_hz=1000.0, clock=clock)
    got = threading.Event()
    orig = rec.on_block

    def on_block(first: int, data: np.ndarray) -> None:
        orig(first, data)
        if first >= 300:
            got.set()

    rec.on_block = on_block  # type: ignore[method-assign]
    daq.start(rec)
    assert got.wait(30)
    daq.stop()
    delivered = sum(b[1].shape[1] for b in rec.blocks)
    assert rec.events[-1].kind == "stop" and rec.events[-1].sample == delivered
    assert daq.done


def test_pushed_source() -> None:
    src = PushedSource(2)
    src.push(np.ones((2, 150)))
    src.push(2 * np.ones((2, 30)))
    out = src(0.0, 200, 1000.0)
    np.testing.assert_array_equal(out[:, :150], 1.0)
    np.testing.assert_array_equal(out[:, 150:180], 2.0)
    np.testing.assert_array_equal(out[:, 180:], 0.0)
    assert src.underrun_samples == 20
    with pytest.raises(DaqError, match=r"expected \(2, n\)"):
        src.push(np.ones((3, 5)))


def test_bad_source_shape_is_a_fault() -> None:
    rec = Recorder()
    daq = SimDaq(lambda t0, n, r: np.zeros((2, n)), rate_hz=100.0, seconds=1.0)
    with pytest.raises(DaqError, match=r"source returned shape \(2, 10\): expected \(3, 10\)"):
        daq.run(rec)
    assert [e.kind for e in rec.events] == ["fault", "stop"]
