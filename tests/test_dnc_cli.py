"""`cutlab dnc sim-controller` in a subprocess, `cutlab dnc send` against it; bad input exits 2
with a one-line message."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys

import pytest
from _dnc_helpers import grbl_bytes, grbl_texts, line_program

from rig.cli import main
from rig.dnc import read_csv_record, restart_blocks


def _start_sim(*args: str) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "rig.cli", "dnc", "sim-controller", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    # its imports alone (rig.sim pulls in scipy) took > 30 s on a loaded 2-core host
    ready, _, _ = select.select([proc.stdout], [], [], 300)
    if not ready:
        proc.kill()
        pytest.fail("sim-controller printed no path within 300 s")
    path = proc.stdout.readline().strip()
    assert path.startswith("/dev/"), path
    return proc, path


def _stop_sim(proc: subprocess.Popen) -> dict:
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    return json.loads(out)


@pytest.mark.long
def test_send_to_sim_controller_with_restart_and_record(tmp_path, capsys) -> None:
    prog = line_program(80, grbl=True)  # 0.7 s of motion: a few 5 Hz status reports
    nc = tmp_path / "part.nc"
    nc.write_text(prog.text)
    proc, path = _start_sim("--protocol", "grbl", "--speed", "1", "--json")
    try:
        start = prog.blocks[10].index
        rec = tmp_path / "blocks.csv"
        args = ["dnc", "send", str(nc), "--port", path, "--protocol", "grbl", "--json"]
        rc = main([*args, "--start-block", str(start), "--record", str(rec), "--no-progress"])
        summary = json.loads(capsys.readouterr().out)
    finally:
        sim = _stop_sim(proc)
    assert rc == 0
    pre = restart_blocks(prog, start, "grbl")
    n = len(grbl_texts(prog, pre, start))  # the preamble's comment is not sent
    assert summary["blocks_sent"] == n and summary["ok"]
    assert summary["last_executed_block"] == prog.blocks[-1].index
    assert summary["transform"] and summary["controller_state"] == "Idle"
    assert summary["last_acknowledged_block"] == prog.blocks[-1].index
    assert summary["bytes_sent"] == len(grbl_bytes(prog, pre, start))
    assert 0.0 <= summary["starved_fraction"] <= 1.0 and summary["seconds"] > 0
    # what the controller received, byte for byte
    import hashlib

    assert sim["sha256"] == hashlib.sha256(grbl_bytes(prog, pre, start)).hexdigest()
    assert sim["blocks_executed"] == n
    rows = read_csv_record(rec)
    assert [r.text for r in rows] == grbl_texts(prog, pre, start)
    assert all(r.exec_time_s >= r.send_time_s for r in rows)


@pytest.mark.parametrize(
    "argv,match",
    [
        (["--protocol", "hpgl", "--port", "loop://"], "protocol = 'hpgl': unknown"),
        (["--protocol", "grbl", "--port", "/dev/ttyNOPE-cutlab"], "cannot open"),
        (["--protocol", "grbl", "--port", "loop://", "--machine", "ace-h63"], "dialect"),
        (["--protocol", "fanuc", "--port", "loop://", "--baud", "250000"], "not a Fanuc"),
    ],
)
def test_bad_input_exits_2_with_one_line(argv, match, tmp_path, capsys) -> None:
    nc = tmp_path / "p.nc"
    nc.write_text(line_program(3, grbl=True).text)  # a program GRBL takes (no O, no M6)
    rc = main(["dnc", "send", str(nc), *argv])
    err = capsys.readouterr().err
    assert rc == 2 and match in err
    assert "Traceback" not in err and err.count("cutlab: error:") == 1
    assert err.splitlines()[-1].startswith("cutlab: error:")


def test_nc_error_exits_2_before_opening_the_port(tmp_path, capsys) -> None:
    nc = tmp_path / "bad.nc"
    nc.write_text("G21\nG1 X10 F100\nG7 X1\n")
    # the port does not exist: the NC error must be what is reported, i.e. found first
    rc = main(["dnc", "send", str(nc), "--protocol", "grbl", "--port", "/dev/ttyNOPE"])
    err = capsys.readouterr().err
    assert rc == 2 and f"{nc}:3:" in err and "nothing was sent" in err


def test_sim_controller_rejects_unknown_knob(capsys) -> None:
    rc = main(["dnc", "sim-controller", "--protocol", "grbl", "--sim", "explode_at=3"])
    assert rc == 2 and "unknown knob" in capsys.readouterr().err


GRBL_KNOBS = (
    "alarm_at_block, alarm_at_s, drop_ok_at_line, drop_port_after_block, error_at_block, "
    "garble_ok_at_line, noise_at_line, overrun_at_byte, reset_at_block, "
    "stop_answering_after_block, "
    "stop_answering_at_s"
)
FANUC_KNOBS = (
    "alarm_at_block, alarm_at_s, drop_port_after_block, overrun_at_byte, "
    "stop_answering_after_block, stop_answering_at_s"
)


@pytest.mark.parametrize(("protocol", "knobs"), [("fanuc", FANUC_KNOBS), ("grbl", GRBL_KNOBS)])
def test_unknown_knob_lists_the_valid_ones(capsys, protocol, knobs) -> None:
    rc = main(["dnc", "sim-controller", "--protocol", protocol, "--sim", "foo=1"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err == (
        f"cutlab: error: --sim foo: unknown knob for the {protocol} controller; valid knobs: "
        f"{knobs}"
    )


@pytest.mark.skipif(not os.path.exists("/dev/ptmx"), reason="needs pseudo-terminals")
def test_sim_controller_fanuc_prints_a_tty() -> None:
    proc, path = _start_sim("--protocol", "fanuc", "--json")
    sim = _stop_sim(proc)
    assert sim["path"] == path and sim["bytes_received"] == 0


def test_serve_answers_a_remote_request(tmp_path) -> None:
    """`cutlab dnc serve --once` (subprocess) answers the simulated control's request."""
    from _dnc_helpers import EventWaiter

    from rig.sim import SimClock, SimFanuc

    prog = line_program(30)
    (tmp_path / "O4321.nc").write_text(prog.text)
    ctl = SimFanuc(clock=SimClock(1.0))  # 9600 baud 7E2 as ace-h63
    done = EventWaiter(ctl, "program_end")
    with ctl:
        cmd = [sys.executable, "-m", "rig.cli", "dnc", "serve", "--once", "--json", "--port",
               ctl.path, "--folder", str(tmp_path), "--machine", "ace-h63"]  # fmt: skip
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            if not select.select([proc.stderr], [], [], 30)[0]:
                pytest.fail("serve printed nothing within 30 s")
            assert "listening" in proc.stderr.readline()
            ctl.request_program("4321")
            out, err = proc.communicate(timeout=120)
        finally:
            proc.kill()
        assert proc.returncode == 0, err
        assert done.wait(60)
    res = json.loads(out)
    assert res["program"] == "4321" and res["ok"] and res["blocks_sent"] == len(prog)
    assert ctl.executed_texts() == [b.text for b in prog.blocks]


