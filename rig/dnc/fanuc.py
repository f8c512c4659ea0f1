"""Fanuc/ISO drip feed (DNC tape mode) over RS-232.

What goes on the wire, in order::

    NUL x leader_nuls, "%", EOB, block, EOB, block, EOB, ..., "%", NUL x leader_nuls

with EOB = LF, CR LF or CR per ``serial.end_of_block``, in tape code ISO (7-bit ASCII; with 7E2
the UART adds the even parity bit ISO asks for). With ``serial.code = "EIA"`` every character is
sent in EIA RS-244 (:mod:`rig.dnc.eia`): ER (0x0B) for ``%``, EOB 0x80; a character EIA lacks is
reported (line and column) before anything is sent.

Flow control, per ``serial.flow_control``:

- ``xonxoff``: the control sends DC3 when its buffer is nearly full and DC1 when it wants more.
  With ``serial.xonxoff_in_streamer`` (default) a reader thread gates the writer's small chunks
  (:mod:`rig.dnc.link`); otherwise the kernel's IXON does it.
- ``rtscts``: the UART stops on CTS off; the writer also checks CTS before each chunk where the
  port reports modem lines (a pty has none).
- ``none``: nothing stops the sender; only safe when the control executes faster than the line.

``wait_for_dc1`` (default True, with DC1/DC3 handled in the streamer): nothing is sent until the
control sends DC1, as a control does when the operator starts DNC/tape operation (the kernel's
IXON, the other option, swallows DC1 and starts un-stopped, so there it does not apply).

DC2/DC4 (the control starting/ending punch output) are honoured: while the control punches, the
streamer does not send; what is punched is collected (:attr:`FanucStreamer.punched`) and a remote
request in it is answered by :mod:`rig.dnc.remote`.

Drip feed has no acknowledgement: each block's record row has its send time, ``ack_time_s`` NaN
and status ``"sent"``. A timeout (XOFF held, write blocked, no DC1) or a lost port stops the stream
with a :class:`~rig.dnc.errors.StreamFault` naming the last fully sent block.

The block the control executes is estimated (:class:`rig.dnc.execution.TimedTracker`): the
control holds what it has read in its buffer and runs each block for its predicted time
(planning.nc's time model, ``machine``'s rapid rate), a block starting when the one before ended
or, if the control had to wait for it, when it arrived. The record's ``exec_time_s`` and the
result's ``executing_block`` / ``last_executed_block`` come from it (a prediction: a Fanuc
reports nothing over the line; the control's screen shows the truth).
"""

from __future__ import annotations

import threading
from typing import Any

from analysis.config import MachineConfig, SerialConfig
from rig.dnc import eia
from rig.dnc._stream import Fault, Item, StreamerBase
from rig.dnc.execution import TimedTracker, line_paths
from rig.dnc.link import DC2, DC4, SerialLink
from rig.dnc.port import EOB_BYTES
from rig.dnc.program import Program
from rig.dnc.record import BlockRow


