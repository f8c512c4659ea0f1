"""The link layer on pyserial's loopback port: CTS and DC3 gating, DC2 hold, loss detection."""

from __future__ import annotations

import threading

import pytest
import serial
from _dnc_helpers import GRBL_LINE_B_S, grbl_cfg

from rig.dnc import GrblStreamer, MemorySink, program_from_text
from rig.dnc.link import DC1, DC3, LinkLost, LinkTimeout, SerialLink
from rig.sim import SimClock, SimGrbl


def test_cts_off_holds_the_writer_until_timeout() -> None:
    """loop:// wires RTS to CTS: with RTS off the writer must not send (and then times out)."""
    ser = serial.serial_for_url("loop://", timeout=0.02)
    got = bytearray()
    link = SerialLink(ser, cts_flow=True, on_data=got.extend).start()
    try:
        link.write(b"G1 X1\n", timeout_s=1.0)
        ser.rts = False
        with pytest.raises(LinkTimeout, match="CTS stayed off"):
            link.write(b"G1 X2\n", timeout_s=0.2)
        ser.rts = True
        link.write(b"G1 X3\n", timeout_s=1.0)
    finally:
        link.close()
    assert b"X2" not in got


def test_dc3_gates_the_writer_and_dc1_releases_it() -> None:
    """On a loopback the writer's own DC3 comes back: the next chunk waits for DC1."""
    ser = serial.serial_for_url("loop://", timeout=0.02)
    got = bytearray()
    echoed = threading.Event()

    def on_data(b: bytes) -> None:
        got.extend(b)
        if got.endswith(b"ABCDEFGH"):
            echoed.set()

    link = SerialLink(ser, soft_flow=True, chunk_bytes=4, on_data=on_data).start()
    try:
        link.write(bytes([DC3]), timeout_s=1.0)
        assert link.xoff.wait(5.0)  # the reader saw it come back
        sent = threading.Event()

        def writer() -> None:
            link.write(b"ABCDEFGH", timeout_s=5.0)
            sent.set()

        th = threading.Thread(target=writer)
        th.start()
        assert not sent.wait(0.2)  # held by the DC3 (bounded wait for an event that must not come)
        link.write_now(bytes([DC1]))
        assert sent.wait(5.0) and echoed.wait(5.0)
        th.join(5)
    finally:
        link.close()
    assert link.xoff_count == 1


def test_closed_port_is_link_lost() -> None:
    ser = serial.serial_for_url("loop://", timeout=0.02)
    link = SerialLink(ser).start()
    link.close()
    with pytest.raises(LinkLost):
        link.write_now(b"?")


def test_grbl_dollar_lines_are_left_alone() -> None:
    """$ lines pass the NC check untouched and GRBL answers them; the rest streams as usual."""
    text = "$$\n$X\nG21 G90\nG1 X1 F600\n$110=800\nG1 X2\n"
    prog = program_from_text(text, "d.nc")
    ctl = SimGrbl(clock=SimClock(10.0))
    with ctl:
        sink = MemorySink()
        st = GrblStreamer(grbl_cfg(ctl.path), sink=sink, pace_bytes_per_s=GRBL_LINE_B_S * 10)
        res = st.send(prog)
    assert res.ok and res.blocks_sent == 6
    # the $$ dump is not taken for answers: one ok per line, in order
    assert [r.status for r in sink.rows] == ["ok"] * 6
    assert "$110=500.000" in st.messages
    assert ctl.settings[110] == 800.0
    assert ctl.executed_texts() == ["G21G90", "G1X1F600", "G1X2"]  # as sent: no spaces


def test_alarm_at_simulated_time() -> None:
    ctl = SimGrbl(clock=SimClock(10.0), sim_alarm_at_s=(0.0, 1))
    with ctl:
        assert ctl.quiet.wait(10)
    assert ctl.alarm == "1" and any(e.kind == "alarm" for e in ctl.events)


def test_fanuc_drip_feed_holds_while_the_control_punches() -> None:
    """DC2 (the control starts punching) stops the drip feed; without DC4 it is a timeout fault
    naming the cause, and the record ends at the last block sent before it."""
    from _dnc_helpers import fanuc_cfg, line_program

    from rig.dnc import FanucStreamer, StreamFault
    from rig.dnc.link import DC2

    prog = line_program(200)
    rows: list = []

    class PunchAfterFirstBatch(MemorySink):
        def append_blocks(self, batch) -> None:  # type: ignore[no-untyped-def]
            super().append_blocks(batch)
            if not rows:  # loop:// sends the DC2 back to the streamer's reader
                st.link.write_now(bytes([DC2]))  # type: ignore[union-attr]
                # Let the reader see it before more is sent (a loaded host could otherwise
                # stream the whole program first: the test flaked under load).
                assert st.punching.wait(10)
            rows.extend(batch)

    sink = PunchAfterFirstBatch()
    st = FanucStreamer(fanuc_cfg("loop://", flow_control="none", timeout_s=0.3), sink=sink)
    with pytest.raises(StreamFault, match="kept punching") as ei:
        st.send(prog)
    assert ei.value.kind == "timeout" and st.punching.is_set()
    assert 32 <= len(sink.rows) < len(prog.blocks)
    assert ei.value.result.last_acknowledged_block == sink.rows[-1].block
