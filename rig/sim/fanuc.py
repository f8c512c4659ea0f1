"""A simulated Fanuc-style control in DNC (tape) mode on the other end of a pseudo-terminal.

Start it in-process::

    ctl = SimFanuc(machine, clock=SimClock(speed=20), baudrate=9600)
    path = ctl.start()                 # e.g. /dev/pts/5: give it to the streamer as the port
    ctl.add_listener(on_segment=machine.on_segment, on_spindle=machine.on_spindle)
    ...
    ctl.stop()

or from the command line: ``cutlab dnc sim-controller --protocol fanuc`` prints the path.

Behaviour
---------
- Waiting for a program it sends DC1 (start reader) every ``dc1_repeat_s`` wall seconds, as if the
  operator had started DNC operation; it ignores everything before ``%``, then skips to the first
  end of block (label skip), then reads blocks until the closing ``%``. NUL and CR are ignored.
- Tape code is recognised from the first tape mark, as a Fanuc does: ``%`` ISO, ER (0x0B) EIA
  (:mod:`rig.dnc.eia`; EOB 0x80, blank and delete ignored, a code with even parity or not in EIA
  is alarm ``TH``).
- Receive buffer of ``rx_buffer_bytes`` characters; DC3 when the free space drops to
  ``xoff_free_bytes``, DC1 when the fill drops to ``xon_fill_bytes``. A character arriving into a
  full buffer is an overrun: alarm ``SR0087 BUFFER OVERFLOW``.
- The executor keeps ``lookahead_blocks`` interpreted blocks ahead of the one running, taking them
  out of the receive buffer, and runs each segment for its programmed time (feed, rapid rate,
  dwell) on the SimClock. Listeners get every segment as it starts.
- Characters at a baud rate other than its own are framing errors: alarm 085 (communication
  error), DC3 held.
- An NC error in a block is a program alarm ``PS:<reason>``: motion stops, DC3, nothing more read.
  In alarm the control holds DC3 (the streamer times out); :meth:`reset` (the RESET key) clears
  buffers and the alarm and waits for a new program; the machine stays where it stopped.
- :meth:`feed_hold` / :meth:`cycle_start` are the panel buttons (no serial command on a Fanuc).
- :meth:`request_program` punches a remote request (DC2 ... DC4) for a DNC server.

Fault knobs (``sim_``): ``sim_stop_answering_after_block=k`` (after k blocks: DC3, then silence),
``sim_drop_port_after_block=k`` (close the pty; :meth:`reopen` gives a new path),
``sim_overrun_at_byte=n`` (the UART reports an overrun on byte n: alarm SR0087),
``sim_alarm_at_block=(k, code)`` (alarm when block k starts), ``sim_stop_answering_at_s=t`` and
``sim_alarm_at_s=(t, code)`` (the same at simulated time t).

Notes
-----
How it differs from a real control:

- A pty has no baud rate: the line rate is emulated (each character arrives ``bits/baud``
  simulated seconds after the previous one); data bits and parity are not seen (Linux keeps a pty
  at 8 bits, no parity), only a wrong baud rate is detected (the bytes then count as framing
  errors and are dropped, as garbage would be).
- RTS/CTS cannot be emulated (a pty has no modem lines): ``flow_control="rtscts"`` is refused.
- A real control tolerates only about 10 characters after its DC3 (alarm 087 otherwise); the
  default here leaves ``xoff_free_bytes`` = 1024 (of 4096) because a Python streamer and this
  controller share CPUs and the GIL with other work and may wake up milliseconds late; set it to
  10 to be as strict as the control. ``max_after_xoff`` says how many characters did arrive.
- DC1 is repeated while waiting (a real control sends it once when reading starts), because a
  streamer that opens the port later flushes its input.
- No acceleration: segments run at their programmed feed from start to end.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Any

from analysis.config import MachineConfig
from planning.nc import NCError
from rig.dnc import eia
from rig.sim._controller import SimControllerBase, SimControllerError, _Planned

DC1, DC2, DC3, DC4 = b"\x11", b"\x12", b"\x13", b"\x14"
_END = "%"


class SimFanuc(SimControllerBase):
    """Fanuc-like control reading a drip-fed program (see the module docstring).

    ``base_kw``: clock, speed, baudrate (9600) and the ``sim_`` fault knobs of
    :class:`SimControllerBase` (a wrong name is a TypeError).
    """

    protocol = "fanuc"

    def __init__(
        self,
        machine: MachineConfig | None = None,
        *,
        bytesize: int = 7,
        parity: str = "E",
        stopbits: int = 2,
        flow_control: str = "xonxoff",
        rx_buffer_bytes: int = 4096,
        xoff_free_bytes: int = 1024,
        xon_fill_bytes: int = 1024,
        lookahead_blocks: int = 2,
        dc1_repeat_s: float = 0.2,
        **base_kw: Any,
    ) -> None:
        if flow_control == "rtscts":
            raise SimControllerError(
                "flow_control = 'rtscts': a pseudo-terminal has no modem lines, so the simulated "
                "control cannot drive CTS; use 'xonxoff' or 'none'"
            )
        if flow_control not in ("xonxoff", "none"):
            raise SimControllerError(f"flow_control = {flow_control!r}: expected xonxoff or none")
        if not 0 < xoff_free_bytes < rx_buffer_bytes or not 0 <= xon_fill_bytes < rx_buffer_bytes:
            raise SimControllerError(
                f"xoff_free_bytes = {xoff_free_bytes}, xon_fill_bytes = {xon_fill_bytes}: "
                f"expected 0 < both < rx_buffer_bytes = {rx_buffer_bytes} bytes"
            )
        bits = 1 + bytesize + (parity != "N") + stopbits
        super().__init__(machine, bits_per_char=bits, rx_buffer_bytes=rx_buffer_bytes, **base_kw)
        self.flow = flow_control == "xonxoff"
        self.xoff_at = rx_buffer_bytes - xoff_free_bytes
        self.xon_at = xon_fill_bytes
        self.lookahead = lookahead_blocks
        self.max_after_xoff = 0  # most characters that arrived after a DC3 (real control: ~10)
        self.dc1_repeat_s = dc1_repeat_s
        self._fanuc_state()

    def _fanuc_state(self) -> None:
        self.reader = "waiting"  # waiting -> label -> reading -> ended
        self.code = "ISO"  # set by the first tape mark: '%' ISO, ER (0x0B) EIA
        # complete blocks: text, arrival time of its end of block, characters it fills
        self._rx_blocks: deque[tuple[str, float, int]] = deque()
        self._partial = bytearray()
        self.fill = 0
        self.xoff_sent = False
        self.xoff_count = 0
        self._after_xoff = 0
        self._last_dc1 = 0.0
        self.programs_read = 0

    # -- receiving -----------------------------------------------------------------------------
    def _on_bytes(self, data: bytes, t: float) -> None:
        for b in data:
            if self.alarm or self.silent:
                return
            if self._count_byte():
                self.overruns += 1
                self._raise_alarm(87, "SR0087 BUFFER OVERFLOW (receiver overrun)", t)
                return
            self.received.append(b)
            if self.reader == "waiting":  # the first tape mark sets the code: '%' ISO, ER EIA
                if b in (0x25, eia.ER):
                    self.code = "ISO" if b == 0x25 else "EIA"
                    self.reader = "label"
                    self._started = False
                    self._event("program_start", f"tape code {self.code}", t)
                continue
            c = self._char(b, t)
            if c is None:
                if self.alarm:
                    return
                continue
            b = c
            if self.reader == "label":
                if b == 0x0A:
                    self.reader = "reading"
                continue
            if self.reader != "reading":
                continue
            if self.fill >= self.rx_capacity:
                self.overruns += 1
                self._raise_alarm(87, "SR0087 BUFFER OVERFLOW (more than the buffer after DC3)", t)
                return
            self.fill += 1
            self.max_fill = max(self.max_fill, self.fill)
            if self.xoff_sent:
                self._after_xoff += 1
                self.max_after_xoff = max(self.max_after_xoff, self._after_xoff)
            if b == 0x25 and not self._partial:
                self._rx_blocks.append((_END, t, 1))
                self.reader = "ended"
            elif b == 0x0A:
                text = self._partial.decode("ascii", "replace").strip()
                self._rx_blocks.append((text, t, len(self._partial) + 1))
                self._partial.clear()
                if not self._block_received():
                    return
            else:
                self._partial.append(b)
            if self.flow and not self.xoff_sent and self.fill >= self.xoff_at:
                self.xoff_sent = True
                self._after_xoff = 0
                self.xoff_count += 1
                self._send(DC3)

    def _char(self, b: int, t: float) -> int | None:
        """The ISO character a received byte stands for (EIA decoded: EOB -> LF, ER -> %);
        None for what the reader ignores (NUL, CR, EIA blank/delete) or a parity alarm."""
        if self.code == "ISO":
            return None if b in (0x00, 0x0D) else b
        if b in (eia.BLANK, eia.DELETE):
            return None
        if not eia.has_odd_parity(b):
            self._raise_alarm(1, f"TH PARITY ALARM (EIA code 0x{b:02X} has even parity)", t)
            return None
        if b == eia.EOB:
            return 0x0A
        if b == eia.ER:
            return 0x25
        ch = eia.DECODE.get(b)
        if ch is None:
            self._raise_alarm(1, f"TH ALARM (0x{b:02X} is not an EIA character)", t)
            return None
        return ord(ch)

    def _next_block(self, now: float) -> _Planned | None:
        while len(self._plan) < self.lookahead + 1 and self._rx_blocks and not self.alarm:
            text, t, n = self._rx_blocks.popleft()
            self.fill -= n
            if self.flow and self.xoff_sent and self.fill <= self.xon_at:
                self.xoff_sent = False
                self._send(DC1)
            if text == _END:
                self._plan.append(_Planned(-1, _END, _empty_motion(), _no_durations(), 0.0, t))
                continue
            try:
                self._plan.append(self._interpret(text, t))
            except NCError as exc:
                self._raise_alarm(0, f"PS alarm at block {self._seq}: {exc.reason}", now)
                return None
        if not self._plan:
            return None
        b = self._plan.popleft()
        if b.text == _END:
            self._event("program_end", f"{self._seq} blocks", max(b.t_ready, self._seg_t1))
            self.programs_read += 1
            self.reader = "waiting"
            self._new_interpreter()
            self._started = False
            return None
        return b

    def _stream_wants(self) -> bool:
        # a drip feed sends until the closing tape mark unless held off by DC3
        return self.reader in ("waiting", "label", "reading") and not self.xoff_sent

    def _on_framing_error(self, t: float) -> None:
        if not self.alarm:
            self._raise_alarm(85, "COMMUNICATION ERROR (framing: wrong baud rate?)", t)

    def _go_silent(self, detail: str) -> None:
        # a control that stops reading holds the line with DC3 (else the sender would go on)
        if self.flow and not self.xoff_sent:
            self._send(DC3)
            self.xoff_sent = True
        super()._go_silent(detail)

    def request_program(self, name: str, start_block: int = 0) -> None:
        """Punch a remote request ``O9999 (PRG=name) (BLK=n)`` framed by DC2 ... DC4 (as the
        operator does at the control to have the DNC server send a program)."""
        blk = f" (BLK={start_block})" if start_block else ""
        with self._lock:
            self._send(DC2 + f"%\nO9999 (PRG={name}){blk}\n%\n".encode() + DC4)

    def _periodic(self, now: float) -> None:
        if self.reader != "waiting" or self.alarm or self.silent or not self.flow:
            return
        wall = time.monotonic()
        if wall - self._last_dc1 >= self.dc1_repeat_s:
            self._last_dc1 = wall
            self._send(DC1)

    def _on_alarm(self, code: int) -> None:
        if self.flow and not self.xoff_sent:
            self._send(DC3)
            self.xoff_sent = True
        self._plan.clear()
        self._rx_blocks.clear()
        self.reader = "alarm"

    def _after_reset(self) -> None:
        self._fanuc_state()


def _empty_motion():  # noqa: ANN202
    from planning.nc import MotionBuilder

    return MotionBuilder().build()


def _no_durations():  # noqa: ANN202
    import numpy as np

    return np.zeros(0)
