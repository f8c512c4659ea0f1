"""Recording that survives its medium: no room to start, the disk running low during a run, a
write error (injected ENOSPC, and a real EFBIG from a file-size limit), a killed writer's file.

Every case ends with a run file plain h5py opens, holding every flushed sample with its value, and
a status that says what happened. A really full file system cannot be made without root (no
mount, no loop device), so the OS-level write error comes from RLIMIT_FSIZE instead: the kernel
refuses the write (EFBIG) exactly where a full disk would refuse it (ENOSPC).
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from analysis.runs import file as rf
from rig.daq import DaqEvent, DaqInfo
from rig.errors import RigError
from rig.log import RunWriter, RunWriterError, plan_recording
from rig.log import space as space_mod

pytestmark = pytest.mark.faults
ROOT = Path(__file__).resolve().parent.parent
B = 500


def _info() -> DaqInfo:
    return DaqInfo(
        device="t", physical_channels=("t/ai0", "t/ai1"), channel_names=("a", "b"),
        rate_hz=1000.0, sample_format="volts_float64", input_range_v=10.0, block_samples=B,
    )  # fmt: skip


def _block(first: int, n: int = B) -> np.ndarray:
    """Value = device index (+ 0.5 on the second channel): any loss or shift shows."""
    return (first + np.arange(n))[None, :] + np.array([[0.0], [0.5]])


def _assert_prefix(run: rf.Run) -> None:
    idx = np.arange(run.samples_stored)
    np.testing.assert_array_equal(run.volts, idx[:, None] + np.array([0.0, 0.5]))


def test_injected_enospc_ends_the_run_failed_with_every_flushed_sample(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    p = tmp_path / "full.h5"
    take = RunWriter._take
    calls = [0]

    def disk_full_after_six(self, item) -> None:  # noqa: ANN001
        calls[0] += 1
        if calls[0] > 6:
            raise OSError(errno.ENOSPC, "No space left on device")
        take(self, item)

    monkeypatch.setattr(RunWriter, "_take", disk_full_after_six)
    info = _info()
    w = RunWriter(p, info, flush_interval_s=1e-3)
    w.on_start(info, 0.0)
    for k in range(6):
        w.on_block(k * B, _block(k * B))
        assert w.wait_idle()
    time.sleep(0.2)  # idle: the writer flushes (every 1 ms at most)
    flushed_before = w.stats().samples_written
    for k in range(6, 10):
        w.on_block(k * B, _block(k * B))
    w.wait_idle()
    assert w.failure is not None and "No space left on device (ENOSPC)" in w.failure
    w.close(rf.STATUS_FAIL, w.failure)  # what a run does once it sees the failure
    with h5py.File(p, "r") as f:  # plain h5py opens it
        assert f[rf.VOLTS].shape[0] == flushed_before == 6 * B
    run = rf.load_run(p)
    assert run.status == "fail" and "ENOSPC" in run.reason and run.complete
    _assert_prefix(run)
    assert (run.events["kind"] == "fault").any()
    assert sorted(q.name for q in tmp_path.iterdir()) == ["full.h5"]  # no copy or .bak left


def test_a_caller_that_does_not_notice_a_write_error_is_told(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(self, item) -> None:  # noqa: ANN001
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(RunWriter, "_take", broken)
    info = _info()
    w = RunWriter(tmp_path / "eio.h5", info)
    w.on_start(info, 0.0)
    w.on_block(0, _block(0))
    w.wait_idle()
    with pytest.raises(RunWriterError, match=r"Input/output error \(EIO\)"):
        w.close()
    run = rf.load_run(tmp_path / "eio.h5")
    assert run.status == "fail" and "EIO" in run.reason and run.samples_stored == 0


def test_disk_running_low_stops_recording_cleanly_before_it_is_full(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    free = [10**9]
    monkeypatch.setattr(space_mod, "free_bytes", lambda folder: free[0])
    info = _info()
    p = tmp_path / "low.h5"
    w = RunWriter(p, info, flush_interval_s=1e-3, min_free_mb=64)
    w.on_start(info, 0.0)
    for k in range(4):
        w.on_block(k * B, _block(k * B))
        assert w.wait_idle()
    free[0] = 50 * 10**6  # 50 MB left: below the 64 MB margin, seen at the next flush
    deadline = time.monotonic() + 5
    while w.failure is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert w.failure is not None
    assert "disk nearly full" in w.failure and "50000000 free bytes (50 MB free)" in w.failure
    assert "below the 64 MB margin: recording stopped at sample 2000" in w.failure
    assert str(tmp_path) in w.failure
    for k in range(4, 8):  # the DAQ goes on delivering; nothing more is written
        w.on_block(k * B, _block(k * B))
    w.on_event(DaqEvent(rf.EV_STOP, 8 * B, "stop"))
    with pytest.raises(RunWriterError, match="below the 64 MB margin"):
        w.close()  # closed as success: the writer says it was not
    run = rf.load_run(p)
    assert run.complete and run.status == "fail" and "64 MB margin" in run.reason
    assert run.samples_stored == 4 * B
    _assert_prefix(run)
    faults = run.events[run.events["kind"] == "fault"]
    assert len(faults) == 1 and "recording stopped" in faults["message"].iloc[0]


def test_recording_without_room_does_not_start(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(space_mod, "free_bytes", lambda folder: 70 * 10**6)
    # 60 s x 20 kHz x 3 channels x 8 B = 28.8 MB (float64 bound) + 64 MB margin > 70 MB free
    with pytest.raises(RigError) as e:
        plan_recording(None, tmp_path / "r.h5", 60.0, rate_hz=20000)
    msg = str(e.value)
    assert str(tmp_path) in msg and "70 MB free" in msg and "29 MB" in msg and "64 MB" in msg
    assert not (tmp_path / "r.h5").exists()
    plan_recording(None, tmp_path / "r.h5", 10.0, rate_hz=20000)  # 4.8 MB + 64 MB fits


_EFBIG = """
import resource, signal, sys, time
import numpy as np
sys.path.insert(0, {root!r})
from rig.daq import DaqInfo
from rig.log import RunWriter
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # the write fails with EFBIG instead
resource.setrlimit(resource.RLIMIT_FSIZE, (6_000_000, 6_000_000))
info = DaqInfo(device="t", physical_channels=("a", "b"), channel_names=("a", "b"),
               rate_hz=10000.0, sample_format="volts_float64", input_range_v=10.0,
               block_samples=1000)