def test_restart_dry_run_prints_the_preamble_and_sends_nothing(tmp_path, capsys) -> None:
    from test_dnc_restart import CLEAR

    nc = tmp_path / "c.nc"
    nc.write_text(CLEAR)
    port = str(tmp_path / "no-such-tty")  # nothing is opened: a port that does not exist
    args = ["dnc", "send", str(nc), "--port", port, "--protocol", "grbl", "--start-block", "5",
            "--dry-run"]  # fmt: skip
    assert main(args) == 0
    out, err = capsys.readouterr()
    lines = [ln.split("    (")[0] for ln in out.splitlines() if not ln.startswith("(")]
    # as GRBL is sent (stripped): up at the clearance, over X20 Y0, down at F600, F3000 back
    assert lines[3:8] == ["G90G0Z5", "X20Y0", "G1Z-1F600", "F3000", "G90G1"]
    assert lines[8] == "G1Y10"
    assert "clearance Z5 mm" in err and "plunge F600 mm/min" in err and "nothing was sent" in err
    assert main([*args, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["sent"] is False and doc["first_blocks"][0] == {"block": 5, "line": 6,
                                                              "text": "G1Y10"}  # fmt: skip
    assert "G1Z-1F600" in doc["preamble"]


@pytest.mark.faults
def test_restart_without_a_plunge_feed_is_one_line(tmp_path, capsys) -> None:
    nc = tmp_path / "np.nc"
    nc.write_text("G21 G90\nG0 X0 Y0 Z5\nG0 Z-1\nG1 X10 F3000\nG1 X20\nM30\n")
    args = ["dnc", "send", str(nc), "--port", str(tmp_path / "tty"), "--protocol", "fanuc",
            "--start-block", "4", "--dry-run"]  # fmt: skip
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--plunge-feed" in err and "np.nc" in err
    assert main([*args, "--plunge-feed", "300"]) == 0
    assert "G1 Z-1 F300" in capsys.readouterr().out
