"""`cutlab dnc send` takes feed hold / resume / abort from the keyboard and from signals (issue 31,
item 3), as senders do: the command runs as a subprocess with a real pseudo-terminal as stdin,
against the simulated GRBL (in this process, on its own pty); SIGUSR1/SIGUSR2 and the keys ``!``
``~`` ``q`` go to it as an operator's would. Every wait has a deadline."""

from __future__ import annotations

import json
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time

import pytest

from analysis.config import load_machine
from rig.sim import SimClock, SimGrbl

# 200 moves of 1 mm at F300: 40 s of motion at speed 1, so every action lands mid-program however
# slow the host; once the operator is done the clock is sped up to finish (see _set_speed)
MOVES = 200
PROGRAM = "\n".join(
    ["(keys test)", "G21 G90 G17", "G0 X0 Y0 Z5", "G1 Z-1 F600"]
    + [f"G1 X{i + 1} Y{(i % 2) * 0.5:g} F300" for i in range(MOVES)]
    + ["G0 Z5", "M30"]
) + "\n"  # fmt: skip
DEADLINE_S = 20.0


def _set_speed(clock: SimClock, speed: float) -> None:
    """Change a running SimClock's speed without a jump in simulated time."""
    with clock._lock:
        wall = time.perf_counter()
        t = (wall - clock._wall0) * clock.speed
        clock.speed = float(speed)
        clock._wall0 = wall - t / clock.speed


class _Sender:
    """`cutlab dnc send` in a subprocess, stdin a pty (``key`` types on it), stderr read line by
    line in a thread."""

    def __init__(self, nc: str, port: str) -> None:
        self.master, slave = os.openpty()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "rig.cli", "dnc", "send", nc, "--port", port, "--protocol",
             "grbl", "--json", "--no-progress"],
            stdin=slave, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        os.close(slave)
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.lines.put(line.rstrip("\n"))

    def wait_line(self, pattern: str, deadline_s: float = DEADLINE_S) -> str:
        rx = re.compile(pattern)
        end = time.monotonic() + deadline_s
        while time.monotonic() < end:
            try:
                line = self.lines.get(timeout=0.05)
            except queue.Empty:
                if self.proc.poll() is not None and self.lines.empty():
                    break
                continue
            self.seen.append(line)
            if rx.search(line):
                return line
        pytest.fail(f"no stderr line matching {pattern!r} within {deadline_s} s: {self.seen}")

    def key(self, text: str) -> None:
        os.write(self.master, text.encode())

    def finish(self, timeout_s: float = 60.0) -> tuple[int, str]:
        try:  # stderr is the reader thread's (communicate would take lines from it); the JSON
            # on stdout is far below a pipe's buffer, so waiting first cannot block the sender
            self.proc.wait(timeout=timeout_s)
            assert self.proc.stdout is not None
            out = self.proc.stdout.read()
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait(timeout=10)
            os.close(self.master)
        self._reader.join(5)
        while not self.lines.empty():
            self.seen.append(self.lines.get_nowait())
        return self.proc.returncode, out


@pytest.fixture
def rig(tmp_path):
    nc = tmp_path / "keys.nc"
    nc.write_text(PROGRAM)
    clock = SimClock(1.0)
    ctl = SimGrbl(load_machine("lab-grbl"), clock=clock)
    path = ctl.start()
    try:
        sender = _Sender(str(nc), path)
        try:
            yield ctl, clock, sender
        finally:
            if sender.proc.poll() is None:
                sender.proc.kill()
                sender.proc.wait(timeout=10)
                os.close(sender.master)
    finally:
        ctl.stop()


def _wait_state(ctl: SimGrbl, state: str, deadline_s: float = DEADLINE_S) -> None:
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        if ctl.state_name() == state:
            return
        time.sleep(0.01)
    pytest.fail(f"the simulated GRBL did not reach {state} within {deadline_s} s")


def test_signals_and_keys_hold_and_resume_a_running_send(rig) -> None:
    ctl, clock, sender = rig
    sender.wait_line(r"^sending ")
    _wait_state(ctl, "Run")
    sender.proc.send_signal(signal.SIGUSR1)
    sender.wait_line(r"feed hold \(SIGUSR1\).*GRBL Hold")
    _wait_state(ctl, "Hold:0")  # the controller itself holds
    sender.proc.send_signal(signal.SIGUSR2)
    sender.wait_line(r"resume \(SIGUSR2\).*GRBL Run")
    sender.key("!")
    sender.wait_line(r"feed hold \(key '!'\).*GRBL Hold")
    _wait_state(ctl, "Hold:0")
    sender.key("~")
    sender.wait_line(r"resume \(key '~'\).*GRBL Run")
    _set_speed(clock, 200.0)  # the operator is done: run the rest quickly
    rc, out = sender.finish()
    assert rc == 0, sender.seen
    doc = json.loads(out)
    assert doc["ok"] and doc["last_executed_block"] == PROGRAM.count("\n") - 1
    acts = [(a["action"], a["source"]) for a in doc["operator_actions"]]
    assert acts == [("hold", "SIGUSR1"), ("resume", "SIGUSR2"), ("hold", "key '!'"),
                    ("resume", "key '~'")]  # fmt: skip
    assert all(a["block"] >= 0 for a in doc["operator_actions"])
    kinds = [e.kind for e in ctl.events if e.kind in ("hold_request", "resume")]
    assert kinds == ["hold_request", "resume", "hold_request", "resume"]
    assert ctl.executed_texts()[-1] == "M30" and ctl.alarm == ""


@pytest.mark.faults
def test_q_holds_the_feed_then_resets_cleanly(rig) -> None:
    ctl, clock, sender = rig
    sender.wait_line(r"^sending ")
    _wait_state(ctl, "Run")
    sender.key("q")
    sender.wait_line(r"abort \(key 'q'\)")
    rc, out = sender.finish()
    assert rc == 2, sender.seen
    doc = json.loads(out)
    assert not doc["ok"] and doc["operator_actions"][0]["action"] == "abort"
    assert any("stopped by the operator (key 'q')" in ln for ln in sender.seen), sender.seen
    kinds = [e.kind for e in ctl.events]
    # feed hold first, then the reset once held: no ALARM:3 (a reset in motion)
    assert "hold_request" in kinds and "reset" in kinds
    assert kinds.index("hold_request") < kinds.index("reset")
    assert ctl.alarm == "" and "alarm" not in kinds