w = RunWriter(sys.argv[1], info, flush_interval_s=0.02, min_free_mb=0)
w.on_start(info, 0.0)
k = 0
while w.failure is None and k < 1000:
    w.put_block(k * 1000, (k * 1000 + np.arange(1000))[None, :] + np.array([[0.0], [0.5]]))
    k += 1
    time.sleep(0.002)
w.close("fail", w.failure or "no failure")
print(w.failure)
"""


def test_a_file_size_limit_ends_failed_without_a_crash(tmp_path: Path) -> None:
    """HDF5 cannot close a file it failed to write and crashed the process at exit (rc 139):
    now the writer stops before the limit (ulimit -f) is reached, the process ends normally and
    the file holds every sample it was handed before the stop, status fail."""
    p = tmp_path / "limit.h5"
    res = subprocess.run(
        [sys.executable, "-c", _EFBIG.format(root=str(ROOT)), str(p)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-2000:]
    assert "file size limit reached" in res.stdout and "RLIMIT_FSIZE" in res.stdout
    with h5py.File(p, "r") as f:
        status = json.loads(rf.decode_text(f[rf.meta_path(rf.META_STATUS)]))
    assert status["status"] == "fail" and "file size limit" in status["reason"]
    assert p.stat().st_size <= 6_000_000
    run = rf.load_run(p)
    stopped_at = int(re.search(r"stopped at sample (\d+)", status["reason"])[1])
    # 2 channels x 8 B: 6 MB holds at most 375 k samples; 2 MiB of it stay for a chunk and
    # the close, so at least 150 k samples (several flushes) got there.
    assert 150_000 <= run.samples_stored == stopped_at < 375_000
    _assert_prefix(run)


_KILLED = """
import os, sys, time
import numpy as np
sys.path.insert(0, {root!r})
from rig.daq import DaqInfo
from rig.log import RunWriter
info = DaqInfo(device="t", physical_channels=("a", "b"), channel_names=("a", "b"),
               rate_hz=1000.0, sample_format="volts_float64", input_range_v=10.0,
               block_samples=500)
