"""Bad input gives a clear message (nothing sent); restart preamble; remote request; the record in
a CSV file and in a real HDF5 run file; GRBL status parsing."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest
from _dnc_helpers import (
    FANUC_LINE_B_S,
    GRBL_LINE_B_S,
    EventWaiter,
    fanuc_bytes,
    fanuc_cfg,
    fanuc_sim,
    grbl_cfg,
    line_program,
)

from analysis.config import SerialConfig
from planning.nc import interpret, state_at_block
from rig.dnc import (
    BlockRow,
    CsvSink,
    DncError,
    FanucStreamer,
    GrblStreamer,
    MemorySink,
    RemoteServer,
    StreamFault,
    parse_request,
    parse_status,
    program_from_text,
    read_csv_record,
    restart_blocks,
)
from rig.dnc.port import check_settings
from rig.sim import SimClock, SimControllerError, SimFanuc, SimGrbl

# -- bad input ------------------------------------------------------------------------------------


def test_unknown_protocol() -> None:
    with pytest.raises(DncError, match="protocol = 'hpgl': unknown; expected one of fanuc, grbl"):
        check_settings(SerialConfig(), "hpgl")


def test_port_that_does_not_exist() -> None:
    prog = line_program(3)
    st = FanucStreamer(fanuc_cfg("/dev/ttyNOPE-cutlab"))
    with pytest.raises(DncError, match=r"serial.port = '/dev/ttyNOPE-cutlab': cannot open"):
        st.send(prog)
    assert st.sink.closed


def test_nc_error_is_reported_before_anything_is_sent() -> None:
    text = "%\nG21 G90\nG1 X10 F600\nG2 X20 Y0 R1\nG1 X30\n%\n"  # R too small for the chord
    ctl = SimFanuc(clock=SimClock(10.0), baudrate=115200)
    with ctl:
        with pytest.raises(DncError) as ei:
            prog = program_from_text(text, "bad.nc")
            FanucStreamer(fanuc_cfg(ctl.path)).send(prog)
        assert ctl.received == b""  # nothing reached the controller
    msg = str(ei.value)
    assert msg.startswith("bad.nc:4:") and "nothing was sent" in msg


def test_unsendable_character_is_named() -> None:
    with pytest.raises(DncError, match=r"p.nc:2:4: character 'é' cannot be sent"):
        program_from_text("G21\nG1 é\n", "p.nc", check_nc=False)


@pytest.mark.parametrize(
    "protocol,kw,match",
    [
        ("grbl", dict(bytesize=7, parity="E", stopbits=2), r"serial.bytesize = 7: GRBL talks 8N1"),
        ("grbl", dict(bytesize=8, parity="N", stopbits=1, flow_control="xonxoff"),
         r"flow_control = 'xonxoff': GRBL paces the sender"),
        ("fanuc", dict(baudrate=250000), r"serial.baudrate = 250000: not a Fanuc"),
        ("fanuc", dict(code="EIA"), r"serial.code = 'EIA' with bytesize = 7, parity = 'E': EIA"),
    ],
)  # fmt: skip
def test_settings_the_controller_cannot_take(protocol, kw, match) -> None:
    cfg = SerialConfig(port="loop://", **kw)
    with pytest.raises(DncError, match=match):
        check_settings(cfg, protocol)
    cls = FanucStreamer if protocol == "fanuc" else GrblStreamer
    with pytest.raises(DncError, match=match):
        cls(cfg)


def test_simulated_control_refuses_rtscts_on_a_pty() -> None:
    with pytest.raises(SimControllerError, match="pseudo-terminal has no modem lines"):
        SimFanuc(flow_control="rtscts")


def test_wrong_baud_rate_is_garbage_to_the_controller() -> None:
    """A streamer at 9600 baud to a GRBL at 115200: framing errors, then no answer."""
    ctl = SimGrbl(clock=SimClock(10.0))
    with ctl:
        st = GrblStreamer(grbl_cfg(ctl.path, baudrate=9600, timeout_s=0.5))
        with pytest.raises(StreamFault) as ei:
            st.send(line_program(3, grbl=True))
    assert ei.value.kind == "timeout" and "wrong port or baud rate" in str(ei.value)
    assert ctl.framing_errors > 0 and ctl.received == b""


def test_fanuc_at_the_wrong_baud_rate_is_alarm_085() -> None:
    ctl = fanuc_sim(4.0)  # 115200 baud
    with ctl:
        st = FanucStreamer(fanuc_cfg(ctl.path, baudrate=9600, timeout_s=0.5))
        with pytest.raises(StreamFault, match="held XOFF"):
            st.send(line_program(100))
    assert ctl.alarm == "85" and ctl.framing_errors > 0 and ctl.executed == []


def test_grbl_line_too_long_is_refused_before_sending() -> None:
    long = "G1 " + " ".join(f"X{i}.12345" for i in range(12)) + " F100"
    prog = program_from_text(f"{long}\n", "long.nc", check_nc=False)
    ctl = SimGrbl(clock=SimClock(10.0))
    with ctl:
        want = r"long.nc:1:1: GRBL error:11: line overflow: .* GRBL's line buffer holds 79"
        with pytest.raises(DncError, match=want):
            GrblStreamer(grbl_cfg(ctl.path)).send(prog)
        assert ctl.received == b""


def test_start_block_out_of_range() -> None:
    prog = line_program(5)
    with pytest.raises(DncError, match=r"start block = 99: out of range"):
        FanucStreamer(fanuc_cfg("loop://")).send(prog, start_block=99)


# -- restart ------------------------------------------------------------------------------------


def test_restart_preamble_restores_the_modal_state() -> None:
    """Interpreting preamble + rest ends where the whole program ends, same modal state."""
    text = (
        "%\nG20 G90 G17 G54\nT3 M6\nS1200 M4\nM8\nG0 X1 Y1 Z0.2\nG1 Z-0.1 F5\n"
        "G91 G1 X0.5\nG3 X0.5 Y0.5 R0.5\nG1 Y1\n%\n"
    )
    prog = program_from_text(text, "r.nc")
    n = 8  # restart at "G3 X0.5 Y0.5 R0.5" (line 9): incremental inch arcs
    pre = restart_blocks(prog, n, "fanuc")
    assert pre[0] == "(RESTART AT BLOCK 8 LINE 9)"
    resumed = "\n".join(pre + text.splitlines()[n:])
    full = interpret(text)
    part = interpret(resumed)
    # the resumed program's last moves are the original's last moves
    k = 2
    np.testing.assert_allclose(part.end[-k:], full.end[-k:], atol=1e-9)
    np.testing.assert_allclose(part.start[-k:], full.start[-k:], atol=1e-9)
    np.testing.assert_array_equal(part.spindle_rpm[-k:], full.spindle_rpm[-k:])
    a = state_at_block(resumed, len(resumed.splitlines()))
    b = state_at_block(text, len(text.splitlines()))
    for field in ("inch", "absolute", "plane", "tool", "spindle_dir", "coolant", "feed_mm_min"):
        assert getattr(a, field) == getattr(b, field), field
    # approach: retract, XY at the safe height, then down at the feed
    assert any(t.startswith("G90 G0 Z") for t in pre)
    assert any(t.startswith("G1 Z") and "F5" in t for t in pre)


def test_restart_with_a_dynamic_tool_length_offset_goes_back_to_the_cut() -> None:
    """G43.1 in force: the preamble sets the offset, then returns to where the block began (the
    offset's own axis words once stood in for that position: X0 Y0 Z2 instead of X3 Y1 Z5)."""
    text = "G21 G90 G17 G54\nG0 X1 Y1 Z5\nG43.1 Z2\nG0 X3\nG0 X4\nG1 Z-1 F100\n"
    from analysis.config import load_machine

    grbl = load_machine("lab-grbl")
    prog = program_from_text(text, "tlo.nc", check_nc=False)
    pre = restart_blocks(prog, 4, "grbl", grbl, plunge_feed_mm_min=100)  # at "G0 X4"
    assert "G43.1 Z2" in pre and "X3 Y1" in pre, pre
    resumed = "\n".join(pre + text.splitlines()[4:])
    full, part = interpret(text, grbl), interpret(resumed, grbl)
    np.testing.assert_allclose(part.end[-2:], full.end[-2:], atol=1e-9)
    a = state_at_block(resumed, len(resumed.splitlines()), grbl)
    b = state_at_block(text, len(text.splitlines()), grbl)
    np.testing.assert_allclose(a.position_mm, b.position_mm, atol=1e-9)
    assert a.tool_length_offset_mm == b.tool_length_offset_mm


def test_restart_completes_canned_cycles_and_refuses_ended_programs() -> None:
    from rig.dnc import restart_plan

    text = "G21 G90\nG0 Z5\nG81 X1 Y1 Z-2 R1 F100\nX2\nX3\nG80\n"
    cyc = program_from_text(text, "c.nc")
    plan = restart_plan(cyc, 3, "fanuc")  # the hole at X2: sent as a complete cycle block
    assert plan.replaced == {3: "G98 G81 X2 Z-2 R1 F100"}
    assert "G81" not in " ".join(plan.preamble)
    rest = [plan.replaced.get(i, t) for i, t in enumerate(text.splitlines()) if i >= 3]
    full, part = interpret(text), interpret("\n".join(plan.preamble + rest) + "\n")
    a, b = full[full.block >= 3], part[part.block >= len(plan.preamble)]
    np.testing.assert_allclose(b.end, a.end, atol=1e-9)
    inc = program_from_text("G21 G90\nG0 Z5\nG91 G81 X1 Y1 Z-2 R-4 F100\nX2\nG80\n", "i.nc")
    with pytest.raises(DncError, match=r"restart at block 3 .*incremental \(G91\) canned cycle"):
        restart_blocks(inc, 3, "fanuc")
    ended = program_from_text("G21\nG0 X1\nM30\nG0 X2\n", "e.nc", check_nc=False)
    with pytest.raises(DncError, match="program ended"):
        restart_blocks(ended, 3, "fanuc")


def test_grbl_preamble_leaves_out_what_grbl_rejects() -> None:
    prog = program_from_text("G21 G90\nT2 M6\nS9000 M3\nG0 X1 Y1 Z1\nG1 Z0 F300\nX5\n", "g.nc")
    pre = restart_blocks(prog, 5, "grbl")
    text = " ".join(pre)
    assert "M6" not in text and "G98" not in text and "G90.1" not in text
    assert "T2" in text and "S9000 M3" in text


# -- remote request -----------------------------------------------------------------------------


def _serve(srv: RemoteServer, punch) -> object:
    """Run srv.serve_one in a thread, punch the request once it listens; its result or error."""
    out: dict = {}

    def run() -> None:
        try:
            out["res"] = srv.serve_one(wait_s=30)
        except DncError as exc:
            out["err"] = exc

    th = threading.Thread(target=run)
    th.start()
    assert srv.listening.wait(10)
    punch()
    th.join(60)
    assert not th.is_alive()
    if "err" in out:
        raise out["err"]
    return out["res"]


def test_parse_request() -> None:
    assert parse_request("%\nO9999 (PRG=1234) (BLK=120)\n%\n").program == "1234"
    assert parse_request("O9999(prg=AB-7)(start=5)").start_block == 5
    with pytest.raises(DncError, match="names no program"):
        parse_request("O9999")


def test_remote_request_serves_the_named_program_from_its_start_block(tmp_path) -> None:
    prog = line_program(40)
    (tmp_path / "O1234.nc").write_text(prog.text)
    ctl = fanuc_sim(4.0)
    with ctl:
        srv = RemoteServer(fanuc_cfg(ctl.path, program_folder=str(tmp_path)),
                           pace_bytes_per_s=FANUC_LINE_B_S * 4)  # fmt: skip
        start = prog.blocks[20].index
        done = EventWaiter(ctl, "program_end")
        res = _serve(srv, lambda: ctl.request_program("1234", start_block=start))
        assert done.wait(60)
    assert srv.request.program == "1234" and srv.request.start_block == start
    pre = restart_blocks(prog, start, "fanuc")
    assert res.ok and ctl.executed_texts() == pre + [b.text for b in prog.blocks[20:]]
    cfg = fanuc_cfg(ctl.path)
    assert bytes(ctl.received) == fanuc_bytes(prog, cfg, pre, start)


def test_remote_request_for_a_missing_program(tmp_path) -> None:
    ctl = SimFanuc(clock=SimClock(4.0), baudrate=115200)
    with ctl:
        srv = RemoteServer(fanuc_cfg(ctl.path, program_folder=str(tmp_path)))
        with pytest.raises(DncError, match=r"program '777': not in .* \(looked for 777, 777.nc"):
            _serve(srv, lambda: ctl.request_program("777"))


# -- the record ---------------------------------------------------------------------------------


def test_csv_record_round_trip(tmp_path) -> None:
    rows = [BlockRow(3, 4, "G1 X1", 6, 1.5), BlockRow(-1, 0, "(x, y)", 7, 2.0, 2.5, "ok", 2.75)]
    sink = CsvSink(tmp_path / "r.csv")
    sink.append_blocks(rows)
    sink.event("fault:timeout", 3.0, "no answer")
    sink.close()
    back = read_csv_record(tmp_path / "r.csv")
    assert back[1] == rows[1] and back[0].block == 3 and math.isnan(back[0].ack_time_s)
    assert "fault:timeout" in (tmp_path / "r.csv.events.csv").read_text()


def test_block_record_in_a_real_run_file_after_a_fault(tmp_path) -> None:
    """GRBL error:N mid-stream: the HDF5 run file is closed (status fail) and holds the blocks."""
    from analysis.runs import load_run
    from rig.daq import SAMPLE_FORMAT_VOLTS, DaqInfo
    from rig.dnc.sinks import LoggerSink
    from rig.log import RunWriter

    info = DaqInfo("Sim1", ("a0", "a1", "a2"), ("Fx", "Fy", "Fz"), 1000.0, SAMPLE_FORMAT_VOLTS,
                   10.0, 100)  # fmt: skip
    clock = SimClock(10.0)
    writer = RunWriter(tmp_path / "run.h5", info, None, clock=clock.now)
    prog = line_program(60, grbl=True)
    ctl = SimGrbl(clock=clock, sim_error_at_block=(30, 33))
    with ctl:
        st = GrblStreamer(grbl_cfg(ctl.path), sink=LoggerSink(writer, close_writer=True),
                          clock=clock.now, pace_bytes_per_s=GRBL_LINE_B_S * 10)  # fmt: skip
        with pytest.raises(StreamFault) as ei:
            st.send(prog)
    assert ei.value.kind == "error" and "error:33" in str(ei.value)
    run = load_run(tmp_path / "run.h5")
    assert run.status == "fail" and "error:33" in run.reason
    acked = run.blocks[np.isfinite(run.blocks["ack_s"])]
    # 30 lines answered ok, the 31st answered error:33 (its answer time is its ack time); the
    # comment line is not sent
    sent = [b.index for b in prog.blocks if not b.text.startswith("(")]
    assert list(acked["block"]) == sent[:31]
    assert f"for block {sent[30]} " in str(ei.value)
    assert (acked["ack_s"] >= acked["send_s"]).all()
    assert (run.events["kind"] == "fault").any()


# -- GRBL status ------------------------------------------------------------------------------


def test_parse_status() -> None:
    st = parse_status("<Run|MPos:1.000,-2.500,0.000|Bf:12,100|FS:600,10000|Ln:42>")
    assert st.state == "Run" and st.mpos_mm == (1.0, -2.5, 0.0)
    assert (st.planner_free, st.rx_free, st.feed_mm_min, st.line) == (12, 100, 600.0, 42)
    assert parse_status("<Hold:0|MPos:0,0,0>").state == "Hold"
    with pytest.raises(DncError, match="bad field"):
        parse_status("<Idle|Bf:x,1>")


def test_memory_sink_refuses_rows_after_close() -> None:
    s = MemorySink()
    s.close()
    with pytest.raises(DncError, match="append after close"):
        s.append_blocks([BlockRow(0, 1, "G0", 3, 0.0)])
