"""GRBL 1.1 streaming: send-response or character counting, real-time commands, status reports.

Modes:

- ``"send-response"``: one line out, wait for its ``ok``/``error:N``; simple, slower.
- ``"char-counting"`` (default): keep as many lines in flight as GRBL's serial receive buffer holds
  (``rx_buffer_bytes``, 127 usable bytes on an Arduino Uno), counting the bytes of every line not
  yet answered; each ``ok``/``error`` frees its line's bytes. The buffer never overflows.

Every line is answered, in order, by ``ok``, ``error:N`` or (when GRBL stops) ``ALARM:N``. Status
reports ``<State|MPos:x,y,z|Bf:planner_free,rx_free|FS:feed,rpm>`` answer the real-time ``?``;
the streamer polls ``?`` (``status_hz``) to tell a busy controller from a dead one (``timeout_s``
of silence is a fault) and to measure starvation (reports in state ``Idle`` while blocks remain).
Real-time commands go out at once, outside the count: :meth:`GrblStreamer.feed_hold` ``!``,
:meth:`~GrblStreamer.cycle_start` ``~``, :meth:`~GrblStreamer.status` ``?``,
:meth:`~GrblStreamer.soft_reset` 0x18. ``$`` lines in the program (settings, ``$H``, ``$X``) are
sent like any line and left alone.

On ``error:N`` or ``ALARM:N`` the streamer stops sending; with ``halt_on_error`` (default) it also
sends feed hold and soft reset, so lines already in GRBL's buffers after the failing one do not
run (character counting would otherwise let them execute). Record rows get the ``ok`` time as
``ack_time_s`` and status ``ok``/``error:N``; lines still in flight at a fault are
``unacknowledged``.
"""

from __future__ import annotations

import queue
import re
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from analysis.config import SerialConfig
from rig.dnc._stream import Fault, Item, StreamerBase
from rig.dnc.errors import DncError
from rig.dnc.link import LinkLost, LinkTimeout, SerialLink
from rig.dnc.record import BlockRow

FEED_HOLD, CYCLE_START, STATUS, SOFT_RESET = b"!", b"~", b"?", b"\x18"
HANDSHAKE = b"$G\n"  # what a stream sends first (see GrblStreamer._handshake)
MODES = ("char-counting", "send-response")
GRBL_RX_BUFFER_BYTES = 127
GRBL_LINE_CHARS = 79  # LINE_BUFFER_SIZE 80 incl. the terminating NUL

_COMMENT = re.compile(r"\([^)]*\)|;.*$")


@dataclass(frozen=True)
class GrblStatus:
    """A parsed status report. Missing fields are None."""

    state: str
    mpos_mm: tuple[float, float, float] | None = None
    planner_free: int | None = None
    rx_free: int | None = None
    feed_mm_min: float | None = None
    spindle_rpm: float | None = None
    line: int | None = None


def parse_status(text: str) -> GrblStatus:
    """``<Run|MPos:1.000,2.000,0.000|Bf:12,100|FS:600,10000|Ln:42>`` -> GrblStatus."""
    body = text.strip().removeprefix("<").removesuffix(">")
    parts = body.split("|")
    if not parts or not parts[0]:
        raise DncError(f"GRBL status report {text!r}: no state")
    kw: dict = {"state": parts[0].split(":")[0]}
    for p in parts[1:]:
        key, _, val = p.partition(":")
        nums = val.split(",")
        try:
            if key == "MPos" and len(nums) >= 3:
                kw["mpos_mm"] = (float(nums[0]), float(nums[1]), float(nums[2]))
            elif key == "Bf" and len(nums) == 2:
                kw["planner_free"], kw["rx_free"] = int(nums[0]), int(nums[1])
            elif key == "FS" and len(nums) == 2:
                kw["feed_mm_min"], kw["spindle_rpm"] = float(nums[0]), float(nums[1])
            elif key == "Ln":
                kw["line"] = int(val)
        except ValueError:
            raise DncError(f"GRBL status report {text!r}: bad field {p!r}") from None
    return GrblStatus(**kw)


def check_line(text: str, where: str, rx_buffer_bytes: int) -> None:
    """Raise DncError if GRBL cannot take this line (too long for its buffers)."""
    if len(text) + 1 > rx_buffer_bytes:
        raise DncError(
            f"{where}: line is {len(text) + 1} bytes with its LF; GRBL's receive buffer holds "
            f"{rx_buffer_bytes} (expected <= {rx_buffer_bytes} bytes)"
        )
    stripped = _COMMENT.sub("", text).replace(" ", "")
    if len(stripped) > GRBL_LINE_CHARS:
        raise DncError(
            f"{where}: {len(stripped)} characters without spaces and comments; GRBL's line "
            f"buffer holds {GRBL_LINE_CHARS} (error:11)"
        )


