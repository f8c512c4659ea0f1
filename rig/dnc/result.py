"""The summary a stream ends with (also the ``--json`` output of ``cutlab dnc send``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypedDict


class StreamSummary(TypedDict):
    """`cutlab dnc send --json`: :class:`StreamResult`'s fields, in order (see there)."""

    protocol: str
    ok: bool
    start_block: int
    blocks_total: int
    blocks_sent: int
    bytes_sent: int
    last_sent_block: int
    last_acknowledged_block: int
    seconds: float
    bytes_per_s: float
    line_bytes_per_s: float
    xoff_count: int
    starved_fraction: float | None
    fault: str
    reason: str
    executing_block: int
    last_executed_block: int
    transform: str
    bytes_stripped: int
    controller_state: str


@dataclass(frozen=True)
class StreamResult:
    """What was streamed.

    blocks_total : blocks meant to be sent (preamble + program from ``start_block``)
    blocks_sent : blocks fully written to the port
    bytes_sent : bytes written (framing, leader and trailer included; GRBL real-time commands
        such as the ``?`` status polls are not counted)
    last_sent_block : program index of the last block fully written (-1: none)
    last_acknowledged_block : program index of the last block the controller acknowledged; for
        Fanuc drip feed, which has no acknowledgement, the last block fully written before the
        stream stopped (-1: none). Resume with ``start_block`` = the block after the last one the
        control *executed* (its screen, or the simulated controller's ``last_completed_block``).
    seconds : wall s from opening the port to the end
    bytes_per_s, line_bytes_per_s : achieved rate and what the line carries at its baud rate
    xoff_count : DC3 stops received (Fanuc with flow control in the streamer)
    starved_fraction : fraction of GRBL status reports, from the first in state Run to the last
        block sent, in which the controller was Idle waiting for blocks (None where the controller
        does not report it: Fanuc, or no report in that span)
    fault : ``""`` or the :class:`~rig.dnc.errors.StreamFault` kind; ``reason`` says why
    executing_block : program index of the block the control was executing at the end (GRBL:
        from its status reports; Fanuc: predicted; -1 none / unknown)
    last_executed_block : program index of the last block known executed to its end (-1: none);
        resume with ``start_block`` = the block after it
    transform : what the streamer changed in the lines it sent (GRBL: ``"stripped comments,
        spaces, N and O words"``; ``""`` as written)
    bytes_stripped : characters left out by ``transform``
    controller_state : the control's state when the stream ended (GRBL: Idle, Hold:0, Alarm, ...;
        ``""`` unknown)
    """

    protocol: str
    ok: bool
    start_block: int
    blocks_total: int
    blocks_sent: int
    bytes_sent: int
    last_sent_block: int
    last_acknowledged_block: int
    seconds: float
    bytes_per_s: float
    line_bytes_per_s: float
    xoff_count: int
    starved_fraction: float | None
    fault: str = ""
    reason: str = ""
    executing_block: int = -1
    last_executed_block: int = -1
    transform: str = ""
    bytes_stripped: int = 0
    controller_state: str = ""

    def as_dict(self) -> StreamSummary:
        """Every field, in order."""
        return {"protocol": self.protocol, "ok": self.ok, "start_block": self.start_block,
                "blocks_total": self.blocks_total, "blocks_sent": self.blocks_sent,
                "bytes_sent": self.bytes_sent, "last_sent_block": self.last_sent_block,
                "last_acknowledged_block": self.last_acknowledged_block, "seconds": self.seconds,
                "bytes_per_s": self.bytes_per_s, "line_bytes_per_s": self.line_bytes_per_s,
                "xoff_count": self.xoff_count, "starved_fraction": self.starved_fraction,
                "fault": self.fault, "reason": self.reason, "executing_block": self.executing_block,
                "last_executed_block": self.last_executed_block, "transform": self.transform,
                "bytes_stripped": self.bytes_stripped,
                "controller_state": self.controller_state}  # fmt: skip

    def summary_line(self) -> str:
        """One line: blocks and bytes sent, time (s), rate (B/s) beside the line's, the last
        acknowledged and the last executed block."""
        out = (
            f"sent {self.blocks_sent} blocks, {self.bytes_sent} bytes in {self.seconds:.1f} s "
            f"({self.bytes_per_s:,.0f} B/s of {self.line_bytes_per_s:,.0f}); last acknowledged "
            f"block {self.last_acknowledged_block}, last executed {self.last_executed_block}"
        )
        if self.transform:
            out += f"; {self.transform} ({self.bytes_stripped} characters)"
        return out
