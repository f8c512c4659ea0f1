"""The simulated clock's gates: simulated time never passes a gate, never rewinds, and goes on
from the gate (no jump) once it is lifted (issue 31, item 10: a slow host makes a simulated run
take longer, never changes what happens in simulated time)."""

from __future__ import annotations

import hashlib
import json
import os
import re
import subprocess
import sys
import termios
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from analysis.runs import file as rf
from rig.campaign import load_campaign, run_campaign
from rig.sim.clock import SimClock


def _spin_wall(s: float) -> None:
    end = time.perf_counter() + s
    while time.perf_counter() < end:
        time.sleep(0.001)


def test_time_stands_at_the_lowest_gate_however_long_the_host_takes() -> None:
    clk = SimClock(1000.0, gates={"arm": 0.0})
    _spin_wall(0.02)  # 20 simulated s ungated
    assert clk.now() == 0.0
    clk.gate("arm", 0.25)
    clk.gate("line", 0.5)
    _spin_wall(0.02)
    assert clk.now() == 0.25
    assert clk.gated()


def test_a_lifted_gate_lets_time_go_on_from_it_without_a_jump() -> None:
    clk = SimClock(1.0, gates={"arm": 0.0})
    _spin_wall(0.05)  # 0.05 simulated s would have passed
    assert clk.now() == 0.0
    clk.gate("arm", None)
    t = clk.now()
    # from the gate: far less than the 0.05 s that passed while it held
    assert 0.0 <= t < 0.05


def test_a_gate_behind_the_present_holds_time_where_it_is() -> None:
    clk = SimClock(1000.0)
    _spin_wall(0.01)
    t1 = clk.now()
    clk.gate("late", t1 / 2)
    t2 = clk.now()
    assert t2 >= t1  # never rewinds
    _spin_wall(0.01)
    assert clk.now() == t2


def test_sleep_until_a_gated_time_waits_for_the_gate_and_honours_stop() -> None:
    clk = SimClock(1000.0, gates={"arm": 1.0})
    stop = threading.Event()
    out: list[bool] = []
    th = threading.Thread(target=lambda: out.append(clk.sleep_until(2.0, stop)))
    th.start()
    _spin_wall(0.02)
    assert not out and clk.now() == 1.0
    stop.set()
    th.join(timeout=5.0)
    assert out == [False]
    clk.gate("arm", None)
    assert clk.sleep_until(1.5)
    assert clk.now() >= 1.5


# -- whole campaigns: a busy host changes how long a simulated run takes, never its samples ---

CAMPAIGNS = Path(__file__).resolve().parent.parent / "configs" / "campaigns"
BUSY_PROCESSES = 2
BUSY_CODE = "while True:\n    pass\n"


def _reduced_feed_sweep(tmp_path: Path, feeds: str, block_length_mm: float) -> Path:
    """The shipped feed sweep with fewer feeds and a shorter slot (same tool, modes, edge limit)."""
    text = (CAMPAIGNS / "feed-sweep.toml").read_text()
    text = re.sub(r"feed_mm_min = \[[^\]]*\]", f"feed_mm_min = [{feeds}]", text)
    text = text.replace("block_length_mm = 40.0", f"block_length_mm = {block_length_mm}")
    p = tmp_path / "feed-sweep.toml"
    p.write_text(text)
    return p


def _on_grbl(config: Path) -> Path:
    """The same campaign on the GRBL mill, streamed with GRBL's protocol (the character-counting
    window, ``?`` polls, the $G handshake) to the simulated GRBL."""
    text = config.read_text()
    text = re.sub(r'machine = "[^"]*"', 'machine = "lab-grbl"', text, count=1)
    text = text.replace("[sim]\n", '[sim]\nprotocol = "grbl"\n', 1)
    config.write_text(text)
    return config


def _fingerprint(folder: Path) -> dict[str, tuple[int, str, str, str]]:
    """Per run file: (samples, sha256 of the force dataset, of the zero and drift taken from
    the rests (what turns its volts into newtons), of the block table's execution starts)."""
    out = {}
    for f in sorted(folder.glob("*/runs/*.h5")):
        with h5py.File(f, "r") as h:
            volts = h[rf.VOLTS][()]
            zero = [h[k][()] for k in (rf.CAL_ZERO_V, rf.CAL_ZERO_TIME_S, rf.CAL_DRIFT_V_S)]
            exec_s = h[rf.BLOCKS]["exec_s"]
        out[f.name] = (
            volts.shape[0],
            hashlib.sha256(np.ascontiguousarray(volts).tobytes()).hexdigest(),
            hashlib.sha256(b"".join(np.ascontiguousarray(z).tobytes() for z in zero)).hexdigest(),
            hashlib.sha256(np.ascontiguousarray(exec_s).tobytes()).hexdigest(),
        )
    return out


