"""GRBL 1.1 streaming: send-response or character counting, real-time commands, status reports,
the executing block, lost answers, clean halts.

Before the first byte (nothing is sent if any line would be refused):

- every line is sent as :func:`planning.nc.grbl.grbl_send_text` leaves it (``strip``, default
  on): comments, spaces, the N word and a lone O program number are left out, as GRBL discards
  them anyway (it counts them in its 128-byte receive buffer but not in its 80-character line
  buffer; a ``!`` ``~`` ``?`` in a comment would even act as a real-time command). What was left
  out is in the result (``transform``, ``bytes_stripped``) and the record's ``stream_start``
  event;
- the whole program and the lines as they will be sent are checked against GRBL 1.1h
  (:func:`planning.nc.dialect.check_dialect`, gcode.c's rules): a line GRBL would answer
  ``error:N`` (O word, M6, G41, a long line, ``G2`` without axis words...) refuses the program,
  with the full list of such lines.

Modes:

- ``"send-response"``: one line out, wait for its ``ok``/``error:N``; simple, slower.
- ``"char-counting"`` (default): keep as many lines in flight as GRBL's serial receive buffer holds
  (``rx_buffer_bytes``, 127 of its 128 bytes), counting the bytes of every line not yet answered.

``ok`` means *planned*: the acknowledged line runs up to 15 planner blocks ahead of the one the
machine cuts. The status reports (``?`` polled ``status_hz`` times a second) are parsed
(:func:`parse_status`: state, MPos/WPos, WCO, Bf, Ln, FS, Ov, Pn, A) and give the *executing*
block (:class:`rig.dnc.execution.ExecTracker`: the position against each line's path, bounded
by the planner count Bf when ``$10`` reports it). The record's rows carry the acknowledgement
time and the execution start; the result both blocks; the progress bar both.

Bytes written are not in GRBL's receive buffer at once: they may still be on the wire (2.5 ms
for a 29-byte line at 115200 baud, more in a USB adapter). Every ``?`` is noted with the bytes
written before it; its report was made after those arrived (one byte stream, in order), so a
report's ``Bf`` is compared with those bytes only, never with what is unanswered now.

A lost or garbled ``ok`` (line noise) leaves the character count short forever; it is declared
only from GRBL's own state, never from a count alone (:mod:`rig.dnc.grbl_lost`).

Overrides (:meth:`GrblStreamer.override`, :meth:`~GrblStreamer.feed_override_pct`,
:meth:`~GrblStreamer.spindle_override_pct`, from any thread while a stream runs): one GRBL 1.1
real-time byte each (feed 0x90 100 %, 0x91/0x92 +-10 %, 0x93/0x94 +-1 %; rapid 0x95-0x97 100/50/
25 %; spindle 0x99 100 %, 0x9A/0x9B +-10 %, 0x9C/0x9D +-1 %; feed and spindle 10-200 %), written
at once past the pacing and the character count (GRBL takes them out of the stream on arrival,
they never enter its receive buffer), each recorded with its time (``override_log``, the sink's
``override`` events). ``overrides`` is the last ``Ov:`` GRBL reported (it sends it in the report
after a change, else every 10-20 reports).

Every wait has a deadline: the handshake as a whole within ``timeout_s``; otherwise silence
(:mod:`rig.dnc.grbl_receive`: nothing that shows GRBL at work) for ``timeout_s`` is a ``timeout``.

Halting: :meth:`GrblStreamer.halt` sends feed hold ``!``, waits for ``Hold:0`` (the motion has
stopped), then, with ``reset``, soft reset 0x18: GRBL ends Idle, without the ``ALARM:3`` a reset
in motion gives. It runs on ``error:N`` (``halt_on_error``) and when the stream is interrupted
(:meth:`~GrblStreamer.interrupt`, from Ctrl-C / SIGTERM / SIGHUP via
:func:`rig.dnc.guard.halt_on_signals`, which sends ``!`` at once). A crash of the streamer sends
``!`` on its way out; ``guard`` adds a watchdog process that sends it if this process dies.

``ALARM:N`` mid-stream stops the stream with the alarm's name and what to do (hard/soft limits:
GRBL answers nothing until a soft reset, ``cutlab dnc reset``, then ``cutlab dnc unlock``).
"""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Any

