"""What both streamers share: opening the link, the record, progress, the result, faults, being
interrupted (Ctrl-C, SIGTERM, SIGHUP), and which block the control executes."""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from analysis.config import SerialConfig
from rig.dnc.errors import DncError, StreamFault
from rig.dnc.link import LinkLost, LinkTimeout, SerialLink
from rig.dnc.port import check_settings, is_pty, line_bytes_per_s, open_port
from rig.dnc.program import Program
from rig.dnc.progress import Progress
from rig.dnc.protocols import protocol_of
from rig.dnc.record import BlockRow, BlockSink, MemorySink
from rig.dnc.result import StreamResult

if TYPE_CHECKING:
    import serial


class Fault(Exception):
    """Internal: stop the stream with a StreamFault of this kind."""

    def __init__(self, kind: str, reason: str) -> None:
        super().__init__(reason)
        self.kind = kind
        self.reason = reason


@dataclass(frozen=True)
class Item:
    """One line to send: program index (-1 preamble), source line (0 preamble), the text as
    sent and as written in the program (``source``; the same unless the streamer changed it)."""

    block: int
    line: int
    text: str
    source: str = ""


def items_for(
    program: Program,
    start_block: int,
    preamble: Sequence[str],
    replaced: Mapping[int, str] | None = None,
) -> list[Item]:
    """The preamble, then the program's blocks from ``start_block`` (``replaced``: block index ->
    the text to send instead, e.g. an arc made complete for a restart)."""
    first = program.position_of(start_block)
    rep = replaced or {}
    out = [Item(-1, 0, t, t) for t in preamble]
    for b in program.blocks[first:]:
        t = rep.get(b.index, b.text)
        out.append(Item(b.index, b.line, t, b.text))
    return out


