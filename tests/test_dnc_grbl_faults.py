"""GRBL faults against the simulated GRBL 1.1h on real pseudo-terminals: a lost ``ok``, a garbled
``ok``, a reset mid-stream, an alarm, a restart at an arc, a halt during motion (in-process and by
signals to ``cutlab dnc send``, and a killed streamer). In each the streamer ends in a stated
state within 10 s, the controller ends as stated, and no line reached the controller twice."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from _dnc_helpers import ARCS, GRBL_LINE_B_S, grbl_cfg, grbl_sent, grbl_texts, line_program

from planning.nc import interpret
from rig.dnc import (
    GrblStreamer,
    MemorySink,
    StreamFault,
    grbl_command,
    program_from_text,
    restart_plan,
)
from rig.dnc.grbl import HANDSHAKE
from rig.sim import SimClock, SimGrbl

pytestmark = pytest.mark.faults

SPEED = 10.0


def _streamer(ctl: SimGrbl, **kw) -> GrblStreamer:
    kw = {"status_hz": 20.0, "pace_bytes_per_s": GRBL_LINE_B_S * SPEED} | kw
    return GrblStreamer(grbl_cfg(ctl.path, timeout_s=5.0), clock=ctl.clock.now,
                        sink=MemorySink(), **kw)  # fmt: skip


def _sent_once(ctl: SimGrbl, *streams: list[str] | bytes) -> None:
    """What the controller received is, per stream, the handshake then a prefix of its lines,
    each line once: nothing was sent twice (``bytes`` items: sent between the streams)."""
    got = bytes(ctl.received)
    for texts in streams:
        if isinstance(texts, bytes):
            assert got.startswith(texts), got[:40]
            got = got[len(texts) :]
            continue
        assert got.startswith(HANDSHAKE), got[:40]
        got = got[len(HANDSHAKE) :]
        n = 0
        for t in texts:
            line = t.encode() + b"\n"
            if not got.startswith(line):
                break
            got = got[len(line) :]
            n += 1
        assert n > 0
    assert got == b"", f"unexpected bytes after the streams: {got[:80]!r}"


def _last_run(prog, n: int) -> int:
    """Program index of the n-th line sent (1-based): the last block run when n lines ran."""
    sent = [b for b in prog.blocks if grbl_sent([b.text])]
    return sent[n - 1].index


def _stream(ctl: SimGrbl, prog, **kw) -> tuple[StreamFault | None, float, GrblStreamer]:
    st = _streamer(ctl, **kw)
    t0 = time.perf_counter()
    try:
        st.send(prog)
        fault = None
    except StreamFault as exc:
        fault = exc
    return fault, time.perf_counter() - t0, st


# -- lost and garbled answers --------------------------------------------------------------------


def test_lost_ok_is_detected_and_the_stream_ends() -> None:
    """Line 40's ok never comes (firmware default $10=1: no Bf). Without the detection the
    character count stays short forever; GRBL runs out of lines, reports Idle, and the streamer
    stops naming what ran, instead of hanging."""
    prog = line_program(100, feed_mm_min=800, grbl=True)  # 7.5 s simulated, 0.75 s wall
    ctl = SimGrbl(clock=SimClock(SPEED), sim_drop_ok_at_line=40)
    with ctl:
        fault, wall, st = _stream(ctl, prog)
        assert ctl.quiet.wait(10)
    assert fault is not None and fault.kind == "lost-ok", fault
    assert wall < 10.0
    assert "never came" in str(fault) and "last block known executed" in str(fault)
    texts = grbl_texts(prog)
    assert ctl.executed_texts() == texts  # GRBL ran every line; only an answer was lost
    assert fault.result.last_executed_block >= prog.blocks[-3].index  # it stands at the end
    assert ctl.state_name() == "Idle" and ctl.alarm == ""
    _sent_once(ctl, texts)


def test_lost_ok_with_buffer_reports_stops_sending_early() -> None:
    """With $10=3 (Bf in the reports), the receive buffer holding fewer bytes than are unanswered
    report after report gives the lost answer away while streaming: sending stops, GRBL drains,
    the stream ends with the reason."""
    prog = line_program(400, feed_mm_min=800, grbl=True)  # 30 s simulated, 3 s wall
    ctl = SimGrbl(clock=SimClock(SPEED), sim_drop_ok_at_line=40, status_report_mask=3)
    with ctl:
        fault, wall, st = _stream(ctl, prog)
        assert ctl.quiet.wait(10)
    assert fault is not None and fault.kind == "lost-ok" and wall < 10.0
    assert "never came" in str(fault)
    assert fault.result.last_sent_block < prog.blocks[-1].index  # stopped before the end
    assert ctl.executed_texts() == grbl_texts(prog)[: len(ctl.executed)]
    assert fault.result.last_executed_block == _last_run(prog, len(ctl.executed))
    _sent_once(ctl, grbl_texts(prog))


def test_garbled_ok_stops_sending_and_ends_idle() -> None:
    prog = line_program(300, feed_mm_min=800, grbl=True)
    ctl = SimGrbl(clock=SimClock(SPEED), sim_garble_ok_at_line=40)
    with ctl:
        fault, wall, st = _stream(ctl, prog)
        assert ctl.quiet.wait(10)
    assert fault is not None and fault.kind == "lost-ok" and wall < 10.0
    assert "'oo'" in str(fault) and st.garbled == ["oo"]
    # sending stopped at the garble: at most what was in flight then went on to run
    assert fault.result.blocks_sent < 40 + 25
    n = len(ctl.executed)
    assert ctl.executed_texts() == grbl_texts(prog)[:n] and n == fault.result.blocks_sent
    assert fault.result.last_executed_block == _last_run(prog, n)
    assert ctl.state_name() == "Idle"
    _sent_once(ctl, grbl_texts(prog))


# -- reset and alarm ----------------------------------------------------------------------------


def test_reset_mid_stream_is_alarm_3_then_unlock_and_resume() -> None:
    """A reset while the machine moves (the reset button, a brown-out): GRBL reports ALARM:3,
    its banner and the Alarm lock; the streamer stops naming the alarm and the remedy. The
    operator unlocks (cutlab dnc unlock) and resumes after the last block known executed."""
    prog = line_program(200, feed_mm_min=800, grbl=True)
    ctl = SimGrbl(clock=SimClock(SPEED), sim_reset_at_block=60)
    with ctl:
        fault, wall, st = _stream(ctl, prog)
        assert fault is not None and fault.kind == "alarm" and wall < 10.0
        msg = str(fault)
        assert "ALARM:3 abort during cycle" in msg and "cutlab dnc unlock" in msg
        assert "port" not in msg.split("last acknowledged")[0]  # no blame on the port/baud
        assert ctl.alarm == "3" and ctl.state_name() == "Alarm"
        time.sleep(0.3)  # lines already on the wire land (error:9) before the operator acts
        reply = grbl_command(grbl_cfg(ctl.path, timeout_s=5.0), "unlock")
        assert reply.state_before == "Alarm" and reply.state_after == "Idle"
        assert "[MSG:Caution: Unlocked]" in reply.lines
        m = len(ctl.executed)
        texts = grbl_texts(prog)
        assert ctl.executed_texts() == texts[:m]
        last = fault.result.last_executed_block
        assert last <= _last_run(prog, m)  # never ahead of what ran
        start = next(b.index for b in prog.blocks if b.index > last)
        plan = restart_plan(prog, start, "grbl")
        res = _streamer(ctl).send(prog, start, plan.preamble, replaced=plan.replaced)
        assert res.ok and res.controller_state == "Idle"
        pre = grbl_sent(plan.preamble)
        rest = grbl_texts(prog, start=start)
        assert ctl.executed_texts()[m:] == pre + rest
        # the second stream sent each of its lines once; the first stopped at a prefix
        _sent_once(ctl, texts, b"$X\n", [*pre, *rest])  # $X: cutlab dnc unlock


def test_soft_limit_alarm_names_the_remedy_and_reset_unlock_recover() -> None:
    prog = line_program(200, feed_mm_min=800, grbl=True)
    ctl = SimGrbl(clock=SimClock(SPEED), sim_alarm_at_block=(60, 2))
    with ctl:
        fault, wall, st = _stream(ctl, prog)
        assert fault is not None and fault.kind == "alarm" and wall < 10.0
        msg = str(fault)
        assert "ALARM:2 soft limit" in msg and "cutlab dnc reset" in msg and "unlock" in msg
        assert "[MSG:Reset to continue]" in st.messages or ctl.critical
        cfg = grbl_cfg(ctl.path, timeout_s=2.0)
        # halted after a limit alarm GRBL answers nothing, not even '?', until a soft reset
        with pytest.raises(Exception, match="no status report"):
            grbl_command(cfg, "status")
        rep = grbl_command(cfg, "reset")
        assert rep.state_after == "Alarm" and "[MSG:'$H'|'$X' to unlock]" in rep.lines
        assert grbl_command(cfg, "unlock").state_after == "Idle"
        assert ctl.alarm == "" and ctl.state_name() == "Idle"
    _sent_once(ctl, grbl_texts(prog), b"$X\n")  # $X: cutlab dnc unlock


# -- restart at an arc --------------------------------------------------------------------------


@pytest.mark.parametrize("start", [5, 6, 7, 8])
def test_restart_at_an_arc_runs_like_the_original(start) -> None:
    """Restart at a G2/G3 block (explicit, modal, incremental): GRBL takes every line (no bare
    ``G90 G2``, error:26) and the tool runs the original path from block N on."""
    prog = program_from_text(ARCS, "arcs.nc")
    plan = restart_plan(prog, start, "grbl")
    assert not any(t.split()[-1] in ("G2", "G3") for t in plan.preamble)
    ctl = SimGrbl(clock=SimClock(SPEED))
    segs: list = []
    ctl.add_listener(on_segment=segs.append)
    with ctl:
        res = _streamer(ctl).send(prog, start, plan.preamble, replaced=plan.replaced)
    assert res.ok and ctl.errors == [] and ctl.alarm == ""
    full = interpret(ARCS)
    want = full[full.block >= start]
    n_pre = len(grbl_sent(plan.preamble))
    got = [s for s in segs if s.block >= n_pre and s.t_end_s > s.t_start_s]
    assert len(got) == len(want)
    np.testing.assert_allclose([s.end_mm for s in got], want.end, atol=1e-6)
    np.testing.assert_allclose([s.start_mm for s in got], want.start, atol=1e-6)
    assert [s.kind for s in got] == list(want.kind)


# -- halting ------------------------------------------------------------------------------------


def test_feed_hold_then_reset_back_to_back_is_alarm_3_but_a_halt_is_clean() -> None:
    """What the firmware does (motion_control.c:380-384): a reset while decelerating (Hold:1)
    loses the position (ALARM:3); after Hold:0 it does not. halt() waits for Hold:0."""
    import serial

    for wait, alarm in ((False, "3"), (True, "")):
        ctl = SimGrbl(clock=SimClock(1.0), hold_decel_s=0.5)
        with ctl, serial.Serial(ctl.path, 115200, timeout=2) as s:
            s.write(b"G1 X100 F600\n")
            s.read_until(b"ok\r\n")
            time.sleep(0.3)
            s.write(b"!")
            if wait:
                assert ctl.clock.sleep_until(ctl.clock.now() + 0.8)
                assert ctl.state_name() == "Hold:0"
            s.write(b"\x18")
            s.read_until(b"['$' for help]\r\n")
            time.sleep(0.1)
            assert ctl.alarm == alarm, wait
            assert ctl.state_name() == ("Alarm" if alarm else "Idle")


def test_interrupt_during_motion_holds_then_resets_cleanly() -> None:
    prog = line_program(300, feed_mm_min=800, grbl=True)
    ctl = SimGrbl(clock=SimClock(SPEED), hold_decel_s=0.3)
    events: list = []
    ctl.add_listener(on_event=events.append)
    with ctl:
        st = _streamer(ctl)
        out: dict = {}

        def run() -> None:
            try:
                st.send(prog)
            except StreamFault as exc:
                out["fault"] = exc

        th = threading.Thread(target=run)
        th.start()
        while len(ctl.executed) < 50 and th.is_alive():
            time.sleep(0.01)
        t0 = time.perf_counter()
        st.interrupt("SIGINT received")
        th.join(15)
        assert not th.is_alive() and time.perf_counter() - t0 < 10.0
        fault = out["fault"]
        assert fault.kind == "interrupted" and "SIGINT" in str(fault)
        assert "Hold:0, then soft reset: GRBL Idle, no alarm" in str(fault)
        assert ctl.alarm == "" and ctl.state_name() == "Idle"
        kinds = [e.kind for e in events]
        assert kinds.index("hold") < kinds.index("reset")
        m = len(ctl.executed)
        assert fault.result.last_executed_block <= _last_run(prog, m)
    _sent_once(ctl, grbl_texts(prog))


def _cli_send(path: str, nc: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "rig.cli", "dnc", "send", nc, "--protocol", "grbl",
           "--port", path, "--no-progress", "--timeout", "5"]  # fmt: skip
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.long
@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP", "SIGKILL"])
def test_signals_to_dnc_send_hold_the_machine(sig, tmp_path) -> None:
    """Ctrl-C, SIGTERM, a closed terminal: feed hold, Hold:0, soft reset, Idle (exit 2 with the
    reason). SIGKILL: the watchdog process holds the feed (GRBL ends in Hold)."""
    prog = line_program(200, feed_mm_min=600, grbl=True)  # 0.1 s a block in real time
    nc = tmp_path / "p.nc"
    nc.write_text(prog.text)
    ctl = SimGrbl(clock=SimClock(1.0), hold_decel_s=0.2)
    with ctl:
        proc = _cli_send(ctl.path, str(nc))
        try:
            end = time.perf_counter() + 30
            while len(ctl.executed) < 12 and time.perf_counter() < end:
                time.sleep(0.02)
            assert len(ctl.executed) >= 12, proc.stderr.read() if proc.poll() is not None else ""
            t0 = time.perf_counter()
            proc.send_signal(getattr(signal, sig))
            out, err = proc.communicate(timeout=15)
            assert time.perf_counter() - t0 < 10.0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        if sig == "SIGKILL":
            end = time.perf_counter() + 10
            while ctl.state_name() != "Hold:0" and time.perf_counter() < end:
                time.sleep(0.02)
            assert ctl.state_name() == "Hold:0" and ctl.alarm == ""
        else:
            assert proc.returncode == 2, err
            assert f"{sig} received" in err and "Hold:0, then soft reset: GRBL Idle" in err
            assert ctl.state_name() == "Idle" and ctl.alarm == ""
        assert len(ctl.executed) < len(grbl_texts(prog))
    _sent_once(ctl, grbl_texts(prog))


@pytest.mark.skipif(not os.path.exists("/dev/ptmx"), reason="needs pseudo-terminals")
def test_cutlab_dnc_reset_and_unlock_commands(tmp_path) -> None:
    """`cutlab dnc reset` on a moving GRBL holds first (no ALARM:3); `cutlab dnc unlock`."""
    ctl = SimGrbl(clock=SimClock(1.0), hold_decel_s=0.2)
    with ctl:
        import serial

        with serial.Serial(ctl.path, 115200, timeout=2) as s:
            s.write(b"G1 X100 F600\n")
            s.read_until(b"ok\r\n")
        base = [sys.executable, "-m", "rig.cli", "dnc"]
        r = subprocess.run([*base, "reset", "--port", ctl.path, "--json"], capture_output=True,
                           text=True, timeout=30)  # fmt: skip
        assert r.returncode == 0, r.stderr
        assert '"state_before": "Run"' in r.stdout and '"state_after": "Idle"' in r.stdout
        assert ctl.alarm == ""
        ctl.soft_reset()  # nothing moving: a clean reset, no lock
        ctl.sim_alarm_at_s = (ctl.clock.now(), 4)  # a probe-fail alarm, raised by its thread
        assert ctl.quiet.wait(5)
        end = time.perf_counter() + 5
        while ctl.alarm != "4" and time.perf_counter() < end:
            time.sleep(0.01)
        r = subprocess.run([*base, "unlock", "--port", ctl.path], capture_output=True, text=True,
                           timeout=30)  # fmt: skip
        assert r.returncode == 0 and "GRBL unlocked ($X): Idle" in r.stderr, r.stderr