from analysis.config import MachineConfig, SerialConfig
from planning.nc.grbl import GRBL_ERRORS, GRBL_PLANNER_BLOCKS
from rig.dnc._stream import Fault, Item, StreamerBase
from rig.dnc.errors import DncError
from rig.dnc.execution import ExecTracker, line_paths
from rig.dnc.grbl_check import (  # noqa: F401 - check_line: importable from here
    GRBL_RX_BUFFER_BYTES,
    TRANSFORM,
    check_line,
    prepare_lines,
)
from rig.dnc.grbl_halt import (  # noqa: F401 - the real-time bytes, importable from here
    CYCLE_START,
    FEED_HOLD,
    HANDSHAKE,
    SOFT_RESET,
    STATUS,
    GrblControl,
)
from rig.dnc.grbl_lost import LostAnswers
from rig.dnc.grbl_overrides import (  # noqa: F401 - override_bytes: importable from here
    OVERRIDE_BYTES,
    OverrideState,
    override_bytes,
)
from rig.dnc.grbl_poll import StatusPoller
from rig.dnc.grbl_receive import GrblReceiver, is_answer
from rig.dnc.grbl_status import GrblStatus, parse_status  # noqa: F401 - importable from here
from rig.dnc.grbl_window import Window
from rig.dnc.link import LinkLost, LinkTimeout, SerialLink
from rig.dnc.program import Program
from rig.dnc.record import BlockRow

MODES = ("char-counting", "send-response")


