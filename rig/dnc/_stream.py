"""What both streamers share: opening the link, the record, progress, the result, faults."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from analysis.config import SerialConfig
from rig.dnc.errors import DncError, StreamFault
from rig.dnc.link import LinkLost, LinkTimeout, SerialLink
from rig.dnc.port import check_settings, is_pty, line_bytes_per_s, open_port
from rig.dnc.program import Program
from rig.dnc.progress import Progress
from rig.dnc.record import BlockRow, BlockSink, MemorySink
from rig.dnc.result import StreamResult


class Fault(Exception):
    """Internal: stop the stream with a StreamFault of this kind."""

    def __init__(self, kind: str, reason: str) -> None:
        super().__init__(reason)
        self.kind = kind
        self.reason = reason


@dataclass(frozen=True)
class Item:
    """One block to send: program index (-1 preamble), source line (0 preamble), text."""

    block: int
    line: int
    text: str


def items_for(program: Program, start_block: int, preamble: Sequence[str]) -> list[Item]:
    first = program.position_of(start_block)
    return [Item(-1, 0, t) for t in preamble] + [
        Item(b.index, b.line, b.text) for b in program.blocks[first:]
    ]


class StreamerBase:
    """Common state of a stream. Subclasses implement ``_run(link, items)``.

    cfg : serial settings (port name or pyserial URL, baud, framing, flow control, timeout)
    sink : the block record (default: an in-memory sink, kept as ``self.sink``)
    clock : the time base of the record, s (default Unix time; the SimClock's ``now`` in the
        simulated rig)
    pace_bytes_per_s : writer pacing; ``"auto"`` paces at the line rate on a pseudo-terminal
        (``/dev/pts/*``), which has no line rate of its own, and not on a real port
    progress : show a tqdm bar on stderr
    """

    protocol = ""

    def __init__(
        self,
        cfg: SerialConfig,
        *,
        sink: BlockSink | None = None,
        clock: Callable[[], float] | None = None,
        pace_bytes_per_s: float | str | None = "auto",
        progress: bool = False,
    ) -> None:
        check_settings(cfg, self.protocol)
        self.cfg = cfg
        self.sink: BlockSink = sink if sink is not None else MemorySink()
        self.clock = clock if clock is not None else time.time
        if pace_bytes_per_s == "auto":
            pace_bytes_per_s = line_bytes_per_s(cfg) if is_pty(cfg.port) else None
        self.pace = pace_bytes_per_s
        self.show_progress = progress
        self.link: SerialLink | None = None
        self._reset_counters()

    def _reset_counters(self) -> None:
        self.blocks_sent = 0
        self.last_sent_block = -1
        self.last_ack_block = -1
        self.starved_fraction: float | None = None
        self._bytes0 = 0

    # -- to be provided by the protocols -----------------------------------------------------------
    def _begin(self) -> None:
        """Protocol hook: clear per-stream state (a streamer object may send many programs)."""

    def _make_link(self) -> SerialLink:
        raise NotImplementedError

    def _run(self, link: SerialLink, items: list[Item]) -> None:
        raise NotImplementedError

    # -- the common frame ------------------------------------------------------------------------
    def _open(self) -> SerialLink:
        return self._make_link().start()

    def _serial(self):  # noqa: ANN202 - pyserial object
        return open_port(self.cfg, self.protocol)

    #: appended to a write timeout's reason (what may be holding the line)
    timeout_hint = ""

    def _write(self, data: bytes) -> None:
        """Write through the open link; a timeout or a lost port ends the stream (Fault)."""
        try:
            self.link.write(data, self.cfg.timeout_s)  # type: ignore[union-attr]
        except LinkTimeout as exc:
            raise Fault("timeout", f"{exc}{self.timeout_hint}") from None
        except LinkLost as exc:
            raise Fault("port-lost", str(exc)) from None

    def send(
        self,
        program: Program,
        start_block: int = 0,
        preamble: Sequence[str] = (),
        link: SerialLink | None = None,
    ) -> StreamResult:
        """Stream ``preamble`` then ``program.blocks[start_block:]``; return the summary.

        Raises :class:`StreamFault` (with ``.result``) if the stream stops part-way; the sink is
        closed in every case. ``link``: an already open link (remote request); it is not closed.
        """
        n_lines = program.blocks[-1].index + 1 if program.blocks else 0
        if not 0 <= start_block < max(n_lines, 1):
            raise DncError(
                f"start block = {start_block}: out of range for {program.name} (0-based block "
                f"index = source line - 1, expected 0..{n_lines - 1})"
            )
        items = items_for(program, start_block, preamble)
        self._reset_counters()
        self._begin()
        # Everything before the start block counts as done: resume maths stays "last + 1".
        self.last_sent_block = self.last_ack_block = start_block - 1
        self._start_block = start_block
        self._n_items = len(items)
        own_link = link is None
        t0 = time.perf_counter()
        self._progress = Progress(len(items), self.show_progress, f"dnc {self.protocol}")
        fault: Fault | None = None
        try:
            self.link = link if link is not None else self._open()
            self._bytes0 = self.link.bytes_written
            what = f"{program.name} from block {start_block}"
            self.sink.event("stream_start", self.clock(), what)
            self._run(self.link, items)
        except Fault as f:
            fault = f
        except DncError as exc:  # refused before anything was sent (port, settings, program)
            self.sink.event("not_started", self.clock(), str(exc))
            self.sink.close()
            self._progress.close()
            raise
        finally:
            seconds = time.perf_counter() - t0
            result = self._result(seconds, fault)
            try:
                if self.sink_closed():
                    pass
                elif fault is not None:
                    self.sink.event(f"fault:{fault.kind}", self.clock(), fault.reason)
                else:
                    self.sink.event("stream_end", self.clock(), f"{self.blocks_sent} blocks")
            finally:
                self.sink.close()
                self._progress.close()
                if own_link and self.link is not None:
                    self.link.close()
        if fault is not None:
            last = result.last_acknowledged_block
            raise StreamFault(
                f"{self.protocol} stream stopped ({fault.kind}): {fault.reason}; last "
                f"{'acknowledged' if self.protocol == 'grbl' else 'fully sent'} block: {last}; "
                f"resume with --start-block <the block after the last one the control executed>",
                fault.kind,
                result,
            )
        return result

    def sink_closed(self) -> bool:
        return bool(getattr(self.sink, "closed", False))

    def _result(self, seconds: float, fault: Fault | None) -> StreamResult:
        nbytes = (self.link.bytes_written - self._bytes0) if self.link is not None else 0
        return StreamResult(
            protocol=self.protocol,
            ok=fault is None,
            start_block=self._start_block,
            blocks_total=self._n_items,
            blocks_sent=self.blocks_sent,
            bytes_sent=nbytes,
            last_sent_block=self.last_sent_block,
            last_acknowledged_block=self.last_ack_block,
            seconds=seconds,
            bytes_per_s=nbytes / seconds if seconds > 0 else 0.0,
            line_bytes_per_s=line_bytes_per_s(self.cfg),
            xoff_count=self.link.xoff_count if self.link is not None else 0,
            starved_fraction=self.starved_fraction,
            fault=fault.kind if fault else "",
            reason=fault.reason if fault else "",
        )

    def _record(self, rows: Sequence[BlockRow]) -> None:
        self.sink.append_blocks(rows)
        if self.link is not None:
            self._progress.update(len(rows), self.link.bytes_written - self._bytes0)
