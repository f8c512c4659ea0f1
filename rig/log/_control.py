"""The run writer's records beside the samples: the thread-safe calls other threads make (events,
NC blocks, acks, execution times, conditions, rig, program, calibration), queued as small records
and written by the writer thread (:meth:`ControlRecords._drain_control`), and the accounting of
blocks dropped on a full queue (consecutive drops make one ``queue_full`` event).

A mixin of :class:`rig.log.writer.RunWriter`, which holds the state named below.
"""

from __future__ import annotations

import collections
import hashlib
import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import h5py
import numpy as np

from analysis.runs import file as rf
from rig.daq import Calibration, DaqEvent, DaqInfo
from rig.log._file import (
    RunWriterError,
    append_rows,
    jsonable,
    write_acks,
    write_text,
    write_zero_and_drift,
)


class ControlRecords:
    """Events, NC blocks, acks, metadata and drops: queued by any thread, written by the
    writer thread."""

    # the RunWriter's state these methods use
    path: Any
    info: DaqInfo
    clock: Callable[[], float]
    _f: h5py.File
    _control: collections.deque[tuple[str, Any]]
    _drop: list[int] | None
    _blocks_dropped: int
    _samples_dropped: int
    _block_rows: dict[int, int]
    _t0_s: float

    # ------------------------------------------------------------------------------------------
    # Thread-safe API for other threads.
    # ------------------------------------------------------------------------------------------

    def event(
        self,
        kind: str,
        message: str = "",
        *,
        time_s: float | None = None,
        sample: int | None = None,
    ) -> None:
        """Record an event (interlock, pause, fault, note ...) at run-clock ``time_s`` (default:
        now) or at device ``sample``."""
        if kind not in rf.EVENT_KINDS:
            raise RunWriterError(
                f"event kind {kind!r}: expected one of {', '.join(rf.EVENT_KINDS)}"
            )
        t = self.clock() if time_s is None and sample is None else time_s
        self._control.append(
            ("event", DaqEvent(kind, -1 if sample is None else int(sample), message,
                               time_s=math.nan if t is None else float(t)))
        )  # fmt: skip

    def append_blocks(
        self,
        block: int | Sequence[int],
        line: int | Sequence[int],
        text: str | Sequence[str],
        send_s: float | Sequence[float],
        ack_s: float | Sequence[float] | None = None,
        exec_s: float | Sequence[float] | None = None,
    ) -> None:
        """Append NC blocks sent by the DNC streamer (scalars or equal-length sequences).

        block : 0-based block index; line : 1-based source line; text : the block as sent;
        send_s, ack_s : run-clock times, s (ack NaN/None until acknowledged, see ack_blocks);
        exec_s : run-clock time the control started executing the block, s (NaN/None: unknown).
        """
        blocks = np.atleast_1d(np.asarray(block, dtype=np.int64))
        n = len(blocks)
        texts = [text] if isinstance(text, str) else list(text)
        lines = np.broadcast_to(np.asarray(line, dtype=np.int64), (n,))
        sends = np.broadcast_to(np.asarray(send_s, dtype=np.float64), (n,))
        acks = np.broadcast_to(
            np.asarray(np.nan if ack_s is None else ack_s, dtype=np.float64), (n,)
        )
        if len(texts) != n:
            raise RunWriterError(f"append_blocks: {n} block indices but {len(texts)} texts")
        rows = np.zeros(n, dtype=rf.BLOCK_DTYPE)
        rows["block"], rows["line"], rows["send_s"], rows["ack_s"] = blocks, lines, sends, acks
        rows["exec_s"] = np.broadcast_to(
            np.asarray(np.nan if exec_s is None else exec_s, dtype=np.float64), (n,)
        )
        for i, t in enumerate(texts):
            b = t.encode("utf-8")
            if len(b) > rf.BLOCK_TEXT_BYTES:
                self.event(
                    rf.EV_NOTE,
                    f"block {blocks[i]} text is {len(b)} bytes; table keeps the first "
                    f"{rf.BLOCK_TEXT_BYTES} (full text in meta/program)",
                    time_s=float(sends[i]),
                )
            rows["text"][i] = b[: rf.BLOCK_TEXT_BYTES]
        self._control.append(("blocks", rows))

    def ack_blocks(self, block: int | Sequence[int], ack_s: float | Sequence[float]) -> None:
        """Set the ack time (run clock, s) of blocks already appended (latest row per block)."""
        b = np.atleast_1d(np.asarray(block, dtype=np.int64))
        a = np.broadcast_to(np.asarray(ack_s, dtype=np.float64), b.shape)
        self._control.append(("ack", (b.copy(), a.copy())))

    def set_exec_times(
        self, rows: Sequence[int], exec_s: Sequence[float], complete: bool = False
    ) -> None:
        """Set ``exec_s`` of the NC-blocks table by row (the k-th block sent is row k; NaN: it
        never started): the control's own record of when each block ran, which replaces the
        streamer's estimate (an estimate knows nothing of a feed hold). ``complete``: the record
        names every block that started, so the rows it does not name never ran (NaN)."""
        r = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        e = np.broadcast_to(np.asarray(exec_s, dtype=np.float64), r.shape)
        self._control.append(("exec", (r.copy(), e.copy(), complete)))

    def set_conditions(self, conditions: object) -> None:
        """Cutting conditions (tool, material, spindle_rpm, feed_mm_min, fz_mm, depth_mm, ...):
        a mapping, a dataclass or a pydantic model; stored as JSON, the latest call wins."""
        self._control.append(("text", (rf.META_CONDITIONS, json.dumps(jsonable(conditions)))))

    def set_rig(self, rig: Mapping[str, object]) -> None:
        """Rig description (device, dynamometer, amplifier, calibration id, machine ...)."""
        self._control.append(("text", (rf.META_RIG, json.dumps(jsonable(rig)))))

    def set_program(self, text: str, name: str = "") -> None:
        """The NC program sent in this run; its SHA-256 and line count go to program_info."""
        info = {
            "name": name,
            "sha256": hashlib.sha256(text.encode("utf-8")).hexdigest(),
            "lines": text.count("\n") + (0 if text.endswith("\n") or not text else 1),
        }
        self._control.append(("text", (rf.META_PROGRAM, text)))
        self._control.append(("text", (rf.META_PROGRAM_INFO, json.dumps(info))))

    def set_calibration(self, cal: Calibration, message: str = "") -> None:
        """Update zero and drift (after reset/operate or a drift fit); the sheet values are fixed
        when the file is created. Also records a ``zero`` event at ``cal.zero_time_s``."""
        if rf.CAL_VOLTS_TO_N not in self._f:
            raise RunWriterError(f"{self.path}: created without a calibration; cannot update it")
        self._control.append(("cal", cal))
        if math.isfinite(cal.zero_time_s):
            self.event(rf.EV_ZERO, message or "amplifier zeroed", time_s=cal.zero_time_s)

    # ------------------------------------------------------------------------------------------
    # Drops (producer side, under the writer's lock) and the writer thread's records.
    # ------------------------------------------------------------------------------------------

    def _record_drop(self, first: int, n: int) -> None:
        self._blocks_dropped += 1
        self._samples_dropped += n
        if self._drop is not None and self._drop[0] + self._drop[1] == first:
            self._drop[1] += n  # consecutive drops make one event
        else:
            if self._drop is not None:
                self._flush_drop()
            self._drop = [first, n]

    def _flush_drop(self) -> None:
        first, n = self._drop  # type: ignore[misc]
        self._drop = None
        msg = f"logger queue full: {n} samples dropped"
        self._control.append(("event", DaqEvent(rf.EV_QUEUE_FULL, first, msg, lost=n)))

    def _drain_control(self) -> None:
        events: list[DaqEvent] = []
        while self._control:
            kind, payload = self._control.popleft()
            if kind == "event":
                events.append(payload)
                continue
            if events:  # keep order between events and the rest
                self._write_events(events)
                events = []
            if kind == "text":
                write_text(self._f, *payload)
            elif kind == "blocks":
                self._write_blocks(payload)
            elif kind == "ack":
                self._write_acks(*payload)
            elif kind == "exec":
                self._write_exec(*payload)
            elif kind == "cal":
                write_zero_and_drift(self._f, payload)
        if events:
            self._write_events(events)

    def _write_events(self, events: list[DaqEvent]) -> None:
        rows = np.zeros(len(events), dtype=rf.EVENT_DTYPE)
        now = time.time()
        rate, t0 = self.info.rate_hz, self._t0_s
        for i, e in enumerate(events):
            sample, t = e.sample, e.time_s
            if sample < 0 and math.isfinite(t) and math.isfinite(t0):
                sample = int(round((t - t0) * rate))
            if not math.isfinite(t) and sample >= 0 and math.isfinite(t0):
                t = t0 + sample / rate
            rows[i] = (sample, e.lost, t, now, e.kind.encode()[:16],
                       e.message.encode("utf-8")[: rf.EVENT_MESSAGE_BYTES])  # fmt: skip
        append_rows(self._f[rf.EVENTS], rows)

    def _write_blocks(self, rows: np.ndarray) -> None:
        first = append_rows(self._f[rf.BLOCKS], rows)
        self._block_rows.update(zip(rows["block"].tolist(), range(first, first + len(rows))))

    def _write_exec(self, rows: np.ndarray, exec_s: np.ndarray, complete: bool) -> None:
        ds = self._f[rf.BLOCKS]
        ok = (rows >= 0) & (rows < ds.shape[0])
        if ds.shape[0] and (ok.any() or complete):
            table = ds[()]
            if complete:
                table["exec_s"] = np.nan
            table["exec_s"][rows[ok]] = exec_s[ok]
            ds[...] = table
        if not ok.all():
            self._write_events(
                [DaqEvent(rf.EV_NOTE, -1, f"exec time for rows never appended: "
                                          f"{rows[~ok][:10].tolist()}")]
            )  # fmt: skip

    def _write_acks(self, blocks: np.ndarray, acks: np.ndarray) -> None:
        unknown = write_acks(self._f[rf.BLOCKS], self._block_rows, blocks, acks)
        if unknown:
            self._write_events(
                [DaqEvent(rf.EV_NOTE, -1, f"ack for blocks never appended: {unknown[:10]}")]
            )