class GrblStreamer(StreamerBase):
    """Stream a program to GRBL (see the module docstring).

    mode : ``"char-counting"`` or ``"send-response"``
    rx_buffer_bytes : GRBL's usable serial receive buffer, bytes (127 on an Uno)
    status_hz : status polls per wall second while streaming (0: none; then no starvation figure
        and silence while GRBL waits with a full planner can look like a dead controller)
    wait_idle : after the last ``ok``, wait until GRBL reports ``Idle`` (the motion has run)
    unlock : if GRBL is in ``Alarm`` at the start, send ``$X`` (else that is a fault)
    halt_on_error : on ``error:N``, send feed hold + soft reset so nothing after it runs
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
        self.last_status: GrblStatus | None = None
        self.messages: list[str] = []
        self._lines: queue.Queue[tuple[float, str]] = queue.Queue()
        self._partial = bytearray()
        self._stop = threading.Event()
        self._streaming = threading.Event()
        self._reports = 0
        self._starved_reports = 0
        self._heard_any = False
        self._seen_run = False

    # -- real-time commands (any thread) ---------------------------------------------------------
    def _rt(self, cmd: bytes) -> None:
        if self.link is None:
            raise DncError("GRBL real-time command before the stream opened the port")
        try:
            self.link.write_now(cmd)
        except (LinkLost, LinkTimeout) as exc:
            raise DncError(f"GRBL real-time command {cmd!r} not sent: {exc}") from None

    def feed_hold(self) -> None:
        self._rt(FEED_HOLD)

    def cycle_start(self) -> None:
        self._rt(CYCLE_START)

    def status(self) -> None:
        self._rt(STATUS)

    def soft_reset(self) -> None:
        self._rt(SOFT_RESET)

    def stop(self) -> None:
        """Stop sending before the next line (ends with fault ``stopped``)."""
        self._stop.set()

    def _begin(self) -> None:
        self._stop.clear()
        self._partial.clear()
        while not self._lines.empty():
            self._lines.get_nowait()
        self._reports = self._starved_reports = 0
        self._heard_any = self._seen_run = False
        self.last_status = None

    # -- link --------------------------------------------------------------------------------------
    def _make_link(self) -> SerialLink:
        return SerialLink(self._serial(), pace_bytes_per_s=self.pace, on_data=self._on_data)

    def _on_data(self, data: bytes) -> None:
        self._partial.extend(data)
        while True:
            i = self._partial.find(b"\n")
            if i < 0:
                return
            raw = bytes(self._partial[:i]).strip()
            del self._partial[: i + 1]
            if raw:
                self._lines.put((self.clock(), raw.decode("ascii", "replace")))

    def _get(self, heard: list[float]) -> tuple[float, str]:
        """Next line from GRBL, whatever it is; faults on silence or a lost port."""
        link = self.link
        assert link is not None
        while True:
            if link.lost.is_set():
                raise Fault("port-lost", link.lost_reason)
            try:
                item = self._lines.get(timeout=0.05)
            except queue.Empty:
                if time.perf_counter() - heard[0] > self.cfg.timeout_s:
                    hint = "" if self._heard_any else " (wrong port or baud rate?)"
                    why = f"no answer from GRBL for {self.cfg.timeout_s:g} s{hint}"
                    raise Fault("timeout", why) from None
                continue
            heard[0] = time.perf_counter()
            self._heard_any = True
            if item[1].startswith("<"):
                st = parse_status(item[1])
                self.last_status = st
                self._seen_run = self._seen_run or st.state in ("Run", "Hold")
                if self._streaming.is_set() and self._seen_run:
                    self._reports += 1
                    self._starved_reports += st.state == "Idle"
            return item

    def _next(self, heard: list[float]) -> tuple[float, str]:
        """Next answer line (``ok``, ``error:N``, ``ALARM:N``, the banner); status reports,
        ``[...]`` messages, ``$n=v`` setting dumps and echoes are kept in ``messages``."""
        while True:
            t, line = self._get(heard)
            if line.startswith("<"):
                continue
            if line == "ok" or line.startswith(("error:", "ALARM:", "Grbl")):
                return t, line
            self.messages.append(line)

    def _wait_state(self, heard: list[float], ok: Callable[[GrblStatus], bool]) -> None:
        """Poll until a fresh status report satisfies ``ok``."""
        self.last_status = None
        self.status()
        while True:
            _, line = self._get(heard)
            if line.startswith("<") and self.last_status is not None:
                if ok(self.last_status):
                    return
                if self.status_hz <= 0:
                    self.status()
            elif line.startswith("ALARM"):
                raise Fault("alarm", f"{line} while finishing the motion")
            elif not line.startswith("<"):
                self.messages.append(line)

    def _poll_status(self) -> None:
        period = 1.0 / self.status_hz
        while not self._poll_stop.wait(period):
            try:
                self.link.write_now(STATUS)  # type: ignore[union-attr]
            except (LinkLost, LinkTimeout):
                return

    # -- the stream --------------------------------------------------------------------------------
    def _run(self, link: SerialLink, items: list[Item]) -> None:
        for it in items:
            where = f"block {it.block} (line {it.line})" if it.block >= 0 else "restart preamble"
            check_line(it.text, where, self.rx_buffer_bytes)
        self._poll_stop = threading.Event()
        poller = None
        if self.status_hz > 0:
            poller = threading.Thread(target=self._poll_status, name="grbl-status", daemon=True)
            poller.start()
        try:
            self._handshake()
            self._stream(items)
        finally:
            self._poll_stop.set()
            if poller is not None:
                poller.join(timeout=2.0)
            if self._reports:
                self.starved_fraction = self._starved_reports / self._reports

    def _handshake(self) -> None:
        heard = [time.perf_counter()]
        # "$G" (parser state) is answered "[GC:...]" then "ok" in every state (GRBL 1.1 refuses
        # "$I" and "$$" while running or held). Answers still on their way from an earlier
        # stream (error:9 for lines that arrived after an alarm, late oks) come before "[GC:" and
        # are dropped here: taken as this stream's, they would let the character counting
        # overfill GRBL's receive buffer.
        self._write(HANDSHAKE)
        while True:
            _, line = self._get(heard)
            if line.startswith("[GC:"):
                break
            if not line.startswith("<"):
                self.messages.append(line)
        _, line = self._next(heard)
        if line != "ok":
            raise Fault("error", f"GRBL answered $G (parser state) with {line}")
        self._wait_state(heard, lambda st: True)
        assert self.last_status is not None
        if self.last_status.state.startswith("Alarm"):
            if not self.unlock:
                raise Fault(
                    "alarm",
                    "GRBL is in its Alarm state; check the machine, then unlock ($X, or --unlock)",
                )
            self._write(b"$X\n")
            _, line = self._next(heard)
            if line != "ok":
                raise Fault("alarm", f"GRBL refused to unlock: {line}")

    def _stream(self, items: list[Item]) -> None:
        inflight: deque[tuple[Item, int, float]] = deque()
        used = 0
        i = 0
        heard = [time.perf_counter()]
        done: list[BlockRow] = []
        counting = self.mode == "char-counting"
        self._streaming.set()
        try:
            while i < len(items) or inflight:
                while i < len(items):
                    if self._stop.is_set():
                        raise Fault("stopped", "stopped by the operator")
                    data = items[i].text.encode("ascii") + b"\n"
                    fits = used + len(data) <= self.rx_buffer_bytes if counting else not inflight
                    if not fits:
                        break
                    t = self.clock()
                    self._write(data)
                    inflight.append((items[i], len(data), t))
                    used += len(data)
                    self.blocks_sent += 1
                    if items[i].block >= 0:
                        self.last_sent_block = items[i].block
                    i += 1
                t_ack, line = self._next(heard)
                if line.startswith("Grbl"):
                    raise Fault("alarm", f"GRBL reset itself mid-stream ({line!r})")
                if line.startswith("ALARM"):
                    raise Fault("alarm", f"{line} (GRBL stopped; lines in flight are lost)")
                if not inflight:
                    self.messages.append(line)
                    continue
                it, n, t_send = inflight.popleft()
                used -= n
                status = line if line.startswith("error") else "ok"
                done.append(BlockRow(it.block, it.line, it.text, n, t_send, t_ack, status))
                if status != "ok":
                    if self.halt_on_error:
                        self._halt()
                    raise Fault("error", f"{line} for block {it.block} (line {it.line}): {it.text}")
                if it.block >= 0:
                    self.last_ack_block = it.block
                if len(done) >= 32:
                    self._record(done)
                    done = []
            self._streaming.clear()
            if self.wait_idle:
                self._wait_idle(heard)
        finally:
            self._streaming.clear()
            done.extend(
                BlockRow(it.block, it.line, it.text, n, t, status="unacknowledged")
                for it, n, t in inflight
            )
            if done:
                self._record(done)

    def _halt(self) -> None:
        try:
            self.link.write_now(FEED_HOLD)  # type: ignore[union-attr]
            self.link.write_now(SOFT_RESET)  # type: ignore[union-attr]
        except (LinkLost, LinkTimeout):
            pass

    def _wait_idle(self, heard: list[float]) -> None:
        """After the last ok: wait for a status report saying Idle (the motion has run)."""
        self._wait_state(heard, lambda st: st.state == "Idle")
