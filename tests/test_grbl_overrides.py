"""GRBL 1.1 real-time overrides (issue 29): the simulated GRBL honours them as 1.1h does
(protocol.c protocol_exec_rt_system: the steps, the 10-200 % limits, rapid 25/50/100 %, the
reset; report.c: ``Ov:`` in the report after a change, else every 10 idle / 20 busy reports;
planner.c plan_update_velocity_profile_parameters: the blocks it holds run at the new feed), over
a real pty; the streamer writes them at once, records them, and keeps them out of its count.

Expected times are worked out here from the move (length / feed x override), not taken from the
code under test; the one time the test does not choose, when an override byte arrived, is read
from the controller's event and the rest follows by hand.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import serial
from _dnc_helpers import GRBL_LINE_B_S, grbl_bytes, grbl_cfg

from rig.dnc import DncError, GrblStreamer, MemorySink, program_from_text
from rig.dnc.grbl import override_bytes
from rig.sim import MotionTimeline, SimClock, SimGrbl

FEED_UP10, FEED_DN10, FEED_UP1, FEED_DN1, FEED_RESET = 0x91, 0x92, 0x93, 0x94, 0x90
SP_UP10, SP_DN10, SP_RESET = 0x9A, 0x9B, 0x99


class Client:
    """A bare serial client: real-time bytes, lines, status reports (bounded reads)."""

    def __init__(self, ctl: SimGrbl) -> None:
        self.ser = serial.Serial(ctl.path, 115200, timeout=3)
        self.ser.reset_input_buffer()

    def send(self, text: str) -> str:
        self.ser.write(text.encode() + b"\n")
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            s = self.ser.readline().decode().strip()
            if s == "ok" or s.startswith(("error:", "ALARM:")):
                return s
        raise TimeoutError(text)

    def rt(self, code: int, n: int = 1) -> None:
        self.ser.write(bytes([code]) * n)

    def status(self) -> str:
        self.ser.write(b"?")
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            s = self.ser.readline().decode().strip()
            if s.startswith("<"):
                return s
        raise TimeoutError("no status report")

    def ov(self) -> str | None:
        """The Ov field of the next report that has one (at most 12 reports: idle refresh 10)."""
        for _ in range(12):
            s = self.status()
            if "|Ov:" in s:
                return s.split("|Ov:")[1].split("|")[0].rstrip(">")
        return None

    def wait_idle(self, timeout_s: float = 30.0) -> str:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            s = self.status()
            if s.startswith("<Idle"):
                return s
            time.sleep(0.02)
        raise TimeoutError("GRBL never came back to Idle")

    def close(self) -> None:
        self.ser.close()


def _moves_at(t_byte_s: float) -> float:
    """When an override taken at ``t_byte_s`` in mid-move reaches the motion: GRBL 1.1h's
    stepper ring (stepper.c: SEGMENT_BUFFER_SIZE 6, so the running segment and 4 prepared
    behind it, each DT_SEGMENT = 1 / ACCELERATION_TICKS_PER_SECOND = 10 ms) runs out first: the
    5th 10 ms boundary after the byte."""
    return (int(t_byte_s / 0.01 + 1e-9) + 5) * 0.01


def _end_time(t0: float, length_mm: float, feed_mm_min: float, ctl: SimGrbl) -> tuple:
    """When a move of ``length_mm`` at ``feed_mm_min`` started at ``t0`` ends, walking through
    the controller's override events (each: from when it reaches the motion on, the feed x its
    %); also where the tool was at each of them: [(t, x_mm, feed %)]."""
    t, x, pct = t0, 0.0, 100.0
    at = []
    for e in ctl.events:
        if e.kind != "override" or e.t_s < t0:
            continue
        new = float(e.detail.split("feed ")[1].split(" %")[0])
        t_e = max(_moves_at(e.t_s), t)
        step = min(length_mm - x, feed_mm_min * pct / 100 / 60 * (t_e - t))
        x, t, pct = x + step, t_e, new
        at.append((t, x, pct))
    return t + (length_mm - x) / (feed_mm_min * pct / 100 / 60), at


def test_fewest_override_bytes() -> None:
    """Counted by hand: 100 -> 50 five -10; 100 -> 87 one -10, three -1; 15 -> 10 one -10 (GRBL
    clamps at 10); 195 -> 100 the reset; unknown -> 120 the reset then two +10; 200 -> 199 -1;
    spindle 100 -> 73 three -10 then three +1."""
    assert override_bytes(100, 50) == [FEED_DN10] * 5
    assert override_bytes(100, 87) == [FEED_DN10, FEED_DN1, FEED_DN1, FEED_DN1]
    assert override_bytes(15, 10) == [FEED_DN10]
    assert override_bytes(195, 100) == [FEED_RESET]
    assert override_bytes(None, 120) == [FEED_RESET, FEED_UP10, FEED_UP10]
    assert override_bytes(200, 199) == [FEED_DN1]
    assert override_bytes(100, 100) == []
    # 100 -> 73: three -10 to 70, three +1 (six bytes; -10 twice and -1 seven times is nine)
    assert override_bytes(100, 73, "spindle") == [SP_DN10] * 3 + [0x9C] * 3
    with pytest.raises(ValueError):
        override_bytes(100, 5)


def test_steps_limits_and_ov_field_idle() -> None:
    """The steps, the limits (25 x +10 from 100 stops at 200, 25 x -10 at 10), rapid 50/25/100,
    the spindle's steps and limits, the resets; Ov: in the report after a change; a byte that
    changes nothing (at a limit) brings no Ov: (report_ovr_counter is reset only on a change)."""
    ctl = SimGrbl(clock=SimClock(1.0))
    with ctl:
        c = Client(ctl)
        try:
            assert c.ov() == "100,100,100"
            c.rt(FEED_UP10, 25)
            assert c.status().split("|Ov:")[1].startswith("200,100,100")  # the very next report
            assert "|Ov:" not in c.status()  # then the idle refresh
            c.rt(FEED_UP10)  # at the limit: no change, nothing reported
            assert "|Ov:" not in c.status()
            c.rt(FEED_RESET)
            assert c.ov() == "100,100,100"
            c.rt(FEED_DN10, 25)
            assert c.ov() == "10,100,100"
            c.rt(FEED_UP1, 3)
            assert c.ov() == "13,100,100"
            c.rt(0x96)
            assert c.ov() == "13,50,100"
            c.rt(0x97)
            assert c.ov() == "13,25,100"
            c.rt(0x95)
            c.rt(SP_DN10, 20)
            assert c.ov() == "13,100,10"
            c.rt(SP_RESET)
            c.rt(SP_UP10, 15)
            assert c.ov() == "13,100,200"
            c.rt(0x9D, 2)
            assert c.ov() == "13,100,198"
            c.ser.write(b"\x18")  # soft reset: main.c restores the defaults
            assert c.ov() == "100,100,100"
        finally:
            c.close()


def _run_move(ctl: SimGrbl, c: Client, before: list[int], lines: list[str]) -> float:
    """Overrides ``before``, then the lines; the time the last line's block took (sim s)."""
    for code in before:
        c.rt(code)
    c.status()  # the bytes have been taken (one byte stream, in order)
    for t in lines:
        assert c.send(t) == "ok"
    c.wait_idle()
    b = ctl.executed[-1]
    return b.t_end_s - b.t_start_s


