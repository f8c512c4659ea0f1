"""The simulated GRBL answers as GRBL 1.1h does (gnea/grbl's source cited per test): ok when a line
is planned, the status report's fields and $10 mask, sync commands, the Alarm lock, messages."""

from __future__ import annotations

import math
import time

import pytest
import serial
from _dnc_helpers import GRBL_LINE_B_S, grbl_cfg, grbl_texts, line_program

from rig.dnc import GrblStreamer, MemorySink
from rig.sim import SimClock, SimGrbl


class Client:
    """A bare serial client: write lines, read GRBL's lines (status reports apart)."""

    def __init__(self, ctl: SimGrbl) -> None:
        self.ser = serial.Serial(ctl.path, 115200, timeout=3)
        self.ser.reset_input_buffer()
        self.skipped: list[str] = []  # lines read while looking for a status report

    def line(self) -> str:
        if self.skipped:
            return self.skipped.pop(0)
        return self.ser.readline().decode().strip()

    def send(self, text: str) -> list[str]:
        """Write a line, read up to its answer (ok / error:N / ALARM); lines before it too."""
        self.ser.write(text.encode() + b"\n")
        out = []
        while True:
            s = self.line()
            if not s:
                if not out or not out[-1]:
                    raise TimeoutError(f"no answer to {text!r}: {out}")
            out.append(s)
            if s == "ok" or s.startswith(("error:", "ALARM:")):
                return out

    def status(self) -> str:
        self.ser.write(b"?")
        while True:
            s = self.ser.readline().decode().strip()
            if s.startswith("<"):
                return s
            if s:  # an answer that came first (a loaded host asked late) is kept for line()
                self.skipped.append(s)

    def close(self) -> None:
        self.ser.close()


def test_ok_means_planned_not_done() -> None:
    """protocol.c answers a line once gc_execute_line has put it in the planner: with 15 planner
    blocks (planner.h BLOCK_BUFFER_SIZE 16 - 1) line k's ok comes before it runs and, when the
    planner is full, the moment block k - 15 ends. On the controller's record (simulated time):
    when the streamer reads an ok, and whether it keeps the planner full at speed 10, is up to
    the host (a loaded one starved the planner, so an ok came on arrival)."""
    prog = line_program(40, feed_mm_min=100, grbl=True)  # 0.67 s simulated per move
    ctl = SimGrbl(clock=SimClock(10.0))
    with ctl:
        sink = MemorySink()
        GrblStreamer(grbl_cfg(ctl.path), sink=sink, clock=ctl.clock.now,
                     pace_bytes_per_s=GRBL_LINE_B_S * 10).send(prog)  # fmt: skip
    rows, ex, t_ok = sink.rows, ctl.executed, dict(ctl.ok_times_s)
    assert [r.text for r in rows] == grbl_texts(prog) == [b.text for b in ex]
    assert sorted(t_ok) == list(range(len(rows)))
    assert all(r.ack_time_s >= t_ok[k] for k, r in enumerate(rows))  # read after it was sent
    moves = range(20, len(rows) - 3)  # the zig-zag moves after the planner could fill
    assert all(ex[k - 15].t_end_s - 1e-9 <= t_ok[k] <= ex[k].t_start_s for k in moves)
    waited = [k for k in moves if abs(t_ok[k] - ex[k - 15].t_end_s) < 1e-9]
    assert waited and ctl.planner_waits > 0, [(k, t_ok[k], ex[k - 15].t_end_s) for k in moves]


def test_status_report_fields_and_mask() -> None:
    """report.c:466-654: state, MPos|WPos ($10 bit 0), Bf ($10 bit 1), FS, WCO on the first
    report then every 10 idle (30 busy), Ov the report after; defaults.h: $10=1."""
    ctl = SimGrbl(clock=SimClock(1.0))
    with ctl:
        c = Client(ctl)
        first, second = c.status(), c.status()
        assert first == "<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>"
        assert second == "<Idle|MPos:0.000,0.000,0.000|FS:0,0|Ov:100,100,100>"
        assert c.send("$10=3") == ["ok"]
        assert c.status().startswith("<Idle|MPos:0.000,0.000,0.000|Bf:15,128|FS:0,0")
        assert c.send("$10=2") == ["ok"]
        assert c.status().startswith("<Idle|WPos:0.000,0.000,0.000|Bf:15,128|")
        assert c.send("$I")[-2] == "[OPT:V,15,128]"  # report.c:444-446
        c.close()


