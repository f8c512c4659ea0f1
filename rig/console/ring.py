"""The live ring: one memory-mapped file shared by the campaign process (the only writer of
samples, run info and status) and the console server (readers; the only writer of commands).

The HDF5 run file flushes about once a second, too slow for a live view, and reading it would
compete with the logger; the ring costs the acquisition thread one copy of each block into
shared memory (``/dev/shm``), and a server that dies or stalls cannot hold anything up.

Layout: a header of int64 fields, three JSON regions (run info, status, command) and a ring of
samples per channel ``(c, capacity)``: int16 codes as the DAQ gives them, volts as float32; the
DAQ's ``(c, n)`` blocks go in as one contiguous copy per channel. Each JSON region is
a seqlock (its sequence number is odd while it is written); samples are copied first and
``rows_written`` raised after, so a reader that copies and then re-reads ``rows_written`` knows
which of its rows may have been overwritten meanwhile and drops them.
"""

from __future__ import annotations

import json
import mmap
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from rig.errors import RigError

MAGIC = 0x3145564954554332  # b"2CUTLIVE1" as a little-endian int64 tag
HEADER_BYTES = 4096
META_BYTES = 1 << 20  # run info: channels, calibration, the program's lines
STATUS_BYTES = 1 << 18
COMMAND_BYTES = 4096
SAMPLE_BYTES = 32 << 20  # 60 s of 3 channels of float32 volts at 40 kHz

# header fields (int64 index)
(_MAGIC, _PID, _HEARTBEAT_NS, _GEN, _ROWS, _CAPACITY, _CHANNELS, _ITEMSIZE, _ROW_TO_SAMPLE,
 _CLOSED, _WRITTEN_NS) = range(11)  # fmt: skip
_SEQ = {"meta": 16, "status": 18, "command": 20}  # seq at k, length at k + 1
_OFFSET = {
    "meta": HEADER_BYTES,
    "status": HEADER_BYTES + META_BYTES,
    "command": HEADER_BYTES + META_BYTES + STATUS_BYTES,
}
_SIZE = {"meta": META_BYTES, "status": STATUS_BYTES, "command": COMMAND_BYTES}
_SAMPLES_AT = HEADER_BYTES + META_BYTES + STATUS_BYTES + COMMAND_BYTES
_DTYPES = {2: np.dtype(np.int16), 4: np.dtype(np.float32), 8: np.dtype(np.float64)}
#: what the ring keeps of the DAQ's samples: int16 codes as they are; volts as float32 (half the
#: bytes of float64 to copy on the acquisition thread; 1e-7 relative, far below the page's 0.1 N)
_STORED = {2: np.dtype(np.int16), 8: np.dtype(np.float32)}


class RingError(RigError):
    """A live ring that cannot be created or read."""


def default_ring_path() -> Path:
    """A new ring file in shared memory (``/dev/shm``), or the temporary folder without it."""
    shm = Path("/dev/shm")
    folder = shm if shm.is_dir() and os.access(shm, os.W_OK) else Path(tempfile.gettempdir())
    return folder / f"cutlab-live-{os.getpid()}-{time.time_ns() % 10**9}.ring"


def _oldest_first(buf: np.ndarray, start: int, stop: int) -> np.ndarray:
    """Rows ``start`` .. ``stop`` (absolute row numbers) of the ring ``buf`` (c, cap) as a new
    (n, c) array: at most two slice copies (no index array)."""
    cap = buf.shape[1]
    out = np.empty((stop - start, buf.shape[0]), buf.dtype)
    i, n = start % cap, stop - start
    k = min(n, cap - i)
    out[:k] = buf[:, i : i + k].T
    out[k:] = buf[:, : n - k].T
    return out


