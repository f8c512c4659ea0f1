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

A lost or garbled ``ok`` (line noise) leaves the character count short forever. It is declared
only from GRBL's own state, never from a count alone: Idle (or Hold:0, with Bf) with nothing in
its planner while lines are unanswered, report after report for ``lost_ok_confirm_s`` (1 s) --
at the end, with its receive buffer empty; mid-stream, with a line that had wholly reached it
before the ``?`` unanswered and out of its buffer (Bf, ``$10=3``) or, without Bf, already run
(the machine stands Idle at the end of its move: GRBL answers a line before it runs it). The
stream then holds and resets (:meth:`~GrblStreamer.halt`) and stops (fault ``lost-ok``) naming
the last block known executed. A report whose Bf makes a lost answer likely, or a line of noise,
pauses sending: once every line sent is answered it goes on (nothing was lost); if neither that
nor the fault comes within ``pause_timeout_s`` (10 s) the stream is halted (``timeout``) stating
GRBL's state.

Overrides (:meth:`GrblStreamer.override`, :meth:`~GrblStreamer.feed_override_pct`,
:meth:`~GrblStreamer.spindle_override_pct`, from any thread while a stream runs): one GRBL 1.1
real-time byte each (feed 0x90 100 %, 0x91/0x92 +-10 %, 0x93/0x94 +-1 %; rapid 0x95-0x97 100/50/
25 %; spindle 0x99 100 %, 0x9A/0x9B +-10 %, 0x9C/0x9D +-1 %; feed and spindle 10-200 %), written
at once past the pacing and the character count (GRBL takes them out of the stream on arrival,
they never enter its receive buffer), each recorded with its time (``override_log``, the sink's
``override`` events). ``overrides`` is the last ``Ov:`` GRBL reported (it sends it in the report
after a change, else every 10-20 reports).

Every wait has a deadline: the handshake as a whole within ``timeout_s``; otherwise nothing that
shows GRBL at work (an answer, a message, a status report that differs from the last or says
Hold) for ``timeout_s`` is a ``timeout``: noise lines and a repeated report keep no wait alive.
A dwell's time is allowed for.

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
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from analysis.config import SerialConfig
from planning.nc.dialect import check_dialect, refused
from planning.nc.grbl import (
    GRBL_ERRORS,
    GRBL_PLANNER_BLOCKS,
    GrblParser,
    grbl_alarm_text,
    grbl_filter,
    grbl_send_text,
)
from rig.dnc._stream import Fault, Item, StreamerBase
from rig.dnc.errors import DncError
from rig.dnc.execution import ExecTracker, line_paths
from rig.dnc.grbl_check import GRBL_LINE_CHARS, GRBL_RX_BUFFER_BYTES, TRANSFORM, check_line  # noqa: F401
from rig.dnc.grbl_overrides import (
    _OVR_KEYS,
    FEED_OVR_RANGE_PCT,
    OVERRIDE_BYTES,
    OVR_SETTLE_S,
    SPINDLE_OVR_RANGE_PCT,
    _after_override,
    override_bytes,
)
from rig.dnc.grbl_status import GrblStatus, parse_status
from rig.dnc.link import LinkLost, LinkTimeout, SerialLink
from rig.dnc.program import Program
from rig.dnc.record import BlockRow

FEED_HOLD, CYCLE_START, STATUS, SOFT_RESET = b"!", b"~", b"?", b"\x18"
HANDSHAKE = b"$G\n"  # what a stream sends first (see GrblStreamer._handshake)
MODES = ("char-counting", "send-response")
SILENT_HINT = (
    " (wrong port or baud rate? or GRBL is halted after a hard/soft limit alarm: it then answers "
    "nothing until a soft reset, cutlab dnc reset)"
)


def _is_answer(line: str) -> bool:
    return line == "ok" or line.startswith("error:")