def test_feed_override_from_the_start_scales_a_long_move() -> None:
    """100 mm at F600 is 10 s; at 50 % 100 / (600 x 0.5 / 60) = 20 s, at 150 % 6.667 s; a
    rapid at 25 % takes 4 x as long (0x97); a feed override never speeds a move past the rapid
    rate (planner.c: nominal_speed capped at rapid_rate): F6000 at 200 % on a 10 m/min machine
    runs at 10 m/min, 100 mm in 0.6 s."""
    ctl = SimGrbl(clock=SimClock(50.0))
    with ctl:
        c = Client(ctl)
        try:
            assert c.send("G21 G90") == "ok"
            t50 = _run_move(ctl, c, [FEED_DN10] * 5, ["G1 X100 F600"])
            assert t50 == pytest.approx(20.0, abs=1e-9)
            t150 = _run_move(ctl, c, [FEED_RESET] + [FEED_UP10] * 5, ["G1 X0 F600"])
            assert t150 == pytest.approx(100 / (600 * 1.5 / 60), abs=1e-9)
            t_fast = _run_move(ctl, c, [FEED_UP10] * 5, ["G1 X100 F6000"])
            assert t_fast == pytest.approx(100 / (10_000 / 60), abs=1e-9)
            t_rapid = _run_move(ctl, c, [FEED_RESET, 0x97], ["G0 X0"])
            assert t_rapid == pytest.approx(4 * 100 / (10_000 / 60), abs=1e-9)
        finally:
            c.close()