w = RunWriter(sys.argv[1], info, flush_interval_s=0.01)
w.on_start(info, 0.0)
for k in range(8):
    w.on_block(k * 500, (k * 500 + np.arange(500))[None, :] + np.array([[0.0], [0.5]]))
w.wait_idle()
time.sleep(0.2)  # flushed
for k in range(8, 11):  # written, maybe not flushed
    w.on_block(k * 500, (k * 500 + np.arange(500))[None, :] + np.array([[0.0], [0.5]]))
os.kill(os.getpid(), 9)
"""


@pytest.mark.long
def test_killed_writer_file_is_repaired_on_first_read_and_reads_interrupted(
    tmp_path: Path,
) -> None:
    p = tmp_path / "killed.h5"
    res = subprocess.run([sys.executable, "-c", _KILLED.format(root=str(ROOT)), str(p)],
                         capture_output=True, timeout=60)  # fmt: skip
    assert res.returncode == -9
    with pytest.raises(OSError, match="already open for write"):
        h5py.File(p, "r")
    before = rf.load_run(p, repair=False)  # read as it is (SWMR), not changed
    assert before.status == "interrupted" and before.samples_stored >= 8 * 500
    with pytest.raises(OSError, match="already open for write"):
        h5py.File(p, "r")
    run = rf.load_run(p)
    assert run.status == "interrupted" and not run.complete
    assert run.samples_stored == before.samples_stored
    assert f"{run.samples_stored} samples per channel kept" in run.reason
    _assert_prefix(run)
    with h5py.File(p, "r") as f:
        assert f[rf.VOLTS].shape == (run.samples_stored, 2)
    assert rf.load_run(p).samples_stored == run.samples_stored  # a second read: as it was
    # Read-only folder: nothing can be rewritten, the run still reads interrupted.
    p2 = tmp_path / "ro" / "killed.h5"
    p2.parent.mkdir()
    subprocess.run([sys.executable, "-c", _KILLED.format(root=str(ROOT)), str(p2)],
                   capture_output=True, timeout=60)  # fmt: skip
    p2.parent.chmod(0o555)
    try:
        assert rf.load_run(p2).status == "interrupted"
    finally:
        p2.parent.chmod(0o755)


def test_live_writer_file_is_never_repaired(tmp_path: Path) -> None:
    info = _info()
    p = tmp_path / "live.h5"
    w = RunWriter(p, info, flush_interval_s=1e-3)
    w.on_start(info, 0.0)
    w.on_block(0, _block(0))
    assert w.wait_idle()
    run = rf.load_run(p)
    assert run.status == "running" and not rf.repair_run(p)
    w.on_block(B, _block(B))
    w.close()
    assert rf.load_run(p).status == "success" and rf.load_run(p).samples_stored == 2 * B


def test_reader_stops_at_the_last_flush_not_the_extent() -> None:
    """The reader of a running file reads no further than /forces/flushed (the extent can be
    ahead of it, with zeros): checked on a file written by hand."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "h.h5"
        info = _info()
        w = RunWriter(p, info, flush_interval_s=1e-3)
        w.on_start(info, 0.0)
        w.on_block(0, _block(0))
        assert w.wait_idle()
        w.close()
        with h5py.File(p, "r+") as f:  # as a killed writer leaves it: extent past the flush
            f[rf.VOLTS].resize((3 * B, 2))
            f[rf.FLUSHED][0] = B
            text = json.dumps({"status": "running"}).encode()
            st = f[rf.meta_path(rf.META_STATUS)]
            st.resize((len(text),))
            st[:] = np.frombuffer(text, np.uint8)
        run = rf.load_run(p)
        assert run.status == "interrupted" and run.samples_stored == B
        _assert_prefix(run)


