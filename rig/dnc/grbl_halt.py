"""The GRBL stream's handshake and its endings: waiting for a status report, for Idle after the
last ``ok``, and the clean halt.

Halting (:meth:`GrblControl.halt`) sends feed hold ``!``, waits for ``Hold:0`` (the motion has
stopped), then, with ``reset``, soft reset 0x18: GRBL ends Idle, without the ``ALARM:3`` a reset
in motion gives.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from planning.nc.grbl import grbl_alarm_text
from rig.dnc._stream import Fault
from rig.dnc.grbl_receive import is_answer
from rig.dnc.grbl_status import GrblStatus

FEED_HOLD, CYCLE_START, STATUS, SOFT_RESET = b"!", b"~", b"?", b"\x18"
HANDSHAKE = b"$G\n"  # what a stream sends first (see GrblControl.handshake)


class GrblControl:
    """Handshake, waits and halts of ``s``'s streams (no state of its own)."""

    def __init__(self, s: Any) -> None:  # its GrblStreamer (rig.dnc.grbl imports this module)
        self.s = s

    def handshake(self) -> None:
        heard = [time.perf_counter()]
        # "$G" (parser state) is answered "[GC:...]" then "ok" in every state (GRBL 1.1 refuses
        # "$I" and "$$" while running or held). Answers still on their way from an earlier
        # stream (error:9 for lines that arrived after an alarm, late oks) come before "[GC:" and
        # are dropped here: taken as this stream's, they would let the character counting
        # overfill GRBL's receive buffer.
        self.s._check_interrupt()
        # one deadline for the whole handshake: noise or status reports do not extend it
        deadline = time.perf_counter() + self.s.cfg.timeout_s
        self.s._write(HANDSHAKE)
        what = "$G (parser state)"
        while not (line := self.s._rx.next_line(heard, deadline, what)).startswith("[GC:"):
            pass  # stale answers of an earlier stream are dropped; alarms and messages are kept
        while not is_answer(line := self.s._rx.next_line(heard, deadline, what)):
            pass
        if line != "ok":
            raise Fault("error", f"GRBL answered $G (parser state) with {line}")
        try:
            st = self.wait_status(heard, lambda s: True, deadline)
        except TimeoutError:
            head = f"GRBL sent no status report within {self.s.cfg.timeout_s:g} s of '?'"
            raise Fault("timeout", self.s._rx.no_answer(head)) from None
        if st.planner_free is not None and st.state == "Idle":
            self.s._planner_cap = st.planner_free
            self.s._rx_cap = st.rx_free
        if st.state == "Alarm":
            if not self.s.unlock:
                raise Fault(
                    "alarm",
                    "GRBL is in its Alarm state (after an alarm or a reset in motion); check the "
                    "machine and its position, then unlock (cutlab dnc unlock, or --unlock)",
                )
            self.s._write(b"$X\n")
            deadline = time.perf_counter() + self.s.cfg.timeout_s
            while True:
                if time.perf_counter() > deadline:
                    head = f"GRBL did not answer $X within {self.s.cfg.timeout_s:g} s"
                    raise Fault("timeout", self.s._rx.no_answer(head))
                ev = self.s._rx.get(heard)
                if ev is None or ev[1].startswith("<"):
                    continue
                if is_answer(ev[1]):
                    break
                self.s.messages.append(ev[1])
            if ev[1] != "ok":
                raise Fault("alarm", f"GRBL refused to unlock: {ev[1]}")

    def wait_status(
        self,
        heard: list[float],
        ok: Callable[[GrblStatus], bool],
        deadline: float | None = None,
        on_line: Callable[[float, str], None] | None = None,
    ) -> GrblStatus:
        """Poll until a fresh status report satisfies ``ok``; lines that are not status reports
        go to ``on_line`` (default: kept in ``messages``; ALARM and a reset banner are faults).
        TimeoutError after ``deadline`` (perf_counter)."""
        self.s.last_status = None
        self.s._rt_safe(STATUS)
        last_poll = time.perf_counter()
        while True:
            if deadline is not None and time.perf_counter() > deadline:
                raise TimeoutError
            ev = self.s._rx.get(heard)
            now = time.perf_counter()
            if ev is None:
                # (in lockstep the poll runs on the simulated clock: no wall-timed extra '?')
                wall_repoll = now - last_poll > 1.0 and self.s.lockstep is None
                if self.s.status_hz <= 0 or wall_repoll:
                    self.s._rt_safe(STATUS)
                    last_poll = now
                continue
            t, line = ev
            if line.startswith("<"):
                st = self.s.last_status
                if st is None:
                    continue
                self.s._track(t, st)
                if ok(st):
                    return st
                if self.s.status_hz <= 0:
                    self.s._rt_safe(STATUS)
                continue
            if on_line is not None:
                on_line(t, line)
            elif line.startswith("ALARM:"):
                raise Fault("alarm", self.alarm_reason(line, "while finishing the motion"))
            else:
                self.s.messages.append(line)

    def wait_idle(self, heard: list[float]) -> None:
        """After the last ok: wait for a status report saying Idle (the motion has run)."""

        def on_line(t: float, line: str) -> None:
            if line.startswith(("ALARM:", "Grbl")):
                self.s._tracking = False
            if line.startswith("ALARM:"):
                raise Fault("alarm", self.alarm_reason(line, "while finishing the motion"))
            if line.startswith("Grbl"):
                raise Fault("reset", f"GRBL was reset while finishing the motion ({line!r})")
            self.s.messages.append(line)

        def idle(st: GrblStatus) -> bool:
            self.s._check_interrupt()
            return st.state == "Idle"

        self.wait_status(heard, idle, on_line=on_line)
        if self.s.tracker is not None:
            self.s.tracker.finish_all(self.s._acked_pos, self.s.clock())
            tr = self.s.tracker
            self.s._executing(tr.pop_started(), tr.current, tr.done)

    def halt(self, reset: bool = True, heard: list[float] | None = None) -> str:
        """Feed hold, wait for Hold:0 (motion stopped), then with ``reset`` a soft reset (GRBL
        Idle, its buffers flushed, no alarm). Returns what happened, for the fault message; it
        never raises for GRBL's behaviour (only for a lost port, as a Fault)."""
        heard = heard if heard is not None else [time.perf_counter()]
        self.s._rt_safe(FEED_HOLD)
        deadline = time.perf_counter() + self.s.halt_timeout_s
        lines: list[str] = []

        def keep(t: float, line: str) -> None:
            lines.append(line)

        idle_reports = [0]

        def stopped(s: GrblStatus) -> bool:
            # GRBL answers '!' with Hold, from Idle too (protocol.c), so an Idle read now may be
            # a report made before the hold arrived (a '?' in flight) over a decelerating
            # machine, where a reset is ALARM:3: Idle counts only when the next report says it too
            idle_reports[0] = idle_reports[0] + 1 if s.state == "Idle" else 0
            return s.full_state == "Hold:0" or s.state in ("Alarm", "Door") or idle_reports[0] >= 2

        try:
            st = self.wait_status(heard, stopped, deadline, on_line=keep)
        except TimeoutError:
            self.s.halt_report = (
                f"feed hold sent; GRBL did not report Hold:0 within {self.s.halt_timeout_s:g} s "
                "(not reset, to keep it from ALARM:3)"
            )
            return self.s.halt_report
        except Fault as f:
            if f.kind == "port-lost":
                raise
            self.s.halt_report = f"feed hold sent; then {f.reason}"
            return self.s.halt_report
        self.s.messages.extend(lines)
        if st.state == "Alarm":
            self.s.halt_report = "GRBL is in Alarm"
            return self.s.halt_report
        if not reset:
            self.s.halt_report = f"machine held ({st.full_state}); resume with cycle start (~)"
            return self.s.halt_report
        lines.clear()
        self.s._tracking = False  # what the reset flushes was not executed
        self.s._rt_safe(SOFT_RESET)
        try:
            st = self.wait_status(
                heard, lambda s: any(x.startswith("Grbl") for x in lines), deadline, on_line=keep
            )
        except (TimeoutError, Fault):
            self.s.halt_report = "feed hold, Hold:0, soft reset sent; no banner came back"
            return self.s.halt_report
        alarms = [x for x in lines if x.startswith("ALARM:")]
        self.s.messages.extend(lines)
        state = st.full_state
        if alarms:
            self.s.halt_report = f"feed hold, Hold:0, then reset: {alarms[0]} ({state})"
        else:
            self.s.halt_report = f"feed hold, Hold:0, then soft reset: GRBL {state}, no alarm"
        return self.s.halt_report

    def alarm_reason(self, line: str, when: str) -> str:
        try:
            code = int(line.split(":")[1])
        except (IndexError, ValueError):
            return f"{line} {when}"
        return f"{grbl_alarm_text(code)} ({line} {when}; GRBL discarded the lines in its buffers)"