def _base_feed(folder: Path) -> float | None:
    from analysis.rules import find_base_feed, sweep_runs_from_files

    files = sorted(folder.glob("*/runs/*.h5"))
    return find_base_feed(sweep_runs_from_files(files).runs).base_feed_mm_min


def _run(config: Path, out: Path, busy: int) -> None:
    hogs: list[subprocess.Popen] = []
    try:
        for _ in range(busy):
            hogs.append(subprocess.Popen([sys.executable, "-c", BUSY_CODE]))
        res = run_campaign(load_campaign(config), out_root=out, progress=False)
        assert all(r.status == "success" for r in res.runs), [r.reason for r in res.runs]
    finally:
        for p in hogs:
            p.kill()
        for p in hogs:
            p.wait(timeout=10)


def _quiet_and_busy(config: Path, tmp_path: Path) -> tuple[dict, dict]:
    _run(config, tmp_path / "quiet", 0)
    _run(config, tmp_path / "busy", BUSY_PROCESSES)
    return _fingerprint(tmp_path / "quiet"), _fingerprint(tmp_path / "busy")


@pytest.mark.long
def test_a_reduced_feed_sweep_is_bit_identical_beside_two_busy_processes(tmp_path: Path) -> None:
    cfg = _reduced_feed_sweep(tmp_path, "600, 800, 1000, 1200", 12.0)
    quiet, busy = _quiet_and_busy(cfg, tmp_path)
    assert len(quiet) == 4 and quiet == busy
    assert _base_feed(tmp_path / "quiet") == _base_feed(tmp_path / "busy") == 1000.0


@pytest.mark.long
def test_a_reduced_feed_sweep_on_grbl_is_bit_identical_beside_two_busy_processes(
    tmp_path: Path,
) -> None:
    # GRBL's stream is a conversation (an ok frees room, the next line goes out; '?' polls):
    # the host's turnaround used to pass on the clock and moved the program's start by 10-60 ms
    cfg = _on_grbl(_reduced_feed_sweep(tmp_path, "600, 1200", 12.0))
    quiet, busy = _quiet_and_busy(cfg, tmp_path)
    assert len(quiet) == 2 and quiet == busy
    # and the whole record of the stream: sent, answered, executed, every event at its time
    assert _nc_record(tmp_path / "quiet") == _nc_record(tmp_path / "busy")


def _nc_record(folder: Path) -> dict[str, tuple[str, list]]:
    """Per run file: sha256 of the NC-blocks table, the events but for their wall times."""
    out = {}
    for f in sorted(folder.glob("*/runs/*.h5")):
        with h5py.File(f, "r") as h:
            blocks, ev = h[rf.BLOCKS][()], h[rf.EVENTS][()]
        names = [n for n in ev.dtype.names if "wall" not in n]
        out[f.name] = (hashlib.sha256(blocks.tobytes()).hexdigest(),
                       [tuple(e[n] for n in names) for e in ev])  # fmt: skip
    return out


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_the_shipped_feed_sweep_is_bit_identical_beside_two_busy_processes(
    tmp_path: Path,
) -> None:
    quiet, busy = _quiet_and_busy(CAMPAIGNS / "feed-sweep.toml", tmp_path)
    assert len(quiet) == 10 and quiet == busy
    assert _base_feed(tmp_path / "quiet") == _base_feed(tmp_path / "busy") == 1000.0


@pytest.mark.slow
@pytest.mark.timeout(1800)  # two whole demo campaigns, one beside two busy processes
def test_the_demo_campaign_is_bit_identical_beside_two_busy_processes(tmp_path: Path) -> None:
    quiet, busy = _quiet_and_busy(CAMPAIGNS / "facemill-ploughing.toml", tmp_path)
    assert len(quiet) >= 4 and quiet == busy


