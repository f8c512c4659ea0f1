"""RunWriter: real HDF5 files, queue overflow, gaps, NC blocks from many threads, crash safety."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis.config import load_rig
from analysis.runs import RunFollower
from analysis.runs import file as rf
from rig.cli import main
from rig.daq import Calibration, DaqEvent, DaqInfo
from rig.log import RunWriter, RunWriterError

ROOT = Path(__file__).resolve().parent.parent
B = 500  # samples per block


def _info(fmt: str = "volts_float64", c: int = 3) -> DaqInfo:
    coeff = None
    if fmt == "raw_int16":
        coeff = np.zeros((c, 4))
        coeff[:, 0] = 0.001 * np.arange(c)
        coeff[:, 1] = 10.0 / 32768
    return DaqInfo(
        device="test",
        physical_channels=tuple(f"t/ai{i}" for i in range(c)),
        channel_names=tuple(f"ch{i}" for i in range(c)),
        rate_hz=1000.0,
        sample_format=fmt,
        input_range_v=10.0,
        block_samples=B,
        scaling_coeff=coeff,
    )


def _block(first: int, n: int = B, c: int = 3) -> np.ndarray:
    """Value = device index + channel / 10: any reorder or splice shows."""
    return (first + np.arange(n))[None, :] + np.arange(c)[:, None] / 10.0


def _expected(sample_index: np.ndarray, c: int = 3) -> np.ndarray:
    return sample_index[:, None] + np.arange(c)[None, :] / 10.0


def test_round_trip_with_metadata(tmp_path: Path) -> None:
    cal = Calibration.from_rig(load_rig())
    info = _info()
    p = tmp_path / "run.h5"
    with RunWriter(p, info, cal, clock=lambda: 10.0, flush_interval_s=0.1) as w:
        w.set_conditions({"tool": "phi10-flat", "spindle_rpm": 2000, "feed_mm_min": 300.0})
        w.set_rig({"device": "test", "dynamometer": "Kistler 9257B"})
        w.set_program("%\nG0 X0\nG1 X10 F300\n%\n", "part.nc")
        w.on_start(info, 10.0)
        for k in range(7):
            w.on_block(k * B, _block(k * B))
        w.on_event(DaqEvent(rf.EV_STOP, 7 * B, "stopped"))
    run = rf.load_run(p)
    assert run.complete and run.status == "success"
    assert run.samples_stored == run.samples_acquired == 7 * B
    np.testing.assert_array_equal(run.volts, _expected(np.arange(7 * B)))
    np.testing.assert_allclose(run.time_s, 10.0 + np.arange(7 * B) / 1000.0)
    assert run.channel_names == ("Fx", "Fy", "Fz")
    np.testing.assert_allclose(run.force_n, cal.force_from_volts(run.volts))
    assert run.conditions["feed_mm_min"] == 300.0
    assert run.program_info["sha256"] and run.program_info["name"] == "part.nc"
    assert run.program_text.startswith("%\nG0")
    assert run.software_version
    assert list(run.events["kind"]) == ["start", "stop"]
    assert run.events["sample"].tolist() == [0, 7 * B]
    df = run.forces()
    assert list(df.columns) == ["Fx", "Fy", "Fz"] and df.index.name == "time_s"


def test_raw_codes_and_scaling_are_kept(tmp_path: Path) -> None:
    info = _info("raw_int16")
    p = tmp_path / "raw.h5"
    codes = np.array([[-32768, -1, 0, 1, 32767]] * 3, dtype=np.int16)
    with RunWriter(p, info) as w:
        w.on_start(info, 0.0)
        w.on_block(0, codes)
    run = rf.load_run(p)
    np.testing.assert_array_equal(run.raw, codes.T)
    np.testing.assert_array_equal(run.scaling_coeff, info.scaling_coeff)
    lsb = 10.0 / 32768
    np.testing.assert_allclose(run.volts, codes.T * lsb + 0.001 * np.arange(3))
    assert run.force_n is None  # no calibration given


def test_full_queue_is_an_event_with_exact_samples(tmp_path: Path) -> None:
    info = _info()
    p = tmp_path / "q.h5"
    w = RunWriter(p, info, queue_blocks=2, flush_interval_s=0.1)
    w.on_start(info, 0.0)
    with w.hold():  # the disk "stalls": two blocks fit in the queue, three are dropped
        for k in range(5):
            w.on_block(k * B, _block(k * B))
    assert w.wait_idle()
    for k in range(5, 8):
        w.on_block(k * B, _block(k * B))
        assert w.wait_idle()  # the disk keeps up again
    stats = w.close()
    assert stats.blocks_dropped == 3 and stats.samples_dropped == 3 * B
    run = rf.load_run(p)
    q = run.events[run.events["kind"] == "queue_full"]
    assert len(q) == 1  # consecutive drops coalesce
    assert int(q["sample"].iloc[0]) == 2 * B and int(q["lost"].iloc[0]) == 3 * B
    assert run.samples_stored == 5 * B and run.samples_acquired == 8 * B
    expect_idx = np.r_[0 : 2 * B, 5 * B : 8 * B]
    np.testing.assert_array_equal(run.sample_index, expect_idx)
    np.testing.assert_array_equal(run.volts, _expected(expect_idx))


def test_gap_in_device_samples_is_recorded(tmp_path: Path) -> None:
    info = _info()
    p = tmp_path / "g.h5"
    with RunWriter(p, info) as w:
        w.on_start(info, 0.0)
        w.on_block(0, _block(0))
        w.on_block(B + 123, _block(B + 123))  # 123 samples never arrived
        w.on_block(2 * B + 123, _block(2 * B + 123, 77))
        w.on_block(100, _block(100, 10))  # overlap: dropped as a fault, never spliced in
    run = rf.load_run(p)
    gap = run.events[run.events["kind"] == "gap"]
    assert gap[["sample", "lost"]].values.tolist() == [[B, 123]]
    assert (run.events["kind"] == "fault").sum() == 1
    idx = np.r_[0:B, B + 123 : 2 * B + 123 + 77]
    np.testing.assert_array_equal(run.sample_index, idx)
    np.testing.assert_array_equal(run.volts, _expected(idx))
    assert run.samples_lost == 123


def test_blocks_from_many_threads(tmp_path: Path) -> None:
    info = _info()
    p = tmp_path / "b.h5"
    w = RunWriter(p, info, clock=lambda: 1.5, flush_interval_s=0.05)
    w.on_start(info, 1.0)

    def stream(t: int) -> None:
        for i in range(50):
            b = t * 1000 + i
            w.append_blocks(b, i + 1, f"N{b} G1 X{i}.5 F300", send_s=1.0 + i * 1e-3)
            w.ack_blocks(b, 2.0 + i * 1e-3)

    threads = [threading.Thread(target=stream, args=(t,)) for t in range(4)]
    for th in threads:
        th.start()
    for k in range(6):
        w.on_block(k * B, _block(k * B))
    for th in threads:
        th.join()
    w.append_blocks([9000, 9001], [1, 2], ["X" * 300, "M30"], [3.0, 3.1])
    w.event("interlock", "door opened", time_s=2.5)
    w.close("abort", "operator stop")
    run = rf.load_run(p)
    bl = run.blocks
    assert len(bl) == 202
    assert sorted(bl["block"])[:200] == sorted(t * 1000 + i for t in range(4) for i in range(50))
    for r in bl[bl["block"] < 9000].itertuples():
        i = r.block % 1000
        assert r.text == f"N{r.block} G1 X{i}.5 F300" and r.line == i + 1
        assert r.ack_s == pytest.approx(2.0 + i * 1e-3)
    assert np.isnan(bl[bl["block"] == 9001]["ack_s"]).all()
    assert bl[bl["block"] == 9000]["text"].iloc[0] == "X" * rf.BLOCK_TEXT_BYTES
    notes = run.events[run.events["kind"] == "note"]
    assert notes["message"].str.contains("300 bytes").any()  # truncation is not silent
    il = run.events[run.events["kind"] == "interlock"].iloc[0]
    assert il["sample"] == 1500 and il["message"] == "door opened"  # (2.5 - t0 1.0) * 1000 Hz
    assert run.status == "abort" and run.reason == "operator stop" and run.complete


def test_exception_in_context_marks_fail(tmp_path: Path) -> None:
    info = _info()
    p = tmp_path / "f.h5"
    with pytest.raises(ZeroDivisionError):
        with RunWriter(p, info) as w:
            w.on_start(info, 0.0)
            w.on_block(0, _block(0))
            1 / 0  # noqa: B018
    run = rf.load_run(p)
    assert run.status == "fail" and "ZeroDivisionError" in run.reason
    assert run.samples_stored == B


def test_calibration_update_is_stored(tmp_path: Path) -> None:
    cal = Calibration.from_rig(load_rig())
    info = _info()
    p = tmp_path / "c.h5"
    with RunWriter(p, info, cal) as w:
        w.on_start(info, 0.0)
        v = np.full((3, B), 0.25)
        w.on_block(0, v)
        w.set_calibration(cal.zeroed(v.T, time_s=0.0).with_drift(np.zeros(3)))
    run = rf.load_run(p)
    np.testing.assert_allclose(run.force_n, 0.0, atol=1e-12)
    assert (run.events["kind"] == "zero").sum() == 1


def test_writer_refuses_bad_setup(tmp_path: Path) -> None:
    p = tmp_path / "x.h5"
    p.write_bytes(b"keep me")
    with pytest.raises(RunWriterError, match="file exists"):
        RunWriter(p, _info())
    assert p.read_bytes() == b"keep me"
    cal = Calibration.from_rig(load_rig())
    with pytest.raises(RunWriterError, match="calibration has 3 channels .* the DAQ task has 4"):
        RunWriter(tmp_path / "y.h5", _info(c=4), cal)
    w = RunWriter(tmp_path / "z.h5", _info())
    with pytest.raises(RunWriterError, match="event kind 'bogus'"):
        w.event("bogus")
    with pytest.raises(RunWriterError, match="status 'running'"):
        w.close("running")
    w.close()


def test_follower_reads_while_writing(tmp_path: Path) -> None:
    info = _info()
    p = tmp_path / "live.h5"
    w = RunWriter(p, info, flush_interval_s=0.05)
    w.on_start(info, 0.0)
    got: list[np.ndarray] = []
    with RunFollower(p) as fol:
        for k in range(6):
            w.on_block(k * B, _block(k * B))
            deadline = time.monotonic() + 10.0
            while sum(len(g) for g in got) < (k + 1) * B and time.monotonic() < deadline:
                first, volts, _ = fol.poll()
                assert first == sum(len(g) for g in got)
                if len(volts):
                    got.append(volts)
            assert not fol.finished
        w.close()
        fol.poll()
        assert fol.finished
    np.testing.assert_array_equal(np.concatenate(got), _expected(np.arange(6 * B)))


_RECORDER = """
import sys
from rig.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.long
def test_sigkill_mid_recording_keeps_everything_flushed(tmp_path: Path, capsys) -> None:
    """A recorder killed with SIGKILL leaves a file that opens, holds every flushed sample, and
    `data info` says how far it got."""
    out = tmp_path / "killed.h5"
    args = ["daq", "record", "--sim", "--seconds", "120", "--rate-hz", "5000", "--flush-s",
            "0.2", "--sim-noise-v", "0", "--quiet", "-o", str(out)]  # fmt: skip
    proc = subprocess.Popen(
        [sys.executable, "-c", _RECORDER, *args],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        seen = 0
        deadline = time.monotonic() + 60.0
        while seen < 2500 and time.monotonic() < deadline:  # >= 0.5 s flushed (>= 2 flushes)
            try:  # a bounded wait on the recorder's exit between looks at the file
                proc.wait(timeout=0.05)
                pytest.fail(f"recorder exited early: {proc.stderr.read().decode()}")
            except subprocess.TimeoutExpired:
                pass
            if out.exists():
                try:
                    with RunFollower(out) as fol:
                        first, volts, _ = fol.poll()
                        seen = first + len(volts)
                except (rf.RunFileError, OSError, KeyError):
                    pass  # file still being created
        assert seen >= 2500, "recorder did not flush 0.5 s of samples within 60 s"
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    import h5py

    with pytest.raises(OSError, match="already open for write"):
        h5py.File(out, "r")  # what HDF5 leaves: plain h5py and HDFView refuse the file
    run = rf.load_run(out)  # ... until the first read repairs it
    assert not run.complete and run.status == "interrupted"
    assert f"{run.samples_stored} samples per channel kept" in run.reason
    with h5py.File(out, "r") as f:
        assert f[rf.VOLTS].shape[0] == run.samples_stored
    assert [q.name for q in tmp_path.iterdir()] == ["killed.h5"]  # no copy or .bak left
    assert run.samples_stored >= seen  # everything flushed before the kill is there
    assert run.samples_lost == 0
    np.testing.assert_array_equal(run.sample_index, np.arange(run.samples_stored))
    # Every stored sample is the source's value at its time: nothing torn or shifted.
    from rig.log.record import milling_force_source

    cal = Calibration.from_rig(load_rig())
    expect = milling_force_source(cal, 3)(run.t0_s, run.samples_stored, 5000.0).T
    np.testing.assert_allclose(run.volts, expect, atol=1e-12)
    assert main(["data", "info", str(out), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["complete"] is False and s["status"] == "interrupted"
    assert s["samples_stored"] == run.samples_stored
    assert s["duration_s"] == pytest.approx(run.samples_stored / 5000.0)
    assert main(["data", "info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "INCOMPLETE" in text and f"{run.samples_stored} samples per channel" in text


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    st.lists(
        st.tuples(st.integers(1, 3 * B), st.integers(0, 400), st.booleans()),
        min_size=1,
        max_size=10,
    )
)
def test_any_delivery_pattern_round_trips(tmp_path: Path, pattern) -> None:
    """Whatever block lengths, holes and stalls the DAQ produces, the file holds exactly the
    delivered samples at their device indices and accounts for every missing one."""
    info = _info()
    p = tmp_path / "prop.h5"
    p.unlink(missing_ok=True)
    w = RunWriter(p, info, queue_blocks=3, flush_interval_s=0.05)
    w.on_start(info, 0.0)
    dev, kept = 0, []
    for n, hole, stall in pattern:
        dev += hole
        if stall:
            with w.hold():  # 3 fit, the rest of a burst of 5 is dropped
                for _ in range(5):
                    w.on_block(dev, _block(dev, n))
                    dev += n
            # What was queued is what the pool could hold: the first 3 of the burst.
            kept.extend(np.arange(dev - (5 - j) * n, dev - (4 - j) * n) for j in range(3))
            assert w.wait_idle()
        else:
            w.on_block(dev, _block(dev, n))
            kept.append(np.arange(dev, dev + n))
            assert w.wait_idle()
            dev += n
    w.on_event(DaqEvent(rf.EV_STOP, dev, "stop"))
    w.close()
    run = rf.load_run(p)
    idx = np.concatenate(kept)
    np.testing.assert_array_equal(run.sample_index, idx)
    np.testing.assert_array_equal(run.volts, _expected(idx))
    assert run.samples_acquired == dev
    assert run.samples_lost == dev - len(idx)


def test_forces_are_tied_to_the_executing_block_not_the_acknowledged_one(tmp_path) -> None:
    # GRBL acknowledges blocks when it plans them: block 1 is acked at 0.1 s but starts cutting at
    # 2.0 s; block 0 cuts from 0.5 s. A sample at 1.0 s belongs to block 0, at 2.5 s to block 1.
    path = tmp_path / "run.h5"
    with RunWriter(path, _info()) as w:
        w.append_blocks([0, 1], [3, 4], ["G1 X10 F100", "G1 X20"], [0.0, 0.05], [0.05, 0.1],
                        exec_s=[0.5, 2.0])  # fmt: skip
    run = rf.load_run(path, samples=False)
    assert list(run.blocks["exec_s"]) == [0.5, 2.0]
    assert list(run.executing_block(np.array([0.2, 1.0, 2.5]))) == [-1, 0, 1]
