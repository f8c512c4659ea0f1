"""The block record: every block sent, with its send time and acknowledgement time.

The streamer writes rows to a *sink*, any object with ``append_blocks(rows)``, ``event(kind,
time_s, detail)`` and ``close()`` (:class:`BlockSink`). Sinks here: :class:`MemorySink` (tests, the
simulated rig) and :class:`CsvSink` (the CLI's ``--record FILE``). The HDF5 run writer of
``rig.log.writer`` is adapted by :class:`rig.dnc.sinks.LoggerSink`.

Rows are appended in block order. Times are seconds on the streamer's clock (Unix time by default,
the :class:`rig.sim.clock.SimClock` in the simulated rig). ``ack_time_s`` is NaN where the protocol
gives no acknowledgement (Fanuc drip feed) or the block was sent but never acknowledged;
``exec_time_s`` is when the control started executing the block (GRBL: from its status reports;
Fanuc: predicted from the time model), NaN where that is not known. A row is appended once its
execution start is known (or the stream has ended), so rows come some blocks behind the sending.
Preamble blocks of a restart carry ``block = -1`` and ``line = 0``.
"""

from __future__ import annotations

import csv
import math
import threading
from collections.abc import Sequence
from dataclasses import astuple, dataclass, fields
from pathlib import Path
from typing import Protocol, runtime_checkable

from rig.dnc.errors import DncError


@dataclass(frozen=True)
class BlockRow:
    """One block as sent.

    block : 0-based index of the block in the program (-1 for restart-preamble blocks)
    line : 1-based source line (0 for preamble blocks)
    text : the block as sent, without end-of-block characters
    n_bytes : bytes written for it, end of block included
    send_time_s : s, when its first byte was written
    ack_time_s : s, when the controller acknowledged it (NaN: no acknowledgement)
    status : ``"sent"`` (no acknowledgement in the protocol), ``"ok"``, ``"error:N"``,
        ``"unacknowledged"`` (sent, but the stream stopped before its answer)
    exec_time_s : s, when the control started executing it (estimated; NaN: not known / never)
    """

    block: int
    line: int
    text: str
    n_bytes: int
    send_time_s: float
    ack_time_s: float = math.nan
    status: str = "sent"
    exec_time_s: float = math.nan


COLUMNS: tuple[str, ...] = tuple(f.name for f in fields(BlockRow))


@runtime_checkable
class BlockSink(Protocol):
    """Where the streamer writes its record. Must be safe to call from the streamer's thread."""

    def append_blocks(self, rows: Sequence[BlockRow]) -> None: ...

    def event(self, kind: str, time_s: float, detail: str = "") -> None: ...

    def close(self) -> None: ...


class MemorySink:
    """Keeps rows and events in lists (thread-safe)."""

    def __init__(self) -> None:
        self.rows: list[BlockRow] = []
        self.events: list[tuple[str, float, str]] = []
        self.closed = False
        self._lock = threading.Lock()

    def append_blocks(self, rows: Sequence[BlockRow]) -> None:
        with self._lock:
            if self.closed:
                raise DncError("block record: append after close")
            self.rows.extend(rows)

    def event(self, kind: str, time_s: float, detail: str = "") -> None:
        with self._lock:
            self.events.append((kind, time_s, detail))

    def close(self) -> None:
        with self._lock:
            self.closed = True


class CsvSink:
    """Rows to a CSV file (header = :data:`COLUMNS`), flushed after every append so the file is
    valid at any moment; events go to ``<file>.events.csv``."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self._f = self.path.open("w", newline="", encoding="utf-8")
            self._ef = self.path.with_suffix(self.path.suffix + ".events.csv").open(
                "w", newline="", encoding="utf-8"
            )
        except OSError as exc:
            raise DncError(f"{self.path}: cannot write the block record: {exc}") from None
        self._w = csv.writer(self._f)
        self._ew = csv.writer(self._ef)
        self._w.writerow(COLUMNS)
        self._ew.writerow(("kind", "time_s", "detail"))
        self._lock = threading.Lock()
        self.closed = False

    def append_blocks(self, rows: Sequence[BlockRow]) -> None:
        with self._lock:
            self._w.writerows(astuple(r) for r in rows)
            self._f.flush()

    def event(self, kind: str, time_s: float, detail: str = "") -> None:
        with self._lock:
            self._ew.writerow((kind, repr(time_s), detail))
            self._ef.flush()

    def close(self) -> None:
        with self._lock:
            if not self.closed:
                self._f.close()
                self._ef.close()
                self.closed = True


def read_csv_record(path: str | Path) -> list[BlockRow]:
    """Rows of a :class:`CsvSink` file back as :class:`BlockRow` (for checks and tests); a record
    written before ``exec_time_s`` existed reads with it NaN."""
    with Path(path).open(newline="", encoding="utf-8") as f:
        r = csv.DictReader(f)
        if tuple(r.fieldnames or ()) not in (COLUMNS, COLUMNS[:-1]):
            raise DncError(f"{path}: not a block record (columns {r.fieldnames})")
        return [
            BlockRow(
                int(d["block"]),
                int(d["line"]),
                d["text"],
                int(d["n_bytes"]),
                float(d["send_time_s"]),
                float(d["ack_time_s"]),
                d["status"],
                float(d.get("exec_time_s") or math.nan),
            )
            for d in r
        ]
