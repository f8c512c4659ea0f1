"""What GRBL sends, as the GRBL streamer reads it: the reader thread's lines, status reports
parsed (:func:`~rig.dnc.grbl_status.parse_status`), and which of them show GRBL at work.

Every wait has a deadline: nothing that shows GRBL at work (an answer, a message, a status report
that differs from the last or says Hold) for ``timeout_s`` is a ``timeout``: noise lines and a
repeated report keep no wait alive. A dwell's time is allowed for.
"""

from __future__ import annotations

import queue
import time
from collections import deque
from typing import Any

from rig.dnc._stream import Fault
from rig.dnc.errors import DncError
from rig.dnc.grbl_status import GrblStatus, parse_status

SILENT_HINT = (
    " (wrong port or baud rate? or GRBL is halted after a hard/soft limit alarm: it then answers "
    "nothing until a soft reset, cutlab dnc reset)"
)


def is_answer(line: str) -> bool:
    return line == "ok" or line.startswith("error:")


class GrblReceiver:
    """The receiving side of one stream of ``s`` (made fresh for each stream)."""

    def __init__(self, s: Any) -> None:  # its GrblStreamer (rig.dnc.grbl imports this module)
        self.s = s
        self.lines: queue.Queue[tuple[float, str]] = queue.Queue()
        self.partial = bytearray()
        self.queries: deque[int] = deque()  # bytes written before each '?' not yet answered
        self.report_written: int | None = None  # ... before the '?' of the last report
        self.alive_key: tuple[Any, ...] | None = None
        self.noise = self.noise_reports = 0
        self.noise_example = ""
        self.heard_any = False
        # for the simulated rig's lockstep (the streamer's ``lockstep``): bytes and lines read,
        # lines taken by the stream, and taken and handled (it came back for the next)
        self.bytes_in = self.put_n = self.taken_n = self.handled_n = 0

    def on_data(self, data: bytes) -> None:
        self.partial.extend(data)
        while True:
            i = self.partial.find(b"\n")
            if i < 0:
                self.bytes_in += len(data)  # once the lines it completes are queued
                return
            raw = bytes(self.partial[:i]).strip()
            del self.partial[: i + 1]
            if raw.startswith(b"<"):
                self.s._ovr.note_report(raw)
            if raw:
                self.put_n += 1
                self.lines.put((self.s.clock(), raw.decode("ascii", "replace")))

    def next_line(self, heard: list[float], deadline: float, what: str) -> str:
        """The next line GRBL sends that is not a status report; messages and alarms among them
        are kept in ``messages`` (answers are not). A ``timeout`` fault at ``deadline``
        (perf_counter) whatever arrives meanwhile (noise, status reports)."""
        while True:
            if time.perf_counter() > deadline:
                head = f"GRBL did not answer {what} within {self.s.cfg.timeout_s:g} s"
                raise Fault("timeout", self.no_answer(head))
            ev = self.get(heard)
            if ev is None:
                self.s._check_interrupt()
                continue
            line = ev[1]
            if line.startswith("<"):
                continue
            if not line.startswith("[GC:") and not is_answer(line):
                self.s.messages.append(line)
            return line

    def no_answer(self, head: str) -> str:
        """Why a wait ended (``head``), and what came instead of an answer (timeout fault)."""
        if self.noise:
            got = (f"{self.noise} line(s) that are not GRBL's (e.g. {self.noise_example!r}: "
                   "wrong baud rate, wrong device or line noise)")  # fmt: skip
        elif self.noise_reports:
            got = f"only status reports that did not change ({self.noise_reports})"
        elif self.heard_any:
            got = "no answer"
        else:
            got = "nothing" + SILENT_HINT
        return f"{head}: received {got}"

    def alive(self, line: str, st: GrblStatus | None) -> bool:
        """Does this line show GRBL at work? Answers and messages do; a status report does when
        it differs from the last one or says the machine is held (an operator's hold, a door);
        noise and a repeated report do not, so neither keeps a wait going for ever."""
        if st is None:
            return line.startswith(("ok", "error:", "ALARM:", "Grbl", "[", "$", ">"))
        if st.state in ("Hold", "Door", "Sleep", "Home"):
            return True
        key = (st.full_state, st.mpos_mm, st.wpos_mm, st.planner_free, st.rx_free)
        changed = key != self.alive_key
        self.alive_key = key
        return changed

    def get(self, heard: list[float], timeout: float = 0.05) -> tuple[float, str] | None:
        """Next line from GRBL or None after ``timeout``; faults on silence (nothing that shows
        GRBL at work, :meth:`alive`, for the serial timeout) or a lost port."""
        link = self.s.link
        assert link is not None
        if link.lost.is_set():
            raise Fault("port-lost", link.lost_reason)
        if time.perf_counter() - heard[0] > self.s.cfg.timeout_s + self.s._extra_wait_s:
            limit = self.s.cfg.timeout_s + self.s._extra_wait_s
            raise Fault("timeout", self.no_answer(f"no answer from GRBL for {limit:g} s"))
        self.handled_n = self.taken_n  # back for more: every line taken was handled
        if self.s.lockstep is not None:
            self.s.lockstep.idle()
        try:
            item = self.lines.get(timeout=timeout)
        except queue.Empty:
            return None
        self.taken_n += 1
        if item[1].startswith("<"):
            if self.queries:  # the i-th report answers at least the i-th '?'
                self.report_written = self.queries.popleft()
            try:
                st = parse_status(item[1])
            except DncError:
                self.s.garbled.append(item[1])
                return None
            if self.alive(item[1], st):
                heard[0] = time.perf_counter()
                self.heard_any = True
            else:
                self.noise_reports += 1
            self.s.last_status = st
            self.s.controller_state = st.full_state
            if st.wco_mm is not None:
                self.s._wco = st.wco_mm
            self.s._seen_run = self.s._seen_run or st.state in ("Run", "Hold")
            if self.s._streaming.is_set() and self.s._seen_run:
                self.s._reports += 1
                self.s._starved_reports += st.state == "Idle"
        elif self.alive(item[1], None):
            heard[0] = time.perf_counter()
            self.heard_any = True
        else:
            self.noise += 1
            self.noise_example = self.noise_example or item[1][:40]
        return item