class StreamerBase:
    """Common state of a stream. Subclasses implement ``_run(link, items)``.

    cfg : serial settings (port name or pyserial URL, baud, framing, flow control, timeout)
    sink : the block record (default: an in-memory sink, kept as ``self.sink``)
    clock : the time base of the record, s (default Unix time; the SimClock's ``now`` in the
        simulated rig)
    pace_bytes_per_s : writer pacing; ``"auto"`` paces at the line rate on a pseudo-terminal
        (``/dev/pts/*``), which has no line rate of its own, and not on a real port
    progress : show a tqdm bar on stderr (blocks acknowledged, and the block executing)
    """

    protocol = ""

    def __init__(
        self,
        cfg: SerialConfig,
        *,
        sink: BlockSink | None = None,
        clock: Callable[[], float] | None = None,
        pace_bytes_per_s: float | Literal["auto"] | None = "auto",
        progress: bool = False,
    ) -> None:
        check_settings(cfg, self.protocol)
        self.rules = protocol_of(self.protocol)  # what the protocol does, asked by rule
        self.cfg = cfg
        self.sink: BlockSink = sink if sink is not None else MemorySink()
        self.clock = clock if clock is not None else time.time
        self.pace: float | None = (
            (line_bytes_per_s(cfg) if is_pty(cfg.port) else None)
            if pace_bytes_per_s == "auto"
            else pace_bytes_per_s
        )
        self.show_progress = progress
        self.link: SerialLink | None = None
        self.interrupted = ""  # why the stream was interrupted ("SIGINT", ...), "" if not
        self._interrupt_event = threading.Event()
        self._reset_counters()

    def _reset_counters(self) -> None:
        self.blocks_sent = 0
        self.last_sent_block = -1
        self.last_ack_block = -1
        self.executing_block = -1
        self.last_executed_block = -1
        self.controller_state = ""
        self.transform = ""
        self.bytes_stripped = 0
        self.starved_fraction: float | None = None
        self._bytes0 = 0
        self._items: list[Item] = []
        self._rows: dict[int, BlockRow] = {}  # answered rows waiting for their execution time
        self._next_row = 0  # position of the next row to hand to the sink
        self._exec_started: dict[int, float] = {}  # item position -> execution start, s
        self._out: list[BlockRow] = []  # rows ready for the sink (written in batches)

    # -- to be provided by the protocols -----------------------------------------------------------
    def _begin(self) -> None:
        """Protocol hook: clear per-stream state (a streamer object may send many programs)."""

    def _prepare(self, program: Program, items: list[Item]) -> list[Item]:
        """Protocol hook, before the port is opened: check and transform the lines to send
        (DncError: nothing is sent)."""
        return items

    def _make_link(self) -> SerialLink:
        raise NotImplementedError

    def _run(self, link: SerialLink, items: list[Item]) -> None:
        raise NotImplementedError

    def _on_interrupt(self) -> None:
        """Protocol hook, called in the interrupting thread (a signal handler): act at once."""

    # -- the common frame ------------------------------------------------------------------------
    def _open(self) -> SerialLink:
        return self._make_link().start()

    def _serial(self) -> serial.SerialBase:
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

    def interrupt(self, reason: str = "interrupted") -> None:
        """Stop the stream from another thread or a signal handler (Ctrl-C, SIGTERM, SIGHUP):
        the protocol acts at once (GRBL: feed hold), then the stream ends with fault
        ``interrupted`` after its halt."""
        if not self.interrupted:
            self.interrupted = reason
        self._interrupt_event.set()
        try:
            self._on_interrupt()
        except Exception:  # noqa: BLE001 - a signal handler must not raise
            pass

    def stop(self) -> None:
        """Stop sending before the next line (ends with fault ``stopped``)."""
        self.interrupt("stopped by the operator")

    def _check_interrupt(self) -> None:
        if self._interrupt_event.is_set():
            kind = "stopped" if self.interrupted.startswith("stopped") else "interrupted"
            raise Fault(kind, self.interrupted or "interrupted")

    def send(
        self,
        program: Program,
        start_block: int = 0,
        preamble: Sequence[str] = (),
        link: SerialLink | None = None,
        replaced: Mapping[int, str] | None = None,
    ) -> StreamResult:
        """Stream ``preamble`` then ``program.blocks[start_block:]`` (``replaced``: block index ->
        text sent instead); return the summary.

        Raises :class:`StreamFault` (with ``.result``) if the stream stops part-way; the sink is
        closed in every case. ``link``: an already open link (remote request); it is not closed.
        """
        n_lines = program.blocks[-1].index + 1 if program.blocks else 0
        if not 0 <= start_block < max(n_lines, 1):
            raise DncError(
                f"start block = {start_block}: out of range for {program.name} (0-based block "
                f"index = source line - 1, expected 0..{n_lines - 1})"
            )
        items = items_for(program, start_block, preamble, replaced)
        self._reset_counters()
        self.interrupted = ""
        self._interrupt_event.clear()
        self._begin()
        # Everything before the start block counts as done: resume maths stays "last + 1".
        self.last_sent_block = self.last_ack_block = start_block - 1
        self.last_executed_block = start_block - 1
        self._start_block = start_block
        try:
            items = self._prepare(program, items)
        except DncError as exc:  # refused before anything was sent
            self.sink.event("not_started", self.clock(), str(exc))
            self.sink.close()
            raise
        self._items = items
        self._n_items = len(items)
        own_link = link is None
        t0 = time.perf_counter()
        self._progress = Progress(len(items), self.show_progress, f"dnc {self.protocol}")
        fault: Fault | None = None
        try:
            self.link = link if link is not None else self._open()
            self._bytes0 = self.link.bytes_written
            what = f"{program.name} from block {start_block}"
            if self.transform:
                what += f" ({self.transform}: {self.bytes_stripped} characters)"
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
            try:
                self._flush_rows(final=True)
            finally:
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
            raise StreamFault(self._fault_message(fault, result), fault.kind, result)
        return result

    def _fault_message(self, fault: Fault, result: StreamResult) -> str:
        last = result.last_acknowledged_block
        what = self.rules.done
        done = result.last_executed_block
        msg = f"{self.protocol} stream stopped ({fault.kind}): {fault.reason}"
        msg += f"; last {what} block: {last}"
        if result.executing_block >= 0:
            msg += f"; executing block: {result.executing_block}"
        msg += f"; last block known executed: {done}"
        nxt = self._next_block_after(done)
        if nxt is not None:
            msg += f"; resume with --start-block {nxt}"
        else:
            msg += "; resume with --start-block <the block after the last one the control executed>"
        return msg

    def _next_block_after(self, block: int) -> int | None:
        """The program index of the first item after ``block``; None if unknown."""
        if block < -1:
            return None
        for it in self._items:
            if it.block > block:
                return it.block
        return None

    def executed_blocks(self) -> list[tuple[int, float, float, str]]:
        """(program block index, start s, end s, text as sent) of every line known to have
        started executing, on the stream's clock: what ties force samples to the block cutting
        them (GRBL: from the status reports; Fanuc: predicted). A line's end is the next one's
        start (NaN for the last one and for lines still running). Preamble lines are -1."""
        out = []
        keys = sorted(self._exec_started)
        for n, k in enumerate(keys):
            if not 0 <= k < len(self._items):
                continue
            it = self._items[k]
            t0 = self._exec_started[k]
            t1 = self._exec_started[keys[n + 1]] if n + 1 < len(keys) else float("nan")
            out.append((it.block, t0, t1, it.text))
        return out

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
            executing_block=self.executing_block,
            last_executed_block=self.last_executed_block,
            transform=self.transform,
            bytes_stripped=self.bytes_stripped,
            controller_state=self.controller_state,
        )

    # -- the record: rows wait for their execution start -----------------------------------------
    def _answered(self, pos: int, row: BlockRow) -> None:
        """Item ``pos`` has its row (sent, answered or not); it goes to the sink once its
        execution start is known (:meth:`_executing`) or at the end."""
        self._rows[pos] = row
        self._flush_rows()

    def _executing(self, started: Mapping[int, float], current: int, done: int) -> None:
        """Execution starts by item position, the item executing and the last one done."""
        for k, t in started.items():
            self._exec_started.setdefault(k, t)
        items = self._items
        if 0 <= current < len(items):
            b = items[current].block
            self.executing_block = b if b >= 0 else self.executing_block
        if 0 <= done < len(items):
            b = max((it.block for it in items[: done + 1]), default=-1)
            self.last_executed_block = max(self.last_executed_block, b)
        self._flush_rows()

    def _flush_rows(self, final: bool = False, batch: int = 32) -> None:
        out: list[BlockRow] = []
        while self._next_row in self._rows:
            k = self._next_row
            t = self._exec_started.get(k)
            if t is None and not final:
                break
            row = self._rows.pop(k)
            if t is not None:  # a line runs once it has arrived, never before
                row = dataclasses.replace(row, exec_time_s=max(float(t), row.send_time_s))
            out.append(row)
            self._next_row += 1
        if final:  # rows never answered nor executed keep their place in order
            for k in sorted(self._rows):
                out.append(self._rows.pop(k))
        self._out.extend(out)
        if self._out and (final or len(self._out) >= batch):
            rows, self._out = self._out, []
            self._record(rows)

    def _record(self, rows: Sequence[BlockRow]) -> None:
        if self.sink_closed():
            return
        self.sink.append_blocks(rows)
        if self.link is not None:
            extra = ""
            if self.rules.paced_by_ok:  # answered lines: the last acknowledged is known
                extra = f"ack {self.last_ack_block} exec {self.executing_block}"
            self._progress.update(len(rows), self.link.bytes_written - self._bytes0, extra)