class GrblStreamer(StreamerBase):
    """Stream a program to GRBL (see the module docstring).

    mode : ``"char-counting"`` or ``"send-response"``
    rx_buffer_bytes : what character counting may have in GRBL's receive buffer (127)
    status_hz : status polls per wall second (0: none; then no executing block, no lost-answer
        detection: silence for ``timeout_s`` is the only limit); per simulated second under the
        simulated rig's ``lockstep``
    wait_idle : after the last ``ok``, wait until GRBL reports ``Idle`` (the motion has run)
    unlock : if GRBL is in ``Alarm`` at the start, send ``$X`` (else that is a fault)
    halt_on_error : on ``error:N``, halt (feed hold, Hold:0, soft reset) so nothing after it runs
    strip : send lines without comments, spaces, N words and lone O words (see the module doc)
    lost_ok_confirm_s : how long GRBL must stay Idle with empty buffers while lines are unanswered
        before the answers count as lost (wall s)
    pause_timeout_s : sending paused on a suspected lost answer (a noise line, the Bf count)
        resumes once every line sent is answered; if neither that nor GRBL standing Idle with
        empty buffers (the lost-answer fault) happens within this time, the stream is halted
        (``timeout``; wall s)
    halt_timeout_s : how long a halt waits for Hold:0 and for the reset's banner (wall s)
    reset_after_halt : a halt ends with a soft reset (GRBL Idle, buffers flushed); False: held
    guard : a watchdog process sends ``!`` if this process dies while streaming (device ports)
    machine : for the executing-block paths (rapid rate, arc tolerance); optional
    stream_kw : sink, clock, pace_bytes_per_s, progress of :class:`StreamerBase`
    """

    protocol = "grbl"

    def __init__(
        self,
        cfg: SerialConfig,
        *,
        mode: str = "char-counting",
        rx_buffer_bytes: int = GRBL_RX_BUFFER_BYTES,
        status_hz: float = 5.0,
        wait_idle: bool = True,
        unlock: bool = False,
        halt_on_error: bool = True,
        strip: bool = True,
        lost_ok_confirm_s: float = 1.0,
        pause_timeout_s: float = 10.0,
        halt_timeout_s: float = 10.0,
        reset_after_halt: bool = True,
        guard: bool = False,
        machine: MachineConfig | None = None,
        **stream_kw: Any,
    ) -> None:
        if mode not in MODES:
            raise DncError(f"GRBL mode = {mode!r}: unknown; expected one of {', '.join(MODES)}")
        if not 16 <= rx_buffer_bytes <= 65536:
            raise DncError(f"rx_buffer_bytes = {rx_buffer_bytes}: expected 16..65536 bytes")
        super().__init__(cfg, **stream_kw)
        self.mode = mode
        self.rx_buffer_bytes = rx_buffer_bytes
        self.status_hz = status_hz
        self.wait_idle = wait_idle
        self.unlock = unlock
        self.halt_on_error = halt_on_error
        self.strip = strip
        self.lost_ok_confirm_s = lost_ok_confirm_s
        self.pause_timeout_s = pause_timeout_s
        self.halt_timeout_s = halt_timeout_s
        self.reset_after_halt = reset_after_halt
        self.guard = guard
        self.machine = machine
        self.last_status: GrblStatus | None = None
        self.messages: list[str] = []
        self.garbled: list[str] = []
        self.halt_report = ""
        self.tracker: ExecTracker | None = None
        self._streaming = threading.Event()
        self._guard_proc: Any = None
        self._ovr = OverrideState()  # kept from one stream to the next, as GRBL keeps them
        #: (stream clock s, byte) of every override byte written, in order
        self.override_log = self._ovr.log
        self._ctl = GrblControl(self)
        #: the simulated rig's lockstep (rig.sim._grbl_lockstep.StreamerPeer, set by its session;
        #: None on a real port): the status poll then runs on the simulated clock
        self.lockstep: Any = None
        self._begin()

    # -- real-time commands (any thread) ---------------------------------------------------------
    def _rt(self, cmd: bytes) -> None:
        if self.link is None:
            raise DncError("GRBL real-time command before the stream opened the port")
        try:
            self._write_rt(self.link, cmd)
        except (LinkLost, LinkTimeout) as exc:
            raise DncError(f"GRBL real-time command {cmd!r} not sent: {exc}") from None

    def _rt_safe(self, cmd: bytes) -> bool:
        try:
            if self.link is not None:
                self._write_rt(self.link, cmd)
                return True
        except (LinkLost, LinkTimeout, OSError):
            pass
        return False

    def _write_rt(self, link: SerialLink, cmd: bytes) -> None:
        if cmd == STATUS:
            # What had been written when this '?' went out: it reaches GRBL behind those bytes
            # (one byte stream), so the report it brings back was made after they arrived.
            # Taken before the write: a line being written meanwhile counts as not yet sent,
            # which can only make a lost answer look less likely, never more.
            self._rx.queries.append(link.bytes_written)
        link.write_now(cmd)
        if cmd == SOFT_RESET:
            self._ovr.after_reset()

    def feed_hold(self) -> None:
        self._rt(FEED_HOLD)

    def cycle_start(self) -> None:
        self._resume_t = self.clock()
        self._rt(CYCLE_START)

    def status(self) -> None:
        self._rt(STATUS)

    def soft_reset(self) -> None:
        self._rt(SOFT_RESET)

    # -- overrides (any thread; the bytes bypass the receive buffer and the character count) ----
    def override(self, code: int) -> None:
        """Write one GRBL 1.1 real-time override byte (:data:`OVERRIDE_BYTES`) now, and record
        it: ``override_log`` and the sink's ``override`` event, on the stream clock."""
        if isinstance(code, bool) or not isinstance(code, int) or code not in OVERRIDE_BYTES:
            raise ValueError(f"GRBL override byte {code!r}: expected one of 0x90-0x97, 0x99-0x9D")
        with self._ovr.lock:
            t = self.clock()  # before the write: the byte cannot arrive before its time
            self._rt(bytes([code]))
            if self.lockstep is not None:  # read before the simulated clock moves on
                self.lockstep.settle()
            self._ovr.wrote(t, code)
            if not self.sink_closed():
                with contextlib.suppress(ValueError, DncError):  # closed meanwhile
                    self.sink.event("override", t, f"0x{code:02X} {OVERRIDE_BYTES[code]}")

    @property
    def overrides(self) -> tuple[int, int, int] | None:
        """The last (feed %, rapid %, spindle %) GRBL reported (``Ov:``), None before any."""
        return self._ovr.reported

    def feed_override_pct(self, target: int) -> None:
        """Send the fewest bytes taking the feed override to ``target`` % (clamped to 10-200)
        from the last known or commanded value; returns once they are written."""
        self._override_to("feed", target)

    def spindle_override_pct(self, target: int) -> None:
        """As :meth:`feed_override_pct` for the spindle override (10-200 %)."""
        self._override_to("spindle", target)

    def _override_to(self, which: str, target: int) -> None:
        with self._ovr.lock:
            for code in self._ovr.bytes_to(which, target):
                self.override(code)

    def _on_interrupt(self) -> None:
        self._rt_safe(FEED_HOLD)  # first of all: the machine stops

    def _begin(self) -> None:
        self._rx = GrblReceiver(self)  # what GRBL sends, fresh for each stream
        self._lost = LostAnswers(self)
        self._extra_wait_s = 0.0  # a dwell under way lengthens the silence allowed
        self._hold_t0: float | None = None  # first report of a hold under way
        self._resume_t = -float("inf")  # the last cycle start sent, stream clock
        self._reports = self._starved_reports = 0
        self._seen_run = False
        self.last_status = None
        self.garbled = []
        self.halt_report = ""
        self._wco: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._planner_cap: int | None = None
        self._rx_cap: int | None = None
        self._acked_pos = -1
        self._sent_pos = -1
        self._last_io = time.perf_counter()
        self._results: list[Any] = []
        self.tracker = None
        self._tracking = True

    # -- before the port opens ---------------------------------------------------------------------
    def _prepare(self, program: Program, items: list[Item]) -> list[Item]:
        out, self._results, stripped, refusals = prepare_lines(
            program, items, strip=self.strip, rx_buffer_bytes=self.rx_buffer_bytes
        )
        if self.strip:
            self.transform, self.bytes_stripped = TRANSFORM, stripped
        if refusals:
            raise DncError(
                f"{program.name}: GRBL 1.1h would refuse {len(refusals)} line(s); nothing was "
                "sent:\n" + "\n".join(refusals)
            )
        return out

    # -- link --------------------------------------------------------------------------------------
    def _make_link(self) -> SerialLink:
        ser = self._serial()
        if self.guard:
            from rig.dnc.guard import HoldGuard

            self._guard_proc = HoldGuard.start_for(ser)
        return SerialLink(ser, pace_bytes_per_s=self.pace, on_data=self._rx.on_data)

    def _work_pos(self, st: GrblStatus) -> tuple[float, float, float] | None:
        if st.wpos_mm is not None:
            return st.wpos_mm
        if st.mpos_mm is not None:
            return (
                st.mpos_mm[0] - self._wco[0],
                st.mpos_mm[1] - self._wco[1],
                st.mpos_mm[2] - self._wco[2],
            )
        return None

    # -- the stream --------------------------------------------------------------------------------
    def _run(self, link: SerialLink, items: list[Item]) -> None:
        poller = StatusPoller(self).start() if self.status_hz > 0 else None
        clean = False
        try:
            self._ctl.handshake()
            self._make_tracker(items)
            self._stream(items)
            clean = True
        except Fault:
            clean = True  # the fault path has halted as it should
            raise
        finally:
            if not clean:  # a crash of the streamer itself (or a second Ctrl-C): hold first
                self._rt_safe(FEED_HOLD)
            if poller is not None:
                poller.stop()
            if self._reports:
                self.starved_fraction = self._starved_reports / self._reports
            if self._guard_proc is not None:
                self._guard_proc.release(hold=not clean)
                self._guard_proc = None

    def _make_tracker(self, items: list[Item]) -> None:
        start = (0.0, 0.0, 0.0)
        if self.last_status is not None:
            p = self._work_pos(self.last_status)
            if p is not None:
                start = p
        rapid = getattr(self.machine, "rapid_mm_min", None) or 5000.0
        paths = line_paths([it.text for it in items], start, rapid_mm_min=rapid)
        blocks = [r.planner_blocks if r is not None else 0 for r in self._results]
        if len(blocks) != len(items):
            blocks = None  # type: ignore[assignment]
        cap = self._planner_cap if self._planner_cap is not None else GRBL_PLANNER_BLOCKS
        self.tracker = ExecTracker(paths, blocks, cap)

    def _track(self, t: float, st: GrblStatus) -> None:
        tr = self.tracker
        if tr is None or not self._tracking:  # after a reset Idle means flushed, not done
            return
        # While GRBL reports Hold no line starts: the time is left out of the start times
        # interpolated between two reports (it ends at the cycle start, if this streamer sent it)
        if st.state in ("Hold", "Door"):
            if self._hold_t0 is None:
                self._hold_t0 = t
            tr.hold(self._hold_t0, t)
        elif self._hold_t0 is not None:
            tr.hold(self._hold_t0, min(max(self._resume_t, self._hold_t0), t))
            self._hold_t0 = None
        tr.update(t, st.state, self._work_pos(st), self._acked_pos, st.planner_free,
                  self._sent_pos)  # fmt: skip
        self._executing(tr.pop_started(), tr.current, tr.done)

    def _stream(self, items: list[Item]) -> None:
        w = Window(items, self.mode == "char-counting", self.rx_buffer_bytes)
        heard = [time.perf_counter()]
        self._streaming.set()
        self._last_io = time.perf_counter()
        try:
            while w.more():
                self._check_interrupt()
                if self._lost.suspect:
                    self._lost.check_pause(w.inflight, heard)
                self._fill(w)
                # a dwell under way answers after it: its time is not silence
                r0 = self._results[w.inflight[0][0]] if w.inflight and self._results else None
                self._extra_wait_s = r0.dwell_s if r0 is not None and r0.dwell_s else 0.0
                ev = self._rx.get(heard)
                if ev is None:
                    continue
                t_ans, line = ev
                if line.startswith("<"):
                    if self.last_status is not None:
                        self._track(t_ans, self.last_status)
                        self._lost.check(w.inflight, items, self.last_status, heard)
                elif is_answer(line):
                    self._on_answer(w, t_ans, line, heard)
                else:
                    self._on_other_line(w, line)
            self._streaming.clear()
            if self.wait_idle:
                self._ctl.wait_idle(heard)
        except Fault as f:
            if f.kind in ("interrupted", "stopped"):
                f.reason += "; " + self.halt(reset=self.reset_after_halt, heard=heard)
            elif f.kind == "timeout" and not self.halt_report:  # (a stalled pause has halted)
                self._rt_safe(FEED_HOLD)  # whatever it is doing, it should not go on
            raise
        finally:
            self._streaming.clear()
            for pos, n, t, _ in w.inflight:
                it = items[pos]
                self._answered(pos, BlockRow(it.block, it.line, it.text, n, t,
                                             status="unacknowledged"))  # fmt: skip

    def _fill(self, w: Window) -> None:
        """Send what the window takes now (nothing while sending is paused)."""
        link = self.link
        assert link is not None
        while not self._lost.suspect and (data := w.next_data()) is not None:
            self._check_interrupt()
            t = self.clock()
            self._write(data)
            it = w.sent(len(data), t, link.bytes_written)
            self.blocks_sent += 1
            self._sent_pos = w.next - 1
            self._last_io = time.perf_counter()
            self._lost.lost_since = None
            if it.block >= 0:
                self.last_sent_block = it.block

    def _on_answer(self, w: Window, t_ans: float, line: str, heard: list[float]) -> None:
        """``ok`` or ``error:N``: the oldest line in flight's (an error halts and faults)."""
        self._lost.lost_since = None
        self._last_io = time.perf_counter()
        if not w.inflight:
            self.messages.append(line)
            return
        pos, n, t_send = w.answered()
        it = w.items[pos]
        status = line if line.startswith("error") else "ok"
        self._answered(pos, BlockRow(it.block, it.line, it.text, n, t_send, t_ans, status))
        if status != "ok":
            code = int(line.split(":")[1]) if line[6:].isdigit() else -1
            why = GRBL_ERRORS.get(code, "")
            where = f"block {it.block} (line {it.line})" if it.block >= 0 else (
                "the restart preamble")  # fmt: skip
            reason = f"{line} ({why}) for {where}: {it.text}"
            if self.halt_on_error:
                reason += "; " + self.halt(reset=self.reset_after_halt, heard=heard)
            raise Fault("error", reason)
        self._acked_pos = pos
        if self.tracker is not None:
            self.tracker.set_origin(t_ans)
        if it.block >= 0:
            self.last_ack_block = it.block

    def _on_other_line(self, w: Window, line: str) -> None:
        """Not a status report nor an answer: an alarm or a reset ends the stream; a message is
        kept; anything else is line noise (it may have been an answer: sending pauses)."""
        if line.startswith(("ALARM:", "Grbl")):
            self._tracking = False
        if line.startswith("ALARM:"):
            raise Fault("alarm", self._ctl.alarm_reason(line, "mid-stream"))
        if line.startswith("Grbl"):
            raise Fault(
                "reset",
                f"GRBL was reset mid-stream (banner {line!r}): the lines in its buffers "
                "were discarded",
            )
        if line.startswith(("[", "$", ">")):
            self.messages.append(line)
            return
        self.garbled.append(line)  # not a GRBL answer: line noise
        self.messages.append(line)
        if w.inflight and not self._lost.suspect:  # maybe an answer: stop sending, let it drain
            self._lost.pause(f"received {line!r}, not a GRBL answer (line noise)")

    def halt(self, reset: bool = True, heard: list[float] | None = None) -> str:
        """Feed hold, wait for Hold:0 (motion stopped), then with ``reset`` a soft reset (GRBL
        Idle, its buffers flushed, no alarm). Returns what happened, for the fault message; it
        never raises for GRBL's behaviour (only for a lost port, as a Fault)."""
        return self._ctl.halt(reset, heard)
