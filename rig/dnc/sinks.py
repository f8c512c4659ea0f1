"""The block record into a run file: :class:`LoggerSink` adapts ``rig.log.writer.RunWriter``.

Rows go to ``RunWriter.append_blocks`` (block, line, text, send time, ack time and the time the
control started executing the block, what ties the force samples to the block cutting them; all
on the clock the writer and the streamer share), stream events to ``RunWriter.event`` (``fault``
for a fault, ``note`` otherwise). ``close()`` waits until the writer has taken what was queued; with
``close_writer=True`` it also closes the run file, status ``fail`` with the reason after a fault,
``success`` otherwise, so the file is closed and valid after every fault.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from analysis.runs import file as rf
from rig.dnc.record import BlockRow


class LoggerSink:
    """A :class:`~rig.dnc.record.BlockSink` writing into a ``rig.log.writer.RunWriter``."""

    def __init__(self, writer: Any, close_writer: bool = False) -> None:
        self.writer = writer
        self.close_writer = close_writer
        self.fault = ""
        self.closed = False

    def append_blocks(self, rows: Sequence[BlockRow]) -> None:
        if not rows:
            return
        self.writer.append_blocks(
            [r.block for r in rows],
            [r.line for r in rows],
            [r.text for r in rows],
            [r.send_time_s for r in rows],
            [r.ack_time_s for r in rows],
            exec_s=[r.exec_time_s for r in rows],
        )

    def event(self, kind: str, time_s: float, detail: str = "") -> None:
        # The writer cuts the message to the run file's field (rf.EVENT_MESSAGE_BYTES).
        if kind.startswith("fault"):
            self.fault = f"{kind}: {detail}"
        ev = rf.EV_FAULT if kind.startswith("fault") else rf.EV_NOTE
        self.writer.event(ev, f"dnc {kind}: {detail}", time_s=time_s)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self.close_writer:
            self.writer.close("fail" if self.fault else "success", self.fault)