@pytest.mark.faults
# one of each protocol and each stop in the quick tier, the other two with CI's `long` ones
@pytest.mark.parametrize("on_force,protocol", [
    ("abort", "fanuc"),
    pytest.param("abort", "grbl", marks=pytest.mark.long),
    pytest.param("hold", "fanuc", marks=pytest.mark.long),
    ("hold", "grbl"),
])  # fmt: skip
def test_a_suspender_stop_is_bit_identical_beside_two_busy_processes(
    tmp_path: Path, on_force: str, protocol: str
) -> None:
    # the quick face-milling campaign of the runner's tests, with a force limit it exceeds: the
    # hold comes at the end of the DAQ block that went over, the abort at once or 0.3 simulated
    # s later, and the record ends a rest after the stop, whatever the host's load
    text = (Path(__file__).parent / "data" / "campaign" / "quick.toml").read_text()
    text = text.replace('"OUT"', json.dumps(str(tmp_path / "unused"))).replace("FAULTS", "")
    text += f'\n[suspenders]\nforce_limit_n = 250\non_force = "{on_force}"\nhold_timeout_s = 0.3\n'
    cfg = tmp_path / "quick.toml"
    cfg.write_text(text)
    if protocol == "grbl":  # the stop's reset reaches the streamer as GRBL's banner mid-stream
        _on_grbl(cfg)
    for out, busy in (("quiet", 0), ("busy", BUSY_PROCESSES)):
        hogs = [subprocess.Popen([sys.executable, "-c", BUSY_CODE]) for _ in range(busy)]
        try:
            res = run_campaign(load_campaign(cfg), out_root=tmp_path / out, progress=False,
                               only=lambda t: t.index == 0)  # fmt: skip
        finally:
            for p in hogs:
                p.kill()
                p.wait(timeout=10)
        assert [r.status for r in res.runs] == ["abort"], [r.reason for r in res.runs]
    quiet, busy = _fingerprint(tmp_path / "quiet"), _fingerprint(tmp_path / "busy")
    assert len(quiet) == 1 and quiet == busy


@pytest.mark.long
def test_the_adaptive_feed_loop_is_bit_identical_beside_two_busy_processes(tmp_path: Path) -> None:
    # configs/campaigns/adaptive-step.toml's adaptive run on a shorter block: the loop decides
    # on each DAQ block at its end in simulated time (the DAQ's gate), and its override bytes
    # are read by the simulated GRBL before the clock moves on, so they land at the same times
    text = (CAMPAIGNS / "adaptive-step.toml").read_text()
    cfg = tmp_path / "adaptive-step.toml"
    cfg.write_text(text.replace("block_length_mm = 100.0", "block_length_mm = 40.0"))
    overrides = {}
    for out, busy in (("quiet", 0), ("busy", BUSY_PROCESSES)):
        hogs = [subprocess.Popen([sys.executable, "-c", BUSY_CODE]) for _ in range(busy)]
        try:
            res = run_campaign(load_campaign(cfg), out_root=tmp_path / out, progress=False,
                               only=lambda t: t.group == "adaptive")  # fmt: skip
        finally:
            for p in hogs:
                p.kill()
                p.wait(timeout=10)
        assert [r.status for r in res.runs] == ["success"], [r.reason for r in res.runs]
        (f,) = (tmp_path / out).glob("*/runs/*.h5")
        with h5py.File(f, "r") as h:
            ev = h[rf.EVENTS][()]
        overrides[out] = [(e[2], e[5]) for e in ev if e[5].startswith(b"dnc override")]
    quiet, busy = _fingerprint(tmp_path / "quiet"), _fingerprint(tmp_path / "busy")
    assert len(quiet) == 1 and quiet == busy
    assert len(overrides["quiet"]) > 10 and overrides["quiet"] == overrides["busy"]


def test_the_line_gate_holds_until_every_byte_the_streamer_wrote_was_read() -> None:
    # A write to a pty returns before the reader sees its bytes (the kernel's flip buffer): a
    # gate lifted on "the streamer is done and nothing is pending" let the clock run past the
    # last chunk now and then, and it arrived as a new burst at a wall-dependent time. The
    # streamer's own count of bytes written now decides; the gate lifts once that was read.
    from rig.sim.fanuc import SimFanuc

    clk = SimClock(1000.0, gates={"arm": 0.0})
    ctl = SimFanuc(clock=clk)
    ctl.lockstep = True
    path = ctl.start()
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    attrs = termios.tcgetattr(fd)
    attrs[4] = attrs[5] = termios.B9600  # the controller's line speed (else framing errors)
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    try:
        ctl.expect_stream()
        clk.gate("arm", None)
        os.write(fd, b"%\n")
        _wait(lambda: ctl._bytes_read == 2)
        ctl.end_stream(bytes_written=10)  # 8 more "in the kernel", not yet readable
        _spin_wall(0.05)  # 50 simulated s if time ran free
        t_held = clk.now()
        assert clk.gated() and t_held < 0.01
        os.write(fd, b"G04P1\n%\n")
        _wait(lambda: not clk.gated())  # all 10 read: the gate lifts
        assert clk.now() > t_held
    finally:
        os.close(fd)
        ctl.stop()


def _wait(cond, timeout_s: float = 10.0) -> None:
    end = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < end, "condition not met within the deadline"
        time.sleep(0.002)
