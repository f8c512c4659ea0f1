"""One-shot GRBL commands outside a stream: ``cutlab dnc unlock`` ($X), ``cutlab dnc reset`` (a
clean soft reset) and the state.

:func:`grbl_command` opens the port, asks for a status report (``?``) and then:

- ``"status"``: nothing more;
- ``"unlock"``: in the Alarm state, ``$X`` (GRBL answers ``[MSG:Caution: Unlocked]`` and ``ok``);
  otherwise nothing is sent;
- ``"reset"``: if GRBL is moving, feed hold ``!`` and wait for ``Hold:0`` first (a reset in motion
  is ``ALARM:3``, position lost); then soft reset 0x18, wait for the banner. A GRBL that answers
  nothing (halted after ``ALARM:1``/``ALARM:2``, which only a reset ends) is reset straight away.

The reply names the state before and after, and what GRBL printed (``[MSG:...]``, ``ALARM:N``).
"""

from __future__ import annotations

import queue
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypedDict

from analysis.config import SerialConfig
from planning.nc.grbl import grbl_alarm_text
from rig.dnc.errors import DncError
from rig.dnc.grbl import FEED_HOLD, SOFT_RESET, STATUS, GrblStatus, parse_status
from rig.dnc.link import LinkLost, SerialLink
from rig.dnc.port import check_settings, open_port

COMMANDS = ("status", "unlock", "reset")


class GrblReplyJson(TypedDict):
    """A GRBL console command's reply as JSON: :class:`GrblReply`'s fields, in order."""

    command: str
    state_before: str
    state_after: str
    lines: list[str]
    summary: str


@dataclass(frozen=True)
class GrblReply:
    """command; state_before / state_after ("" if GRBL gave no status report); lines: what GRBL
    printed besides status reports; summary: one line for people."""

    command: str
    state_before: str
    state_after: str
    lines: list[str] = field(default_factory=list)
    summary: str = ""

    def as_dict(self) -> GrblReplyJson:
        return {"command": self.command, "state_before": self.state_before,
                "state_after": self.state_after, "lines": self.lines,
                "summary": self.summary}  # fmt: skip

    def status_lines(self) -> list[str]:
        """What `cutlab dnc unlock|reset` says on stderr: GRBL's lines, then the summary."""
        return [*(f"grbl: {line}" for line in self.lines), self.summary]

    @property
    def ok(self) -> bool:
        """GRBL answered and is not in Alarm after the command."""
        return self.state_after not in ("", "Alarm")


class _Console:
    def __init__(self, cfg: SerialConfig) -> None:
        self.q: queue.Queue[str] = queue.Queue()
        self.buf = bytearray()
        port = open_port(cfg, "grbl")
        # Bytes GRBL sent before we opened (a status report the streamer asked for and never read)
        # are not answers to our requests: a stale '<Run|...>' would pass for a live machine.
        port.reset_input_buffer()
        self.link = SerialLink(port, on_data=self._on_data).start()
        self.lines: list[str] = []

    def _on_data(self, data: bytes) -> None:
        self.buf.extend(data)
        while (i := self.buf.find(b"\n")) >= 0:
            raw = bytes(self.buf[:i]).strip()
            del self.buf[: i + 1]
            if raw:
                self.q.put(raw.decode("ascii", "replace"))

    def rt(self, b: bytes) -> None:
        try:
            self.link.write_now(b)
        except LinkLost as exc:
            raise DncError(f"GRBL port lost: {exc}") from None

    def next_line(self, timeout: float) -> str | None:
        try:
            return self.q.get(timeout=timeout)
        except queue.Empty:
            return None

    def status(self, timeout: float) -> GrblStatus | None:
        """Ask ``?`` (again every 0.5 s) until a report comes, or None after ``timeout``."""
        end = time.perf_counter() + timeout
        last = 0.0
        while time.perf_counter() < end:
            if time.perf_counter() - last > 0.5:
                self.rt(STATUS)
                last = time.perf_counter()
            line = self.next_line(0.05)
            if line is None:
                continue
            if line.startswith("<"):
                try:
                    return parse_status(line)
                except DncError:
                    continue
            self.lines.append(line)
        return None

    def wait_line(self, pred: Callable[[str], bool], timeout: float) -> str | None:
        end = time.perf_counter() + timeout
        while time.perf_counter() < end:
            line = self.next_line(0.05)
            if line is None or line.startswith("<"):
                continue
            self.lines.append(line)
            if pred(line):
                return line
        return None

    def close(self) -> None:
        self.link.close()