def test_feed_override_mid_move_splits_the_segment() -> None:
    """A 50 % override reaching the motion at t_o in a 300 mm F600 move (the 5th 10 ms segment
    boundary after its bytes, :func:`_moves_at`): the tool is at 10 (t_o - t0) mm
    and covers the rest at 5 mm/s, so the block ends at t_o + (300 - 10 (t_o - t0)) / 5; the
    twin's timeline moves at 10 mm/s before t_o and 5 mm/s after, and the segment cut short
    ends where the slow one starts (the stock is cut only as far as the tool went)."""
    ctl = SimGrbl(clock=SimClock(50.0))
    tl = MotionTimeline()
    ctl.add_listener(on_segment=tl.add, on_spindle=tl.add_spindle_breakpoint)
    with ctl:
        c = Client(ctl)
        try:
            assert c.send("G21 G90 S10000 M3") == "ok"
            assert c.send("G1 X300 F600") == "ok"
            deadline = time.monotonic() + 10
            while ctl.position_mm()[0] < 10 and time.monotonic() < deadline:
                time.sleep(0.002)
            c.rt(FEED_DN10, 5)
            # the motion takes it once the stepper's ring has run out (40-50 ms of the sim
            # clock, 1 ms of wall time at 50 x); FS reports the running speed
            seen = [c.status() for _ in range(2)]  # the first brings WCO; Ov: then the next
            while "|FS:300," not in seen[-1] and len(seen) < 50:
                seen.append(c.status())
            assert "|FS:300,10000" in seen[-1], seen
            assert [r.split("|Ov:")[1][:10] for r in seen if "|Ov:" in r][0] == "50,100,100"
            c.wait_idle()
        finally:
            c.close()
    t0 = ctl.executed[-1].t_start_s
    t_end, at = _end_time(t0, 300.0, 600.0, ctl)
    t_o, x_o, pct = at[-1]  # the five bytes may arrive in more than one read of the pty
    assert at[0][1] >= 10.0 and x_o < 295.0 and pct == 50, at
    assert ctl.executed[-1].t_end_s == pytest.approx(t_end, abs=1e-9)
    t_a, x_a, _ = at[0]
    st = tl.state([t_a - 0.5, t_o + 0.5, t_o + 1.0])
    assert st.velocity_mm_s[:, 0] == pytest.approx([10.0, 5.0, 5.0], abs=1e-9)
    assert st.position_mm[:, 0] == pytest.approx([x_a - 5.0, x_o + 2.5, x_o + 5.0], abs=1e-9)
    assert tl.state([t_end]).position_mm[0, 0] == pytest.approx(300.0)
    cut = [g for g in tl.segments if g.t_start_s == t0][0]
    assert cut.t_end_s == pytest.approx(at[0][0], abs=1e-12)
    assert cut.end_mm[0] == pytest.approx(at[0][1], abs=1e-9)


def test_override_while_held_applies_on_resume_and_busy_refresh() -> None:
    """Held (``!``, Hold:0) the override changes nothing under way; the move resumes (``~``) at
    the new feed: 300 mm at F600 held at x_h resumes at 150 %, the rest takes (300 - x_h) / 15 s.
    While busy, Ov: comes in the report after the change, then every 20th (report.c
    REPORT_OVR_REFRESH_BUSY_COUNT; one later if the WCO refresh falls on it), never beside WCO."""
    ctl = SimGrbl(clock=SimClock(20.0), hold_decel_s=0.0)
    with ctl:
        c = Client(ctl)
        try:
            assert c.send("G21 G90") == "ok"
            assert c.send("G1 X300 F600") == "ok"
            deadline = time.monotonic() + 10
            while ctl.position_mm()[0] < 5 and time.monotonic() < deadline:
                time.sleep(0.002)
            c.ser.write(b"!")
            while "Hold:0" not in c.status() and time.monotonic() < deadline:
                time.sleep(0.01)
            c.rt(FEED_UP10, 5)
            assert c.ov() == "150,100,100"  # the next report, or the one after a WCO
            x_h = float(c.status().split("MPos:")[1].split(",")[0])
            c.ser.write(b"~")
            reports = [c.status() for _ in range(45)]  # 45 reports take far less than the move
            assert all(r.startswith("<Run") for r in reports), reports[-1]
            c.wait_idle()
        finally:
            c.close()
    t_resume = [e.t_s for e in ctl.events if e.kind == "resume"][-1]
    # x_h as reported, to 0.5 um: 3e-5 s of the rest
    assert ctl.executed[-1].t_end_s == pytest.approx(t_resume + (300 - x_h) / 15.0, abs=1e-4)
    has_ov = [i for i, r in enumerate(reports) if "|Ov:" in r]
    assert all("|WCO:" not in reports[i] for i in has_ov)
    gaps = np.diff(has_ov)
    assert len(gaps) >= 1 and set(gaps.tolist()) <= {20, 21}, has_ov


