"""Lost answers in a GRBL stream: a lost or garbled ``ok`` leaves the character count short
forever.

It is declared only from GRBL's own state, never from a count alone: Idle (or Hold:0, with Bf)
with nothing in its planner while lines are unanswered, report after report for
``lost_ok_confirm_s`` (1 s) -- at the end, with its receive buffer empty; mid-stream, with a line
that had wholly reached it before the ``?`` unanswered and out of its buffer (Bf, ``$10=3``) or,
without Bf, already run (the machine stands Idle at the end of its move: GRBL answers a line
before it runs it). The stream then holds and resets (:meth:`~rig.dnc.grbl.GrblStreamer.halt`)
and stops (fault ``lost-ok``) naming the last block known executed. A report whose Bf makes a
lost answer likely, or a line of noise, pauses sending: once every line sent is answered it goes
on (nothing was lost); if neither that nor the fault comes within ``pause_timeout_s`` (10 s) the
stream is halted (``timeout``) stating GRBL's state.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Any

import numpy as np

from rig.dnc._stream import Fault, Item
from rig.dnc.grbl_status import GrblStatus


class LostAnswers:
    """The lost-answer watch of one stream of ``s`` (made fresh for each stream)."""

    def __init__(self, s: Any) -> None:  # its GrblStreamer (rig.dnc.grbl imports this module)
        self.s = s
        self.suspect = ""  # why the answers no longer match the lines (sending paused)
        self.pause_since: float | None = None
        self.drift_reports = 0
        self.idle_hits: tuple[float, int] | None = None  # (since, reports): see check
        self.lost_since: float | None = None
        self.lost_reports = 0

    def pause(self, why: str) -> None:
        """Stop sending until every line sent is answered (then go on: nothing was lost) or GRBL
        stands Idle with empty buffers (an answer was lost); :meth:`check_pause` keeps it
        within ``pause_timeout_s``."""
        self.suspect = why
        self.pause_since = time.perf_counter()
        self.s.sink.event("paused", self.s.clock(), f"sending paused: {why}")

    def check_pause(self, inflight: deque, heard: list[float]) -> None:
        now = time.perf_counter()
        if not inflight:  # every line sent was answered: the count is right, go on
            self.s.sink.event(
                "resumed", self.s.clock(), f"every line answered; was: {self.suspect}"
            )
            self.suspect = ""
            self.pause_since = None
            self.drift_reports = 0
            return
        st = self.s.last_status
        if self.pause_since is None or (st is not None and st.state in ("Hold", "Door")):
            self.pause_since = now  # an operator's hold is not the streamer's pause
            return
        if now - self.pause_since <= self.s.pause_timeout_s:
            return
        state = "no status report"
        if st is not None:
            state = st.full_state
            if st.planner_free is not None:
                state += f", Bf {st.planner_free},{st.rx_free}"
        reason = (
            f"sending paused for {self.s.pause_timeout_s:g} s ({self.suspect}) and in that time "
            f"neither did the {len(inflight)} unanswered line(s) get their answers nor did GRBL "
            f"stand Idle with empty buffers (GRBL: {state})"
        )
        raise Fault(
            "timeout", reason + "; " + self.s.halt(reset=self.s.reset_after_halt, heard=heard)
        )

    def check(self, inflight: deque, items: list[Item], st: GrblStatus, heard: list[float]) -> None:
        """A report may make a lost answer *likely* (Bf: GRBL's receive buffer holds less than
        had reached it unanswered): sending pauses. Only GRBL's state *shows* it: Idle (or
        Hold:0) with nothing in the planner nor the receive buffer while lines are unanswered,
        report after report for ``lost_ok_confirm_s``: the fault, after a feed hold."""
        now = time.perf_counter()
        s_q = self.s._rx.report_written
        if st.rx_free is not None and self.s._rx_cap and inflight and s_q is not None:
            self._drift(inflight, st, s_q)
        pause_line = False
        if inflight and self.s._results:
            r0 = self.s._results[inflight[0][0]]
            pause_line = r0 is not None and r0.program_flow == "pause"  # M0: Hold:0 till ~
        cap = self.s._planner_cap
        stopped = st.state == "Idle" or (
            st.full_state == "Hold:0" and st.planner_free is not None and cap is not None
            and not pause_line
        )  # fmt: skip
        planner_empty = st.planner_free is None or cap is None or st.planner_free >= cap
        res = self.s._results[inflight[0][0]] if inflight and self.s._results else None
        dwell = res.dwell_s if res is not None and res.dwell_s else 0.0
        bf = st.rx_free is not None and st.planner_free is not None and bool(self.s._rx_cap)
        if stopped and planner_empty and s_q is not None:
            # Mid-stream (needs Bf, $10=3): GRBL stands with an empty planner, yet the oldest
            # unanswered line had wholly reached it before the '?' and is not in its receive
            # buffer. Busy with it (out of the buffer, not planned yet) lasts milliseconds;
            # seen at every such report spanning lost_ok_confirm_s (and a dwell), an answer is
            # missing: after a lost ok each later ok is taken for the line before its own, so
            # one line too many stays unanswered whichever it is. (A starved GRBL goes Idle
            # between lines while the stream goes on: the wait for silence below would come
            # only at the end.)
            # Without Bf ($10=1): the machine stands Idle at the end of that line's move, so it
            # ran it, and GRBL answers a line before it runs it.
            hit = False
            if inflight and inflight[0][3] <= s_q:
                n0 = inflight[0][1]
                arrived = sum(min(n, max(0, s_q - (end - n))) for _, n, _, end in inflight)
                if bf:
                    hit = self.s._rx_cap - st.rx_free <= arrived - n0 + 1  # type: ignore[operator]
                else:
                    hit = st.state == "Idle" and self.ran(inflight[0][0], st)
            if not hit:
                self.idle_hits = None
            else:
                since, n_rep = self.idle_hits or (now, 0)
                self.idle_hits = (since, n_rep + 1)
                if n_rep + 1 >= 3 and now - since >= self.s.lost_ok_confirm_s + dwell:
                    upto = max(k for k, _, _, end in inflight if end <= s_q)
                    self.fault(inflight, items, st, heard, arrived_upto=upto)
        empty = (
            stopped
            and planner_empty
            and (st.rx_free is None or st.rx_free >= (self.s._rx_cap or 128) - 1)
        )
        if not inflight or not empty:
            self.lost_since = None
            return
        # the line time of what is outstanding, and a dwell under way, are allowed for
        wait = self.s.lost_ok_confirm_s
        nbytes = sum(n for _, n, _, _ in inflight)
        wait += nbytes * 10.0 / max(self.s.cfg.baudrate, 1) + dwell
        if now - self.s._last_io < wait:
            return
        if self.lost_since is None:
            self.lost_since = now
            self.lost_reports = 0
        self.lost_reports += 1
        if now - self.lost_since < self.s.lost_ok_confirm_s or self.lost_reports < 3:
            return
        self.fault(inflight, items, st, heard)

    def _drift(self, inflight: deque, st: GrblStatus, s_q: int) -> None:
        """Bf: GRBL's receive buffer holds less than had reached it unanswered, 3 reports in a
        row: an answer may have been lost (sending pauses)."""
        # The unanswered bytes written before the '?' this report answers had all reached
        # GRBL when it made the report (one byte stream, in order); bytes written after it
        # may still be on the wire and are not counted. GRBL holds them in its receive
        # buffer, except the line it is busy with or reading (the oldest unanswered, if
        # nothing was lost); 1 byte of margin (1.1h's count of a wrapped ring is one short).
        arrived = sum(min(n, max(0, s_q - (end - n))) for _, n, _, end in inflight)
        held = self.s._rx_cap - st.rx_free  # type: ignore[operator]  # both set: see check
        if arrived - held - inflight[0][1] - 1 > 0:
            self.drift_reports += 1
            if self.drift_reports >= 3 and not self.suspect:
                self.pause(
                    f"GRBL's receive buffer held {held} bytes when {arrived} unanswered bytes "
                    "had reached it, 3 reports in a row: an answer may have been lost"
                )
        else:
            self.drift_reports = 0

    def ran(self, k: int, st: GrblStatus) -> bool:
        """The machine stands at the end of line ``k``'s move, away from its start."""
        tr = self.s.tracker
        pos = self.s._work_pos(st)
        if tr is None or pos is None or not 0 <= k < len(tr.paths) or not tr.paths[k].moves:
            return False
        pts = tr.paths[k].points
        p = np.asarray(pos, float)
        return bool(
            np.linalg.norm(pts[-1] - p) <= tr.tol_mm and np.linalg.norm(pts[0] - p) > 2 * tr.tol_mm
        )

    def fault(
        self,
        inflight: deque,
        items: list[Item],
        st: GrblStatus,
        heard: list[float],
        arrived_upto: int | None = None,
    ) -> None:
        """The lost-answer fault; ``arrived_upto``: mid-stream, the last line known to have
        reached GRBL (the lines after it may be on the wire; the halt's reset discards them)."""
        last = items[self.s._sent_pos] if arrived_upto is None else items[arrived_upto]
        upto_pos = self.s._sent_pos if arrived_upto is None else arrived_upto
        tr = self.s.tracker
        pos = self.s._work_pos(st)
        known = -1
        if tr is not None and pos is not None:
            # GRBL processed every line that reached it: the last one whose move ends where the
            # machine stands, and all before it, ran (an answer lost might have been an error:N)
            j = tr.line_ending_at(pos, range(upto_pos + 1))
            if j >= 0:
                known = j
                tr.finish_all(j, self.s.clock())
                self.s._executing(tr.pop_started(), tr.current, tr.done)
        why = f" ({self.suspect})" if self.suspect else ""
        where = ""
        if pos is not None:
            where = f"; the machine stands at X{pos[0]:.3f} Y{pos[1]:.3f} Z{pos[2]:.3f}"
            if known >= 0:
                b = items[known].block
                where += f", the end of block {b}" if b >= 0 else ", the end of the preamble"
        upto = f"up to block {last.block}" if last.block >= 0 else "of the restart preamble"
        if arrived_upto is None:
            reason = (
                f"GRBL is {st.full_state} with empty buffers, so it has processed every line sent "
                f"({upto}), but {len(inflight)} answer(s) never came: lost or garbled on the line"
                f"{why}; which line they belonged to cannot be told{where}; nothing more was sent"
            )
        else:
            reason = (
                f"GRBL stood {st.full_state} with an empty planner, report after report, while a "
                f"line that had reached it stayed unanswered, so it had processed the lines "
                f"{upto} but an answer never came: lost or garbled on the line{why}; "
                f"which line it belonged to cannot be told{where}; sending stopped, and the "
                "lines still on their way are discarded by the reset"
            )
        raise Fault(
            "lost-ok", reason + "; " + self.s.halt(reset=self.s.reset_after_halt, heard=heard)
        )