_MID_REPAIR = """
import os, sys, time
sys.path.insert(0, {root!r})
from analysis.runs import file as rf
def hold(src, dst):  # the repair stops between its .bak link and its rename: killed here
    time.sleep(60)
os.replace = hold  # the repair calls os.replace
rf.load_run(sys.argv[1])
"""


@pytest.fixture(scope="module")
def killed_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One killed writer's file (still marked open for writing), copied by each test."""
    p = tmp_path_factory.mktemp("killed") / "killed.h5"
    res = subprocess.run([sys.executable, "-c", _KILLED.format(root=str(ROOT)), str(p)],
                         capture_output=True, timeout=60)  # fmt: skip
    assert res.returncode == -9
    return p


def _killed_run(p: Path, killed: Path) -> None:
    shutil.copyfile(killed, p)


def test_a_repair_killed_mid_way_leaves_nothing_after_the_next_read(
    tmp_path: Path, killed_file: Path
) -> None:
    """Issue 31 item 5: `data info` SIGKILLed while it repaired a killed run left
    .NAME.repair-PID and NAME.bak-PID for good; the next read now removes them."""
    p = tmp_path / "killed.h5"
    _killed_run(p, killed_file)
    child = subprocess.Popen([sys.executable, "-c", _MID_REPAIR.format(root=str(ROOT)), str(p)])
    tmp, bak = tmp_path / f".killed.h5.repair-{child.pid}", tmp_path / f"killed.h5.bak-{child.pid}"
    deadline = time.monotonic() + 60
    while not (tmp.exists() and bak.exists()) and time.monotonic() < deadline:
        time.sleep(0.01)
    child.kill()
    child.wait(timeout=30)
    assert tmp.exists() and bak.exists()  # what a killed repair leaves
    run = rf.load_run(p)
    assert run.status == "interrupted" and run.samples_stored >= 8 * 500
    _assert_prefix(run)
    assert sorted(q.name for q in tmp_path.iterdir()) == ["killed.h5"]
    with h5py.File(p, "r") as f:
        assert f[rf.VOLTS].shape[0] == run.samples_stored


def test_a_backup_of_a_missing_run_file_is_put_back(tmp_path: Path, killed_file: Path) -> None:
    """A repair's .bak whose process is gone and whose run file is missing is the run: it is
    restored (then repaired) on the next read, never deleted."""
    p = tmp_path / "lost.h5"
    _killed_run(p, killed_file)
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    pid = int(gone.stdout)  # a process that has ended
    os.replace(p, tmp_path / f"lost.h5.bak-{pid}")
    (tmp_path / f".lost.h5.repair-{pid}").write_bytes(b"\0" * 4096)  # a half-written copy
    run = rf.load_run(p)
    assert run.status == "interrupted" and run.samples_stored >= 8 * 500
    _assert_prefix(run)
    assert sorted(q.name for q in tmp_path.iterdir()) == ["lost.h5"]


def test_a_repair_stopped_by_an_exception_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, killed_file: Path
) -> None:
    p = tmp_path / "k.h5"
    _killed_run(p, killed_file)

    def interrupted(src: object, dst: object) -> None:
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(os, "replace", interrupted)
        with pytest.raises(KeyboardInterrupt):
            rf.load_run(p)
    assert sorted(q.name for q in tmp_path.iterdir()) == ["k.h5"]  # original, untouched
    assert rf.load_run(p).status == "interrupted"
    assert sorted(q.name for q in tmp_path.iterdir()) == ["k.h5"]