def test_spindle_override_changes_the_reported_and_the_twins_speed() -> None:
    """S10000 M3 then -10 % x 3: FS reports 7000 rpm (spindle_compute_pwm_value scales the
    programmed speed), the twin's spindle turns at 7000 from the byte's arrival, and the moves
    after it carry 7000; the reset brings 10000 back."""
    ctl = SimGrbl(clock=SimClock(20.0))
    tl = MotionTimeline()
    ctl.add_listener(on_segment=tl.add, on_spindle=tl.add_spindle_breakpoint)
    with ctl:
        c = Client(ctl)
        try:
            assert c.send("G21 G90 S10000 M3") == "ok"
            c.wait_idle()
            assert "|FS:0,10000" in c.status()
            c.rt(SP_DN10, 3)
            assert "|FS:0,7000" in c.status()
            assert c.send("G1 X10 F600") == "ok"
            c.wait_idle()
            c.rt(SP_RESET)
            assert "|FS:0,10000" in c.status()
        finally:
            c.close()
    t_o = [e.t_s for e in ctl.events if e.kind == "override"]
    seg = ctl.executed[-1]
    st = tl.state([t_o[0] - 1e-3, t_o[2] + 1e-3, 0.5 * (seg.t_start_s + seg.t_end_s)])
    assert st.spindle_rpm == pytest.approx([10000, 7000, 7000])
    assert [g.spindle_rpm for g in tl.segments if g.block == seg.seq] == [7000.0]


def test_streamer_override_api_records_and_bypasses_the_count() -> None:
    """feed_override_pct(50) during a stream: five 0x92 written at once, each in
    ``override_log`` and in the sink's events with its time; ``overrides`` follows GRBL's Ov:;
    the bytes never enter GRBL's receive buffer (what it received is exactly the program) and
    the character count is untouched (no overrun, every line answered); the long move's time
    follows the override from its arrival (worked out as above)."""
    # 300 mm at F600 is 30 s (0.75 wall s at x40): the override lands well inside it
    text = "G21 G90\nS10000 M3\n" + "".join(f"G1 X{x} F600\n" for x in (300, 290)) + "M30\n"
    prog = program_from_text(text, "ovr.nc")
    ctl = SimGrbl(clock=SimClock(40.0), status_report_mask=3)
    sink = MemorySink()
    with ctl:
        st = GrblStreamer(grbl_cfg(ctl.path), sink=sink, clock=ctl.clock.now, status_hz=20,
                          pace_bytes_per_s=GRBL_LINE_B_S * 40)  # fmt: skip
        with pytest.raises(DncError):
            st.feed_override_pct(50)  # no stream, no port
        with pytest.raises(ValueError):
            st.override(0x98)
        with pytest.raises(ValueError):
            st.override(ord("?"))
        assert st.overrides is None
        out: dict = {}
        th = threading.Thread(target=lambda: out.update(res=st.send(prog)), daemon=True)
        th.start()
        deadline = time.monotonic() + 20
        # GRBL's Ov: (its 2nd report) first: from an unknown value the helper would reset first
        while time.monotonic() < deadline and (ctl.position_mm()[0] < 20 or not st.overrides):
            time.sleep(0.005)
        assert ctl.position_mm()[0] >= 20 and st.overrides == (100, 100, 100)
        st.feed_override_pct(50)
        assert [code for _, code in st.override_log] == [FEED_DN10] * 5
        while time.monotonic() < deadline and st.overrides != (50, 100, 100):
            time.sleep(0.01)
        assert st.overrides == (50, 100, 100)
        st.feed_override_pct(50)  # already there: nothing sent
        assert len(st.override_log) == 5
        th.join(timeout=30)
        assert not th.is_alive()
    assert out["res"].blocks_sent == len(prog.blocks)
    assert bytes(ctl.received) == grbl_bytes(prog)
    assert ctl.overruns == 0 and ctl.max_fill <= 127
    evs = [(t, d) for k, t, d in sink.events if k == "override"]
    assert [d for _, d in evs] == ["0x92 feed -10 %"] * 5
    assert [t for t, _ in evs] == [t for t, _ in st.override_log]
    t_o = [e.t_s for e in ctl.events if e.kind == "override"]
    assert len(t_o) == 5 and t_o[0] >= st.override_log[0][0]  # written, then arrived
    first = [b for b in ctl.executed if b.text == "G1X300F600"][0]
    back = [b for b in ctl.executed if b.text == "G1X290F600"][0]
    t_end, at = _end_time(first.t_start_s, 300, 600, ctl)
    assert 20 <= at[0][1] < 295, at  # in the first move
    assert first.t_end_s == pytest.approx(t_end, abs=1e-9)
    assert back.t_end_s - back.t_start_s == pytest.approx(2.0, abs=1e-9)  # 10 mm all at 50 %


@pytest.mark.faults
def test_dnc_send_adaptive_refused_for_fanuc(tmp_path, capsys) -> None:  # noqa: ANN001
    """A drip feed has no real-time override on its line: one line naming the controller, 2."""
    from rig.cli import main

    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG1 X10 F600\nM30\n")
    rc = main(["dnc", "send", "--protocol", "fanuc", "--adaptive", "feed", str(prog)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and err[0].startswith("cutlab: error: ")
    assert "fanuc controller" in err[0] and "ace-h63" in err[0] and "--protocol grbl" in err[0]