class _Mapped:
    def __init__(self, path: Path, mm: mmap.mmap) -> None:
        self.path = path
        self._mm = mm
        # the int64 header as a memoryview: a load or store a third the cost of numpy's (the
        # acquisition thread makes three a block; the status thread and the readers many)
        self.h = memoryview(mm)[:HEADER_BYTES].cast("q")
        self._last: dict[str, bytes] = {}  # the JSON last written per region

    def _region(self, name: str) -> memoryview:
        return memoryview(self._mm)[_OFFSET[name] : _OFFSET[name] + _SIZE[name]]

    @staticmethod
    def dumps(obj: Any) -> bytes:
        """The JSON the regions hold (compact; NaN refused; anything else as its str)."""
        return json.dumps(obj, separators=(",", ":"), allow_nan=False, default=str).encode()

    def _put_json(self, name: str, obj: Any) -> None:
        self._put_bytes(name, self.dumps(obj))

    def _put_bytes(self, name: str, data: bytes) -> None:
        if len(data) > _SIZE[name]:
            raise RingError(f"live ring: {name} is {len(data)} bytes, room for {_SIZE[name]}")
        if data == self._last.get(name):
            return  # unchanged: no write, and readers see no new sequence number
        self._last[name] = data
        k = _SEQ[name]
        self.h[k] += 1  # odd: being written
        self._region(name)[: len(data)] = data
        self.h[k + 1] = len(data)
        self.h[k] += 1

    def get_json(self, name: str) -> tuple[int, Any]:
        """(sequence number, the object; None if never written)."""
        k = _SEQ[name]
        for _ in range(100):
            s1 = int(self.h[k])
            if s1 % 2:
                time.sleep(0.0005)
                continue
            n = int(self.h[k + 1])
            data = bytes(self._region(name)[:n])
            if int(self.h[k]) == s1:
                return s1, (json.loads(data) if n else None)
        return int(self.h[k]), None

    def seq(self, name: str) -> int:
        return int(self.h[_SEQ[name]])

    def close(self) -> None:
        self.h.release()  # drop the views before the map
        self.h = memoryview(bytearray(HEADER_BYTES)).cast("q")
        try:
            self._mm.close()
        except BufferError:  # a reader's array still points into it: the GC closes it
            pass


class RingWriter(_Mapped):
    """The campaign side: creates the file; one thread writes samples, others JSON regions."""

    def __init__(self, path: str | Path | None = None, sample_bytes: int = SAMPLE_BYTES) -> None:
        p = Path(path) if path is not None else default_ring_path()
        size = _SAMPLES_AT + int(sample_bytes)
        try:
            fd = os.open(p, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o600)
            try:
                os.ftruncate(fd, size)  # sparse: pages cost memory only once written
                mm = mmap.mmap(fd, size)
            finally:
                os.close(fd)
        except OSError as exc:
            raise RingError(f"live ring {p}: {exc.strerror or exc}") from None
        super().__init__(p, mm)
        self._sample_bytes = int(sample_bytes)
        self._rows: np.ndarray | None = None
        self._cap = self._w = 0
        self.h[_PID] = os.getpid()
        self.heartbeat()
        self.h[_MAGIC] = MAGIC

    def heartbeat(self) -> None:
        self.h[_HEARTBEAT_NS] = time.time_ns()

    def begin_run(self, meta: dict[str, Any], n_channels: int, dtype: np.dtype) -> None:
        """A new run (a new DAQ start): its info, and an empty sample ring of its shape."""
        stored = _STORED.get(np.dtype(dtype).itemsize)
        if stored is None:
            raise RingError(f"live ring: samples of {dtype} (expected int16 or float64)")
        itemsize = stored.itemsize
        capacity = self._sample_bytes // (n_channels * itemsize)
        buf = np.frombuffer(self._mm, stored, capacity * n_channels, _SAMPLES_AT)
        self._rows = buf.reshape(n_channels, capacity)
        self._cap, self._w = capacity, 0  # the writer's own copy of the header's fields
        self.h[_ROWS] = 0
        self.h[_ROW_TO_SAMPLE] = 0
        self.h[_CAPACITY], self.h[_CHANNELS], self.h[_ITEMSIZE] = capacity, n_channels, itemsize
        self.put_meta(meta)
        self.h[_GEN] += 1  # last: a reader seeing the new generation sees all of the above

    def put_meta(self, meta: dict[str, Any]) -> None:
        self._put_json("meta", meta)

    def put_status(self, status: dict[str, Any]) -> None:
        self._put_json("status", status)

    def put_status_json(self, data: bytes) -> None:
        """The status already encoded by :meth:`dumps` (the live side splices in the events'
        JSON, encoded once per new event rather than 25 times a second)."""
        self._put_bytes("status", data)

    def write(self, first_sample: int, data: np.ndarray) -> None:
        """Append a DAQ block ``data`` (c, n) starting at device sample ``first_sample``."""
        # The acquisition thread's cost: one copy per channel row into the preallocated ring
        # (two where it wraps), three header stores; no lock, no allocation, no Python loop.
        rows = self._rows
        if rows is None:
            return
        n = data.shape[1]
        cap, w = self._cap, self._w
        if n > cap:  # a block longer than the ring: keep its end
            data, first_sample, n = data[:, n - cap :], first_sample + n - cap, cap
        i = w % cap
        if i + n <= cap:  # the usual case: the block whole, no view of it to make
            np.copyto(rows[:, i : i + n], data, casting="same_kind")
        else:
            k = cap - i
            np.copyto(rows[:, i:], data[:, :k], casting="same_kind")
            np.copyto(rows[:, : n - k], data[:, k:], casting="same_kind")
        self._w = w + n
        h = self.h
        h[_ROW_TO_SAMPLE] = first_sample - w  # holes: later rows keep their device time
        h[_WRITTEN_NS] = time.time_ns()  # the page's sample-to-screen latency starts here
        h[_ROWS] = w + n

    def rows_so_far(self) -> np.ndarray:
        """A copy of the current run's rows (n, c) still in the ring (oldest first)."""
        rows = self._rows
        if rows is None:
            return np.zeros((0, 0))
        return _oldest_first(rows, max(0, self._w - self._cap), self._w)

    def read_command(self) -> tuple[int, Any]:
        return self.get_json("command")

    def close(self, unlink: bool = False) -> None:
        self.h[_CLOSED] = 1
        self.heartbeat()
        self._rows = None
        super().close()
        if unlink:
            self.path.unlink(missing_ok=True)