def test_line_numbers_build_reports_ln() -> None:
    """USE_LINE_NUMBERS (config.h, off by default): Ln of the running block, 14 planner blocks."""
    ctl = SimGrbl(clock=SimClock(1.0), line_numbers=True, status_report_mask=3)
    with ctl:
        c = Client(ctl)
        assert c.status().startswith("<Idle|MPos:0.000,0.000,0.000|Bf:14,128|")
        c.send("N42 G1 X100 F600")
        time.sleep(0.2)
        assert "|Ln:42|" in c.status()
        c.close()


def test_sync_lines_wait_and_messages() -> None:
    """gcode.c:946/955/969/1085: spindle, coolant, dwell, program end wait for the planner to
    empty; the dwell's ok after the dwell (state Idle meanwhile); M30 prints [MSG:Pgm End]."""
    ctl = SimGrbl(clock=SimClock(10.0))
    with ctl:
        c = Client(ctl)
        c.send("G21 G90 G1 X10 F600")  # 1 s simulated
        assert c.send("M8") == ["ok"]
        c.ser.write(b"G4 P5\n")  # 0.5 wall s: the report below most likely comes during it
        time.sleep(0.05)
        assert c.status().startswith("<Idle|")  # mc_dwell: synced, then Idle
        assert c.line() == "ok"
        assert c.send("M30") == ["[MSG:Pgm End]", "ok"]
        c.close()
    # on the controller's record (the test's own clock reads lag on a loaded host)
    t_ok, ex = dict(ctl.ok_times_s), ctl.executed
    assert [b.text for b in ex] == ["G21 G90 G1 X10 F600", "M8", "G4 P5", "M30"]
    assert ex[0].t_end_s - ex[0].t_start_s == pytest.approx(1.0)
    assert t_ok[0] == ex[0].t_start_s and t_ok[1] >= ex[0].t_end_s  # M8 waited for the move
    assert ex[2].t_end_s - ex[2].t_start_s == pytest.approx(5.0)
    assert t_ok[2] == ex[2].t_end_s  # the dwell's ok after the dwell


def test_program_pause_m0_is_a_hold_until_cycle_start() -> None:
    ctl = SimGrbl(clock=SimClock(10.0))
    with ctl:
        c = Client(ctl)
        c.send("G21 G1 X1 F600")
        c.ser.write(b"M0\n")
        deadline = time.monotonic() + 60  # the move and the M0 line, however slow the host
        while not (st := c.status()).startswith("<Hold:0|"):  # gcode.c:1088 feed hold for M0
            assert st.startswith(("<Run|", "<Idle|")) and time.monotonic() < deadline, st
            time.sleep(0.02)
        c.ser.write(b"~")
        assert c.line() == "ok"  # its answer after the resume
        c.close()


def test_alarm_lock_error_9_and_unlock() -> None:
    """protocol.c:100-101 g-code in Alarm is error:9; system.c $X: [MSG:Caution: Unlocked]."""
    ctl = SimGrbl(clock=SimClock(1.0), sim_alarm_at_s=(0.0, 4))
    with ctl:
        assert ctl.quiet.wait(5)
        c = Client(ctl)
        assert c.send("G0 X1") == ["error:9"]
        assert c.send("$X") == ["[MSG:Caution: Unlocked]", "ok"]
        assert c.send("$H") == ["error:5"]  # homing disabled ($22=0): STATUS_SETTING_DISABLED
        # a 100 s move (a 1 mm rapid took 6 ms: a loaded host sent $H after it had ended)
        assert c.send("G1 X100 F60") == ["ok"]
        assert c.send("$H") == ["error:8"]  # system.c:173 not Idle while it moves
        c.close()


def test_a_long_arc_is_acknowledged_when_its_segments_fit() -> None:
    """motion_control.c:109: a half circle of r = 50 mm is 175 planner blocks (174 segments, then
    the end point); gc_execute_line returns (ok) only when the last of them is in the 15-block
    planner: after 160/175 of its time. On the controller's record (when this test reads the ok
    is up to the host)."""
    ctl = SimGrbl(clock=SimClock(10.0), status_report_mask=3)
    segs: list = []
    ctl.add_listener(on_segment=segs.append)
    with ctl:
        c = Client(ctl)
        c.send("G21 G90 F3000")
        c.ser.write(b"G2 X100 Y0 R50\n")  # 157 mm at 50 mm/s: 3.1 s
        assert c.line() == "ok"
        c.close()
    (arc,) = [g for g in segs if g.block == 1]
    t_ok = dict(ctl.ok_times_s)[1] - arc.t_start_s
    run_s = arc.t_end_s - arc.t_start_s
    assert abs(run_s - math.pi) < 0.01  # 157 mm at 50 mm/s
    assert abs(t_ok - run_s * 160 / 175) < 1e-9, t_ok  # the last 15 blocks were left to run