class FanucStreamer(StreamerBase):
    """Drip-feed a program to a Fanuc-style control (see the module docstring).

    ``machine``: for the predicted execution (rapid rate); ``stream_kw``: sink, clock,
    pace_bytes_per_s, progress of :class:`StreamerBase`.
    """

    protocol = "fanuc"

    def __init__(
        self,
        cfg: SerialConfig,
        *,
        wait_for_dc1: bool = True,
        record_batch: int = 32,
        machine: MachineConfig | None = None,
        **stream_kw: Any,
    ) -> None:
        super().__init__(cfg, **stream_kw)
        self.machine = machine
        self.tracker: TimedTracker | None = None
        self.eob = EOB_BYTES[cfg.end_of_block]
        self.wait_for_dc1 = wait_for_dc1
        self.record_batch = record_batch
        self.punched = bytearray()
        self.punching = threading.Event()  # set between DC2 and DC4
        self._line_free = threading.Event()  # its complement, to wait on
        self._line_free.set()
        self._stop = threading.Event()

    def _on_interrupt(self) -> None:
        self._stop.set()  # a Fanuc has no feed hold over the line: stop feeding it

    def _check_interrupt(self) -> None:
        try:
            super()._check_interrupt()
        except Fault as f:
            if f.kind == "interrupted":
                f.reason += (
                    "; feeding stopped (a Fanuc takes no feed hold over the line: it runs what "
                    "it has buffered; press FEED HOLD or RESET on the control)"
                )
            raise

    def _begin(self) -> None:
        self._stop.clear()
        self.punched.clear()
        self.tracker = None

    def _prepare(self, program: Program, items: list[Item]) -> list[Item]:
        rapid = getattr(self.machine, "rapid_mm_min", None) or 10_000.0
        paths = line_paths([it.text for it in items], dialect="fanuc", rapid_mm_min=rapid)
        self.tracker = TimedTracker([p.duration_s for p in paths])
        return items

    def _make_link(self) -> SerialLink:
        soft = self.cfg.flow_control == "xonxoff" and self.cfg.xonxoff_in_streamer
        return SerialLink(
            self._serial(),
            soft_flow=soft,
            cts_flow=self.cfg.flow_control == "rtscts",
            pace_bytes_per_s=self.pace,
            on_data=self._on_data,
            on_control=self._on_control,
        )

    def _on_data(self, data: bytes) -> None:
        if self.punching.is_set():
            self.punched.extend(data)

    def _on_control(self, b: int) -> None:
        if b == DC2:
            self.punching.set()
            self._line_free.clear()
        elif b == DC4:
            self.punching.clear()
            self._line_free.set()

    timeout_hint = " (alarm on the control? e.g. 087 buffer overflow)"

    def _write(self, data: bytes) -> None:
        timeout = self.cfg.timeout_s
        if not self._line_free.wait(timeout):
            raise Fault("timeout", f"control kept punching (DC2 without DC4) for {timeout:g} s")
        super()._write(data)

    def _encode(self, items: list[Item]) -> tuple[list[bytes], bytes, bytes]:
        """Each block's bytes with its end of block, the opening and the closing tape marks."""
        if self.cfg.code == "EIA":
            out = []
            for it in items:
                where = f"block {it.block} (line {it.line})" if it.block >= 0 else "preamble"
                out.append(eia.encode(it.text, where) + bytes([eia.EOB]))
            return out, bytes([eia.ER, eia.EOB]), bytes([eia.ER])
        return [it.text.encode("ascii") + self.eob for it in items], b"%" + self.eob, b"%"

    def _run(self, link: SerialLink, items: list[Item]) -> None:
        timeout = self.cfg.timeout_s
        encoded, opening, closing = self._encode(items)  # errors here: nothing sent yet
        if self.wait_for_dc1 and link.soft_flow:
            # Before the control asks (DC1), the gate is shut.
            if not link.dc1_seen.is_set():
                link.xon.clear()
            if not link.dc1_seen.wait(timeout):
                if link.lost.is_set():
                    raise Fault("port-lost", link.lost_reason)
                raise Fault(
                    "timeout",
                    f"the control sent no DC1 within {timeout:g} s (put it in DNC/tape mode and "
                    "start the cycle)",
                )
        lead = b"\0" * self.cfg.leader_nuls
        self._write(lead + opening)
        tr = self.tracker
        for pos, (it, data) in enumerate(zip(items, encoded)):
            if self._stop.is_set():
                self._check_interrupt()
                raise Fault("stopped", "stopped by the operator")
            t_send = self.clock()
            self._write(data)
            self._answered(pos, BlockRow(it.block, it.line, it.text, len(data), t_send))
            self.blocks_sent += 1
            if it.block >= 0:
                self.last_sent_block = self.last_ack_block = it.block
            if tr is not None:
                now = self.clock()
                tr.arrived(pos, now)
                tr.update(now)
                self._executing(tr.pop_started(), tr.current, tr.done)
        self._write(closing + lead)