def grbl_command(cfg: SerialConfig, command: str, timeout_s: float | None = None) -> GrblReply:
    """Run ``command`` (status, unlock, reset) on the GRBL at ``cfg.port`` (see the module doc).
    DncError if the port cannot be used; GRBL's own refusals are in the reply."""
    if command not in COMMANDS:
        raise DncError(f"GRBL command {command!r}: expected one of {', '.join(COMMANDS)}")
    check_settings(cfg, "grbl")
    wait = cfg.timeout_s if timeout_s is None else timeout_s
    con = _Console(cfg)
    try:
        st0 = con.status(min(wait, 3.0))
        before = st0.full_state if st0 is not None else ""
        if command == "status":
            if st0 is None:
                raise DncError(f"no status report from GRBL on {cfg.port} in {min(wait, 3.0):g} s")
            return GrblReply(command, before, before, con.lines, f"GRBL {before}")
        if command == "unlock":
            return _unlock(con, st0, wait)
        return _reset(con, st0, wait)
    finally:
        con.close()


def _unlock(con: _Console, st0: GrblStatus | None, wait: float) -> GrblReply:
    before = st0.full_state if st0 is not None else ""
    if st0 is None:
        raise DncError(
            "no status report from GRBL: if it is halted after a hard/soft limit alarm it answers "
            "nothing until a soft reset (cutlab dnc reset); otherwise check the port and baud"
        )
    if st0.state != "Alarm":
        return GrblReply("unlock", before, before, con.lines,
                         f"GRBL is {before}, not in Alarm: nothing to unlock")  # fmt: skip
    con.link.write(b"$X\n", wait)
    ans = con.wait_line(lambda x: x == "ok" or x.startswith("error:"), wait)
    st1 = con.status(wait)
    after = st1.full_state if st1 is not None else ""
    if ans != "ok":
        why = ans or f"no answer in {wait:g} s"
        return GrblReply("unlock", before, after, con.lines, f"GRBL refused $X: {why}")
    msg = f"GRBL unlocked ($X): {after}; check the machine position before moving"
    return GrblReply("unlock", before, after, con.lines, msg)


def _reset(con: _Console, st0: GrblStatus | None, wait: float) -> GrblReply:
    before = st0.full_state if st0 is not None else ""
    held = ""
    if st0 is not None and (st0.state in ("Run", "Jog", "Home") or st0.full_state == "Hold:1"):
        con.rt(FEED_HOLD)
        end = time.perf_counter() + wait
        idle = 0  # Idle twice: one may be a report from before the hold (rig.dnc.grbl_halt)
        while time.perf_counter() < end:
            st = con.status(max(0.1, end - time.perf_counter()))
            idle = idle + 1 if st is not None and st.state == "Idle" else 0
            if st is not None and (st.full_state == "Hold:0" or st.state == "Alarm" or idle >= 2):
                held = f"held first ({st.full_state}), "
                break
        else:
            return GrblReply("reset", before, before, con.lines,
                             f"feed hold sent but GRBL did not reach Hold:0 in {wait:g} s; not "
                             "reset (a reset in motion loses the position: ALARM:3)")  # fmt: skip
    con.rt(SOFT_RESET)
    banner = con.wait_line(lambda x: x.startswith("Grbl"), wait)
    if banner is None:
        return GrblReply("reset", before, "", con.lines,
                         f"soft reset sent; no banner from GRBL in {wait:g} s")  # fmt: skip
    con.wait_line(lambda x: False, 0.3)  # what follows the banner ([MSG:...])
    st1 = con.status(wait)
    after = st1.full_state if st1 is not None else ""
    alarms = [x for x in con.lines if x.startswith("ALARM:")]
    msg = f"GRBL {held}soft reset: {after or 'no status'}"
    if alarms:
        code = int(alarms[-1].split(":")[1]) if alarms[-1][6:].isdigit() else 0
        msg += f"; {grbl_alarm_text(code) if code else alarms[-1]}"
    elif after == "Alarm":
        msg += "; still locked (Alarm): check the machine, then cutlab dnc unlock"
    return GrblReply("reset", before, after, con.lines, msg)