class RingReader(_Mapped):
    """The server side: reads samples, run info and status; writes commands."""

    def __init__(self, path: str | Path) -> None:
        p = Path(path)
        try:
            with open(p, "r+b") as f:
                mm = mmap.mmap(f.fileno(), 0)
        except (OSError, ValueError) as exc:
            raise RingError(f"live ring {p}: cannot open: {exc}") from None
        if (size := len(mm)) < _SAMPLES_AT:
            mm.close()
            raise RingError(f"live ring {p}: {size} bytes, not a cutlab live ring")
        super().__init__(p, mm)
        if int(self.h[_MAGIC]) != MAGIC:
            self.close()
            raise RingError(f"live ring {p}: not a cutlab live ring (bad magic)")

    @property
    def generation(self) -> int:
        return int(self.h[_GEN])

    @property
    def rows_written(self) -> int:
        """Rows written in the current generation (run)."""
        return int(self.h[_ROWS])

    @property
    def writer_pid(self) -> int:
        return int(self.h[_PID])

    @property
    def closed(self) -> bool:
        return bool(self.h[_CLOSED])

    @property
    def row_to_sample(self) -> int:
        """Device sample number less ring row number (rows after a hole keep their time)."""
        return int(self.h[_ROW_TO_SAMPLE])

    @property
    def written_ns(self) -> int:
        """Wall clock (``time.time_ns``) when the newest block came into the ring (0: none)."""
        return int(self.h[_WRITTEN_NS])

    def heartbeat_age_s(self) -> float:
        return (time.time_ns() - int(self.h[_HEARTBEAT_NS])) / 1e9

    def rows_since(
        self, gen: int, cursor: int, most: int | None = None
    ) -> tuple[int, int, int, np.ndarray]:
        """Rows (n, c) of run generation ``gen`` from row ``cursor`` on (a new generation: from
        its oldest row in the ring; ``most``: only the newest that many). Returns (generation,
        first row, row-to-sample offset, rows)."""
        for _ in range(10):
            g = self.generation
            cap, c, size = int(self.h[_CAPACITY]), int(self.h[_CHANNELS]), int(self.h[_ITEMSIZE])
            w = int(self.h[_ROWS])
            if g == 0 or cap <= 0 or size not in _DTYPES:
                return g, 0, 0, np.zeros((0, max(c, 0)))
            start = cursor if g == gen else 0
            start = max(start, w - cap, w - most if most is not None else 0, 0)
            buf = np.frombuffer(self._mm, _DTYPES[size], cap * c, _SAMPLES_AT).reshape(c, cap)
            rows = _oldest_first(buf, start, max(start, w))
            offset = int(self.h[_ROW_TO_SAMPLE])
            w2 = int(self.h[_ROWS])
            if self.generation != g:
                continue  # a new run began while copying
            lost = max(0, w2 - cap - start)  # overwritten while copying
            return g, start + lost, offset, rows[lost:]
        return self.generation, cursor, 0, np.zeros((0, 0))

    def send_command(self, command: dict[str, Any]) -> int:
        """Post a command for the campaign process; returns its sequence number."""
        seq = self.seq("command") + 2
        self._put_json("command", {**command, "seq": seq})
        return seq