class GrblStreamer(StreamerBase):
    """Stream a program to GRBL (see the module docstring).

    mode : ``"char-counting"`` or ``"send-response"``
    rx_buffer_bytes : what character counting may have in GRBL's receive buffer (127)
    status_hz : status polls per wall second (0: none; then no executing block, no lost-answer
        detection: silence for ``timeout_s`` is the only limit)
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
        machine: Any = None,
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
        self._lines: queue.Queue[tuple[float, str]] = queue.Queue()
        self._partial = bytearray()
        self._streaming = threading.Event()
        self._guard_proc: Any = None
        #: (stream clock s, byte) of every override byte written, in order
        self.override_log: list[tuple[float, int]] = []
        self._ovr_lock = threading.RLock()
        self._ovr_reported: tuple[int, int, int] | None = None
        # what our bytes have made of the feed, rapid and spindle overrides (None: unknown
        # until an Ov: report or a reset; GRBL keeps them from one program to the next)
        self._ovr_cmd: list[int | None] = [None, None, None]
        self._ovr_written_t = -float("inf")  # perf_counter of the last override byte
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
            self._queries.append(link.bytes_written)
        link.write_now(cmd)
        if cmd == SOFT_RESET:
            with self._ovr_lock:
                self._ovr_cmd = [100, 100, 100]  # main.c: a reset restores the defaults

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
        with self._ovr_lock:
            t = self.clock()  # before the write: the byte cannot arrive before its time
            self._rt(bytes([code]))
            self._ovr_written_t = time.perf_counter()
            self.override_log.append((t, code))
            if code <= 0x94:
                self._ovr_cmd[0] = _after_override(self._ovr_cmd[0], code)
            elif code <= 0x97:
                self._ovr_cmd[1] = {0x95: 100, 0x96: 50, 0x97: 25}[code]
            else:
                self._ovr_cmd[2] = _after_override(self._ovr_cmd[2], code)
            if not self.sink_closed():
                with contextlib.suppress(ValueError, DncError):  # closed meanwhile
                    self.sink.event("override", t, f"0x{code:02X} {OVERRIDE_BYTES[code]}")

    @property
    def overrides(self) -> tuple[int, int, int] | None:
        """The last (feed %, rapid %, spindle %) GRBL reported (``Ov:``), None before any."""
        return self._ovr_reported

    def feed_override_pct(self, target: int) -> None:
        """Send the fewest bytes taking the feed override to ``target`` % (clamped to 10-200)
        from the last known or commanded value; returns once they are written."""
        self._override_to("feed", target)

    def spindle_override_pct(self, target: int) -> None:
        """As :meth:`feed_override_pct` for the spindle override (10-200 %)."""
        self._override_to("spindle", target)

    def _override_to(self, which: str, target: int) -> None:
        lo, hi = FEED_OVR_RANGE_PCT if which == "feed" else SPINDLE_OVR_RANGE_PCT
        goal = min(max(int(round(target)), lo), hi)
        with self._ovr_lock:
            for code in override_bytes(self._ovr_cmd[_OVR_KEYS[which][2]], goal, which):
                self.override(code)

    def _note_overrides(self, raw: bytes) -> None:
        """An ``Ov:`` field in a status report (reader thread): the reported values; once our
        last byte is ``OVR_SETTLE_S`` old they are what our bytes made (or a panel's change)."""
        i = raw.find(b"|Ov:")
        if i < 0:
            return
        field = raw[i + 4 :].split(b"|")[0].split(b">")[0]
        try:
            f, r, s = (int(v) for v in field.split(b","))
        except ValueError:
            return
        with self._ovr_lock:
            self._ovr_reported = (f, r, s)
            if time.perf_counter() - self._ovr_written_t > OVR_SETTLE_S:
                self._ovr_cmd = [f, r, s]

    def _on_interrupt(self) -> None:
        self._rt_safe(FEED_HOLD)  # first of all: the machine stops

    def _begin(self) -> None:
        self._queries: deque[int] = deque()  # bytes written before each '?' not yet answered
        self._report_written: int | None = None  # ... before the '?' of the last report
        self._alive_key: tuple | None = None
        self._noise = self._noise_reports = 0
        self._noise_example = ""
        self._extra_wait_s = 0.0  # a dwell under way lengthens the silence allowed
        self._pause_since: float | None = None
        self._hold_t0: float | None = None  # first report of a hold under way
        self._idle_hits: tuple[float, int] | None = None  # (since, reports): see _check_lost
        self._resume_t = -float("inf")  # the last cycle start sent, stream clock
        self._partial.clear()
        while not self._lines.empty():
            self._lines.get_nowait()
        self._reports = self._starved_reports = 0
        self._heard_any = self._seen_run = False
        self.last_status = None
        self.garbled = []
        self.halt_report = ""
        self._wco: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._planner_cap: int | None = None
        self._rx_cap: int | None = None
        self._acked_pos = -1
        self._sent_pos = -1
        self._last_io = time.perf_counter()
        self._lost_since: float | None = None
        self._lost_reports = 0
        self._results: list[Any] = []
        self.tracker = None
        self._tracking = True
        self._suspect = ""  # why the answers no longer match the lines (sending paused)
        self._drift_reports = 0

    # -- before the port opens ---------------------------------------------------------------------
    def _prepare(self, program: Program, items: list[Item]) -> list[Item]:
        out: list[Item] = []
        stripped = 0
        for it in items:
            sent = grbl_send_text(it.text) if self.strip else it.text.strip()
            stripped += len(it.text) - len(sent)
            if sent:
                out.append(Item(it.block, it.line, sent, it.source or it.text))
        if self.strip:
            self.transform, self.bytes_stripped = TRANSFORM, stripped
        problems = refused(check_dialect(program.text, "grbl", file=program.name, strip=self.strip))
        listed = {p.line for p in problems}
        lines: list[str] = [str(p) for p in problems]
        parser = GrblParser()
        self._results = []
        for k, it in enumerate(out):
            where = f"{program.name}:{it.line}"
            if it.block < 0:
                where = f"restart preamble line {k + 1}"
            if len(it.text) + 1 > self.rx_buffer_bytes and (it.line not in listed or it.block < 0):
                lines.append(
                    f"{where}: {len(it.text) + 1} bytes with its LF: more than the "
                    f"{self.rx_buffer_bytes} bytes GRBL's receive buffer may hold"
                )
            if it.text.startswith("$"):
                self._results.append(None)
                continue
            f = grbl_filter(it.text)
            if f.overflow:
                if it.line not in listed or it.block < 0:
                    n = len(grbl_filter(it.text, 10**9).text)
                    lines.append(
                        f"{where}: GRBL error:11: line overflow: {n} characters without spaces "
                        f"and comments; GRBL's line buffer holds {GRBL_LINE_CHARS}"
                    )
                self._results.append(None)
                continue
            res = parser.parse(f.text)
            self._results.append(res if res.ok else None)
            if not res.ok and (it.line not in listed or it.block < 0):
                lines.append(
                    f"{where}: {res.word}: GRBL error:{res.code} "
                    f"{GRBL_ERRORS.get(res.code, '')} (as sent: {it.text})"
                )
        if lines:
            raise DncError(
                f"{program.name}: GRBL 1.1h would refuse {len(lines)} line(s); nothing was sent:\n"
                + "\n".join(lines)
            )
        return out

    # -- link --------------------------------------------------------------------------------------
    def _make_link(self) -> SerialLink:
        ser = self._serial()
        if self.guard:
            from rig.dnc.guard import HoldGuard

            self._guard_proc = HoldGuard.start_for(ser)
        return SerialLink(ser, pace_bytes_per_s=self.pace, on_data=self._on_data)

    def _on_data(self, data: bytes) -> None:
        self._partial.extend(data)
        while True:
            i = self._partial.find(b"\n")
            if i < 0:
                return
            raw = bytes(self._partial[:i]).strip()
            del self._partial[: i + 1]
            if raw.startswith(b"<"):
                self._note_overrides(raw)
            if raw:
                self._lines.put((self.clock(), raw.decode("ascii", "replace")))

    def _next_line(self, heard: list[float], deadline: float, what: str) -> str:
        """The next line GRBL sends that is not a status report; messages and alarms among them
        are kept in ``messages`` (answers are not). A ``timeout`` fault at ``deadline``
        (perf_counter) whatever arrives meanwhile (noise, status reports)."""
        while True:
            if time.perf_counter() > deadline:
                head = f"GRBL did not answer {what} within {self.cfg.timeout_s:g} s"
                raise Fault("timeout", self._no_answer(head))
            ev = self._get(heard)
            if ev is None:
                self._check_interrupt()
                continue
            line = ev[1]
            if line.startswith("<"):
                continue
            if not line.startswith("[GC:") and not _is_answer(line):
                self.messages.append(line)
            return line

    def _no_answer(self, head: str) -> str:
        """Why a wait ended (``head``), and what came instead of an answer (timeout fault)."""
        if self._noise:
            got = (f"{self._noise} line(s) that are not GRBL's (e.g. {self._noise_example!r}: "
                   "wrong baud rate, wrong device or line noise)")  # fmt: skip
        elif self._noise_reports:
            got = f"only status reports that did not change ({self._noise_reports})"
        elif self._heard_any:
            got = "no answer"
        else:
            got = "nothing" + SILENT_HINT
        return f"{head}: received {got}"

    def _alive(self, line: str, st: GrblStatus | None) -> bool:
        """Does this line show GRBL at work? Answers and messages do; a status report does when
        it differs from the last one or says the machine is held (an operator's hold, a door);
        noise and a repeated report do not, so neither keeps a wait going for ever."""
        if st is None:
            return line.startswith(("ok", "error:", "ALARM:", "Grbl", "[", "$", ">"))
        if st.state in ("Hold", "Door", "Sleep", "Home"):
            return True
        key = (st.full_state, st.mpos_mm, st.wpos_mm, st.planner_free, st.rx_free)
        changed = key != self._alive_key
        self._alive_key = key
        return changed

    def _get(self, heard: list[float], timeout: float = 0.05) -> tuple[float, str] | None:
        """Next line from GRBL or None after ``timeout``; faults on silence (nothing that shows
        GRBL at work, :meth:`_alive`, for the serial timeout) or a lost port."""
        link = self.link
        assert link is not None
        if link.lost.is_set():
            raise Fault("port-lost", link.lost_reason)
        if time.perf_counter() - heard[0] > self.cfg.timeout_s + self._extra_wait_s:
            limit = self.cfg.timeout_s + self._extra_wait_s
            raise Fault("timeout", self._no_answer(f"no answer from GRBL for {limit:g} s"))
        try:
            item = self._lines.get(timeout=timeout)
        except queue.Empty:
            return None
        if item[1].startswith("<"):
            if self._queries:  # the i-th report answers at least the i-th '?'
                self._report_written = self._queries.popleft()
            try:
                st = parse_status(item[1])
            except DncError:
                self.garbled.append(item[1])
                return None
            if self._alive(item[1], st):
                heard[0] = time.perf_counter()
                self._heard_any = True
            else:
                self._noise_reports += 1
            self.last_status = st
            self.controller_state = st.full_state
            if st.wco_mm is not None:
                self._wco = st.wco_mm
            self._seen_run = self._seen_run or st.state in ("Run", "Hold")
            if self._streaming.is_set() and self._seen_run:
                self._reports += 1
                self._starved_reports += st.state == "Idle"
        elif self._alive(item[1], None):
            heard[0] = time.perf_counter()
            self._heard_any = True
        else:
            self._noise += 1
            self._noise_example = self._noise_example or item[1][:40]
        return item

    def _poll_status(self) -> None:
        period = 1.0 / self.status_hz
        while not self._poll_stop.wait(period):
            try:
                self._write_rt(self.link, STATUS)  # type: ignore[arg-type]
            except (LinkLost, LinkTimeout, OSError):
                return

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
        self._poll_stop = threading.Event()
        poller = None
        if self.status_hz > 0:
            poller = threading.Thread(target=self._poll_status, name="grbl-status", daemon=True)
            poller.start()
        clean = False
        try:
            self._handshake()
            self._make_tracker(items)
            self._stream(items)
            clean = True
        except Fault:
            clean = True  # the fault path has halted as it should
            raise
        finally:
            if not clean:  # a crash of the streamer itself (or a second Ctrl-C): hold first
                self._rt_safe(FEED_HOLD)
            self._poll_stop.set()
            if poller is not None:
                poller.join(timeout=2.0)
            if self._reports:
                self.starved_fraction = self._starved_reports / self._reports
            if self._guard_proc is not None:
                self._guard_proc.release(hold=not clean)
                self._guard_proc = None

    def _handshake(self) -> None:
        heard = [time.perf_counter()]
        # "$G" (parser state) is answered "[GC:...]" then "ok" in every state (GRBL 1.1 refuses
        # "$I" and "$$" while running or held). Answers still on their way from an earlier
        # stream (error:9 for lines that arrived after an alarm, late oks) come before "[GC:" and
        # are dropped here: taken as this stream's, they would let the character counting
        # overfill GRBL's receive buffer.
        self._check_interrupt()
        # one deadline for the whole handshake: noise or status reports do not extend it
        deadline = time.perf_counter() + self.cfg.timeout_s
        self._write(HANDSHAKE)
        what = "$G (parser state)"
        while not (line := self._next_line(heard, deadline, what)).startswith("[GC:"):
            pass  # stale answers of an earlier stream are dropped; alarms and messages are kept
        while not _is_answer(line := self._next_line(heard, deadline, what)):
            pass
        if line != "ok":
            raise Fault("error", f"GRBL answered $G (parser state) with {line}")
        try:
            st = self._wait_status(heard, lambda s: True, deadline)
        except TimeoutError:
            head = f"GRBL sent no status report within {self.cfg.timeout_s:g} s of '?'"
            raise Fault("timeout", self._no_answer(head)) from None
        if st.planner_free is not None and st.state == "Idle":
            self._planner_cap = st.planner_free
            self._rx_cap = st.rx_free
        if st.state == "Alarm":
            if not self.unlock:
                raise Fault(
                    "alarm",
                    "GRBL is in its Alarm state (after an alarm or a reset in motion); check the "
                    "machine and its position, then unlock (cutlab dnc unlock, or --unlock)",
                )
            self._write(b"$X\n")
            deadline = time.perf_counter() + self.cfg.timeout_s
            while True:
                if time.perf_counter() > deadline:
                    head = f"GRBL did not answer $X within {self.cfg.timeout_s:g} s"
                    raise Fault("timeout", self._no_answer(head))
                ev = self._get(heard)
                if ev is None or ev[1].startswith("<"):
                    continue
                if _is_answer(ev[1]):
                    break
                self.messages.append(ev[1])
            if ev[1] != "ok":
                raise Fault("alarm", f"GRBL refused to unlock: {ev[1]}")

    def _wait_status(
        self,
        heard: list[float],
        ok: Callable[[GrblStatus], bool],
        deadline: float | None = None,
        on_line: Callable[[float, str], None] | None = None,
    ) -> GrblStatus:
        """Poll until a fresh status report satisfies ``ok``; lines that are not status reports
        go to ``on_line`` (default: kept in ``messages``; ALARM and a reset banner are faults).
        TimeoutError after ``deadline`` (perf_counter)."""
        self.last_status = None
        self._rt_safe(STATUS)
        last_poll = time.perf_counter()
        while True:
            if deadline is not None and time.perf_counter() > deadline:
                raise TimeoutError
            ev = self._get(heard)
            now = time.perf_counter()
            if ev is None:
                if self.status_hz <= 0 or now - last_poll > 1.0:
                    self._rt_safe(STATUS)
                    last_poll = now
                continue
            t, line = ev
            if line.startswith("<"):
                st = self.last_status
                if st is None:
                    continue
                self._track(t, st)
                if ok(st):
                    return st
                if self.status_hz <= 0:
                    self._rt_safe(STATUS)
                continue
            if on_line is not None:
                on_line(t, line)
            elif line.startswith("ALARM:"):
                raise Fault("alarm", self._alarm_reason(line, "while finishing the motion"))
            else:
                self.messages.append(line)

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
        # (position, bytes, send time, the link's bytes written once the line was)
        inflight: deque[tuple[int, int, float, int]] = deque()
        used = 0
        i = 0
        heard = [time.perf_counter()]
        counting = self.mode == "char-counting"
        link = self.link
        assert link is not None
        self._streaming.set()
        self._last_io = time.perf_counter()
        try:
            while i < len(items) or inflight:
                self._check_interrupt()
                if self._suspect:
                    self._check_pause(inflight, heard)
                while i < len(items) and not self._suspect:
                    data = items[i].text.encode("ascii") + b"\n"
                    fits = used + len(data) <= self.rx_buffer_bytes if counting else not inflight
                    if not fits:
                        break
                    self._check_interrupt()
                    t = self.clock()
                    self._write(data)
                    inflight.append((i, len(data), t, link.bytes_written))
                    used += len(data)
                    self.blocks_sent += 1
                    self._sent_pos = i
                    self._last_io = time.perf_counter()
                    self._lost_since = None
                    if items[i].block >= 0:
                        self.last_sent_block = items[i].block
                    i += 1
                # a dwell under way answers after it: its time is not silence
                r0 = self._results[inflight[0][0]] if inflight and self._results else None
                self._extra_wait_s = r0.dwell_s if r0 is not None and r0.dwell_s else 0.0
                ev = self._get(heard)
                if ev is None:
                    continue
                t_ans, line = ev
                if line.startswith("<"):
                    if self.last_status is not None:
                        self._track(t_ans, self.last_status)
                        self._check_lost(inflight, items, self.last_status, heard)
                    continue
                if _is_answer(line):
                    self._lost_since = None
                    self._last_io = time.perf_counter()
                    if not inflight:
                        self.messages.append(line)
                        continue
                    pos, n, t_send, _ = inflight.popleft()
                    used -= n
                    it = items[pos]
                    status = line if line.startswith("error") else "ok"
                    self._answered(pos, BlockRow(it.block, it.line, it.text, n, t_send, t_ans,
                                                 status))  # fmt: skip
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
                    continue
                if line.startswith(("ALARM:", "Grbl")):
                    self._tracking = False
                if line.startswith("ALARM:"):
                    raise Fault("alarm", self._alarm_reason(line, "mid-stream"))
                if line.startswith("Grbl"):
                    raise Fault(
                        "reset",
                        f"GRBL was reset mid-stream (banner {line!r}): the lines in its buffers "
                        "were discarded",
                    )
                if line.startswith(("[", "$", ">")):
                    self.messages.append(line)
                    continue
                self.garbled.append(line)  # not a GRBL answer: line noise
                self.messages.append(line)
                if inflight and not self._suspect:  # maybe an answer: stop sending, let it drain
                    self._pause(f"received {line!r}, not a GRBL answer (line noise)")
            self._streaming.clear()
            if self.wait_idle:
                self._wait_idle(heard)
        except Fault as f:
            if f.kind in ("interrupted", "stopped"):
                f.reason += "; " + self.halt(reset=self.reset_after_halt, heard=heard)
            elif f.kind == "timeout" and not self.halt_report:  # (a stalled pause has halted)
                self._rt_safe(FEED_HOLD)  # whatever it is doing, it should not go on
            raise
        finally:
            self._streaming.clear()
            for pos, n, t, _ in inflight:
                it = items[pos]
                self._answered(pos, BlockRow(it.block, it.line, it.text, n, t,
                                             status="unacknowledged"))  # fmt: skip

    def _alarm_reason(self, line: str, when: str) -> str:
        try:
            code = int(line.split(":")[1])
        except (IndexError, ValueError):
            return f"{line} {when}"
        return f"{grbl_alarm_text(code)} ({line} {when}; GRBL discarded the lines in its buffers)"

    # -- lost answers ------------------------------------------------------------------------------
    def _pause(self, why: str) -> None:
        """Stop sending until every line sent is answered (then go on: nothing was lost) or GRBL
        stands Idle with empty buffers (an answer was lost); :meth:`_check_pause` keeps it
        within ``pause_timeout_s``."""
        self._suspect = why
        self._pause_since = time.perf_counter()
        self.sink.event("paused", self.clock(), f"sending paused: {why}")

    def _check_pause(self, inflight: deque, heard: list[float]) -> None:
        now = time.perf_counter()
        if not inflight:  # every line sent was answered: the count is right, go on
            self.sink.event("resumed", self.clock(), f"every line answered; was: {self._suspect}")
            self._suspect = ""
            self._pause_since = None
            self._drift_reports = 0
            return
        st = self.last_status
        if self._pause_since is None or (st is not None and st.state in ("Hold", "Door")):
            self._pause_since = now  # an operator's hold is not the streamer's pause
            return
        if now - self._pause_since <= self.pause_timeout_s:
            return
        state = "no status report"
        if st is not None:
            state = st.full_state
            if st.planner_free is not None:
                state += f", Bf {st.planner_free},{st.rx_free}"
        reason = (
            f"sending paused for {self.pause_timeout_s:g} s ({self._suspect}) and in that time "
            f"neither did the {len(inflight)} unanswered line(s) get their answers nor did GRBL "
            f"stand Idle with empty buffers (GRBL: {state})"
        )
        raise Fault("timeout", reason + "; " + self.halt(reset=self.reset_after_halt, heard=heard))

    def _check_lost(
        self, inflight: deque, items: list[Item], st: GrblStatus, heard: list[float]
    ) -> None:
        """A report may make a lost answer *likely* (Bf: GRBL's receive buffer holds less than
        had reached it unanswered): sending pauses. Only GRBL's state *shows* it: Idle (or
        Hold:0) with nothing in the planner nor the receive buffer while lines are unanswered,
        report after report for ``lost_ok_confirm_s``: the fault, after a feed hold."""
        now = time.perf_counter()
        s_q = self._report_written
        if st.rx_free is not None and self._rx_cap and inflight and s_q is not None:
            # The unanswered bytes written before the '?' this report answers had all reached
            # GRBL when it made the report (one byte stream, in order); bytes written after it
            # may still be on the wire and are not counted. GRBL holds them in its receive
            # buffer, except the line it is busy with or reading (the oldest unanswered, if
            # nothing was lost); 1 byte of margin (1.1h's count of a wrapped ring is one short).
            arrived = sum(min(n, max(0, s_q - (end - n))) for _, n, _, end in inflight)
            held = self._rx_cap - st.rx_free
            if arrived - held - inflight[0][1] - 1 > 0:
                self._drift_reports += 1
                if self._drift_reports >= 3 and not self._suspect:
                    self._pause(
                        f"GRBL's receive buffer held {held} bytes when {arrived} unanswered bytes "
                        "had reached it, 3 reports in a row: an answer may have been lost"
                    )
            else:
                self._drift_reports = 0
        pause_line = False
        if inflight and self._results:
            r0 = self._results[inflight[0][0]]
            pause_line = r0 is not None and r0.program_flow == "pause"  # M0: Hold:0 till ~
        cap = self._planner_cap
        stopped = st.state == "Idle" or (
            st.full_state == "Hold:0" and st.planner_free is not None and cap is not None
            and not pause_line
        )  # fmt: skip
        planner_empty = st.planner_free is None or cap is None or st.planner_free >= cap
        res = self._results[inflight[0][0]] if inflight and self._results else None
        dwell = res.dwell_s if res is not None and res.dwell_s else 0.0
        bf = st.rx_free is not None and st.planner_free is not None and bool(self._rx_cap)
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
                    hit = self._rx_cap - st.rx_free <= arrived - n0 + 1  # type: ignore[operator]
                else:
                    hit = st.state == "Idle" and self._ran(inflight[0][0], st)
            if not hit:
                self._idle_hits = None
            else:
                since, n_rep = self._idle_hits or (now, 0)
                self._idle_hits = (since, n_rep + 1)
                if n_rep + 1 >= 3 and now - since >= self.lost_ok_confirm_s + dwell:
                    upto = max(k for k, _, _, end in inflight if end <= s_q)
                    self._lost_answers(inflight, items, st, heard, arrived_upto=upto)
        empty = (
            stopped
            and planner_empty
            and (st.rx_free is None or st.rx_free >= (self._rx_cap or 128) - 1)
        )
        if not inflight or not empty:
            self._lost_since = None
            return
        # the line time of what is outstanding, and a dwell under way, are allowed for
        wait = self.lost_ok_confirm_s
        nbytes = sum(n for _, n, _, _ in inflight)
        wait += nbytes * 10.0 / max(self.cfg.baudrate, 1) + dwell
        if now - self._last_io < wait:
            return
        if self._lost_since is None:
            self._lost_since = now
            self._lost_reports = 0
        self._lost_reports += 1
        if now - self._lost_since < self.lost_ok_confirm_s or self._lost_reports < 3:
            return
        self._lost_answers(inflight, items, st, heard)

    def _ran(self, k: int, st: GrblStatus) -> bool:
        """The machine stands at the end of line ``k``'s move, away from its start."""
        tr = self.tracker
        pos = self._work_pos(st)
        if tr is None or pos is None or not 0 <= k < len(tr.paths) or not tr.paths[k].moves:
            return False
        pts = tr.paths[k].points
        p = np.asarray(pos, float)
        return bool(
            np.linalg.norm(pts[-1] - p) <= tr.tol_mm and np.linalg.norm(pts[0] - p) > 2 * tr.tol_mm
        )

    def _lost_answers(
        self,
        inflight: deque,
        items: list[Item],
        st: GrblStatus,
        heard: list[float],
        arrived_upto: int | None = None,
    ) -> None:
        """The lost-answer fault; ``arrived_upto``: mid-stream, the last line known to have
        reached GRBL (the lines after it may be on the wire; the halt's reset discards them)."""
        last = items[self._sent_pos] if arrived_upto is None else items[arrived_upto]
        upto_pos = self._sent_pos if arrived_upto is None else arrived_upto
        tr = self.tracker
        pos = self._work_pos(st)
        known = -1
        if tr is not None and pos is not None:
            # GRBL processed every line that reached it: the last one whose move ends where the
            # machine stands, and all before it, ran (an answer lost might have been an error:N)
            j = tr.line_ending_at(pos, range(upto_pos + 1))
            if j >= 0:
                known = j
                tr.finish_all(j, self.clock())
                self._executing(tr.pop_started(), tr.current, tr.done)
        why = f" ({self._suspect})" if self._suspect else ""
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
        raise Fault("lost-ok", reason + "; " + self.halt(reset=self.reset_after_halt, heard=heard))

    # -- ending --------------------------------------------------------------------------------
    def _wait_idle(self, heard: list[float]) -> None:
        """After the last ok: wait for a status report saying Idle (the motion has run)."""

        def on_line(t: float, line: str) -> None:
            if line.startswith(("ALARM:", "Grbl")):
                self._tracking = False
            if line.startswith("ALARM:"):
                raise Fault("alarm", self._alarm_reason(line, "while finishing the motion"))
            if line.startswith("Grbl"):
                raise Fault("reset", f"GRBL was reset while finishing the motion ({line!r})")
            self.messages.append(line)

        def idle(st: GrblStatus) -> bool:
            self._check_interrupt()
            return st.state == "Idle"

        self._wait_status(heard, idle, on_line=on_line)
        if self.tracker is not None:
            self.tracker.finish_all(self._acked_pos, self.clock())
            tr = self.tracker
            self._executing(tr.pop_started(), tr.current, tr.done)

    def halt(self, reset: bool = True, heard: list[float] | None = None) -> str:
        """Feed hold, wait for Hold:0 (motion stopped), then with ``reset`` a soft reset (GRBL
        Idle, its buffers flushed, no alarm). Returns what happened, for the fault message; it
        never raises for GRBL's behaviour (only for a lost port, as a Fault)."""
        heard = heard if heard is not None else [time.perf_counter()]
        self._rt_safe(FEED_HOLD)
        deadline = time.perf_counter() + self.halt_timeout_s
        lines: list[str] = []

        def keep(t: float, line: str) -> None:
            lines.append(line)

        try:
            st = self._wait_status(
                heard,
                lambda s: s.full_state == "Hold:0" or s.state in ("Idle", "Alarm", "Door"),
                deadline,
                on_line=keep,
            )
        except TimeoutError:
            self.halt_report = (
                f"feed hold sent; GRBL did not report Hold:0 within {self.halt_timeout_s:g} s "
                "(not reset, to keep it from ALARM:3)"
            )
            return self.halt_report
        except Fault as f:
            if f.kind == "port-lost":
                raise
            self.halt_report = f"feed hold sent; then {f.reason}"
            return self.halt_report
        self.messages.extend(lines)
        if st.state == "Alarm":
            self.halt_report = "GRBL is in Alarm"
            return self.halt_report
        if not reset:
            self.halt_report = f"machine held ({st.full_state}); resume with cycle start (~)"
            return self.halt_report
        lines.clear()
        self._tracking = False  # what the reset flushes was not executed
        self._rt_safe(SOFT_RESET)
        try:
            st = self._wait_status(
                heard, lambda s: any(x.startswith("Grbl") for x in lines), deadline, on_line=keep
            )
        except (TimeoutError, Fault):
            self.halt_report = "feed hold, Hold:0, soft reset sent; no banner came back"
            return self.halt_report
        alarms = [x for x in lines if x.startswith("ALARM:")]
        self.messages.extend(lines)
        state = st.full_state
        if alarms:
            self.halt_report = f"feed hold, Hold:0, then reset: {alarms[0]} ({state})"
        else:
            self.halt_report = f"feed hold, Hold:0, then soft reset: GRBL {state}, no alarm"
        return self.halt_report
