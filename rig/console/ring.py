"""The live ring: one memory-mapped file shared by the campaign process (the only writer of
samples, run info and status) and the console server (readers; the only writer of commands).

The HDF5 run file flushes about once a second, too slow for a live view, and reading it would
compete with the logger. So the ring shares the run writer's own copy of each block: the
writer's queue buffers are slots of this file (:meth:`RingWriter.buffers`), and the one copy it
makes anyway (the DAQ's block as the file's (n, c) rows) is what the page sees. The acquisition
thread pays two stores around that copy and a log entry a block, nothing more (issue 32: the
logger within 5 % of its bare speed with the console open; a copy of each block into the ring
cost it 6 %). Without a run writer that shares (tests, the bench's tap) :meth:`RingWriter.write`
copies blocks into the slots itself.

A slot holds its block until the writer reuses it (its pool cycles: 64 buffers of 0.1 s blocks
are about 6 s), so each reader keeps its own history: :meth:`RingReader.pull` copies the blocks
published since it last looked into a private mirror (c, capacity) of the reader's process
(int16 codes as the DAQ gives them, volts as float32), off the acquisition thread. A reader that
falls behind a slot's life loses those blocks (a hole, like a gap in the DAQ), never reads a
torn one: a slot's sequence number is odd while it is written and raised again after, and a
block is taken only if its slot's number is, before and after the copy, the one published with
it. A server that dies or stalls cannot hold anything up.

Layout: a header of int64 fields, three JSON regions (run info, status, command; each a seqlock:
its sequence number odd while it is written), the slots' sequence numbers, the log of the last
``LOG_ENTRIES`` published blocks (sequence, slot, first device sample, rows) and the slots
(nslots, rows, c) in the DAQ's type.
"""

from __future__ import annotations

import json
import mmap
import os
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from rig.errors import RigError

MAGIC = 0x3245564954554332  # b"2CUTLIVE2" as a little-endian int64 tag (2: the slots' layout)
HEADER_BYTES = 4096
META_BYTES = 1 << 20  # run info: channels, calibration, the program's lines
STATUS_BYTES = 1 << 18
COMMAND_BYTES = 4096
MAX_SLOTS = 4096
SEQS_BYTES = 8 * MAX_SLOTS
LOG_ENTRIES = 1024  # published blocks a reader can still find: 100 s of 0.1 s blocks
LOG_BYTES = 4 * 8 * LOG_ENTRIES
# the slots' address space (sparse: only the slots a writer takes are given memory, reserved
# with fallocate so a full /dev/shm refuses them instead of failing a store with SIGBUS)
SAMPLE_BYTES = 1 << 30
OWN_SLOTS = 64  # slots :meth:`RingWriter.write` cycles through (no writer to share with)
MIRROR_BYTES = 32 << 20  # a reader's history: 60 s of 3 channels of float32 volts at 40 kHz
DEFAULT_SLOT_ROWS = 4096  # rows a slot when the run's block size is not given

# header fields (int64 index)
(_MAGIC, _PID, _HEARTBEAT_NS, _GEN, _PUBLISHED, _SLOT_ROWS, _CHANNELS, _ITEMSIZE, _NSLOTS,
 _CLOSED, _WRITTEN_NS) = range(11)  # fmt: skip
_SEQ = {"meta": 16, "status": 18, "command": 20}  # seq at k, length at k + 1
_OFFSET = {
    "meta": HEADER_BYTES,
    "status": HEADER_BYTES + META_BYTES,
    "command": HEADER_BYTES + META_BYTES + STATUS_BYTES,
}
_SIZE = {"meta": META_BYTES, "status": STATUS_BYTES, "command": COMMAND_BYTES}
_SEQS_AT = HEADER_BYTES + META_BYTES + STATUS_BYTES + COMMAND_BYTES
_LOG_AT = _SEQS_AT + SEQS_BYTES
_SAMPLES_AT = _LOG_AT + LOG_BYTES
_DTYPES = {2: np.dtype(np.int16), 8: np.dtype(np.float64)}  # the slots: the DAQ's samples
#: what a reader's mirror keeps of them: int16 codes as they are; volts as float32 (half the
#: memory; 1e-7 relative, far below the page's 0.1 N)
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


def _block(m: _Mapped, slots: np.ndarray, p: int) -> tuple[int, np.ndarray] | None:
    """Published block number ``p`` of this run as (first device sample, a copy of its rows
    (n, c)); None if its slot or its log entry has been reused since (or is being written)."""
    log, e = m.log, 4 * (p % LOG_ENTRIES)
    seq, k, first, n = log[e], log[e + 1], log[e + 2], log[e + 3]
    if seq % 2 or not 0 <= k < len(slots) or not 0 < n <= slots.shape[1] or m.seqs[k] != seq:
        return None
    rows = slots[k, :n].copy()
    if m.seqs[k] != seq or m.h[_PUBLISHED] - p >= LOG_ENTRIES:
        return None  # the slot was refilled, or the entry rewritten, while copying
    return first, rows


class _Mapped:
    def __init__(self, path: Path, mm: mmap.mmap) -> None:
        self.path = path
        self._mm = mm
        # the int64 header as a memoryview: a load or store a third the cost of numpy's (the
        # acquisition thread makes three a block; the status thread and the readers many)
        self.h = memoryview(mm)[:HEADER_BYTES].cast("q")
        self.seqs = memoryview(mm)[_SEQS_AT : _SEQS_AT + SEQS_BYTES].cast("q")  # a slot's
        self.log = memoryview(mm)[_LOG_AT : _LOG_AT + LOG_BYTES].cast("q")  # 4 fields a block
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
        for v in (self.h, self.seqs, self.log):
            v.release()  # drop the views before the map (later stores go to scratch memory)
        self.h = memoryview(bytearray(HEADER_BYTES)).cast("q")
        self.seqs = memoryview(bytearray(SEQS_BYTES)).cast("q")
        self.log = memoryview(bytearray(LOG_BYTES)).cast("q")
        try:
            self._mm.close()
        except BufferError:  # a reader's array still points into it: the GC closes it
            pass


class RingWriter(_Mapped):
    """The campaign side: creates the file; the acquisition thread publishes blocks (through
    the run writer sharing :meth:`buffers`, or :meth:`write`), other threads write JSON
    regions."""

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
        self._slots: np.ndarray | None = None  # (nslots, rows, c) of this run
        self._p = 0  # blocks published this run
        self._next = 0  # the slot :meth:`write` fills next
        self._shared = False  # a run writer's buffers are the slots: write() copies nothing
        self.h[_PID] = os.getpid()
        self.heartbeat()
        self.h[_MAGIC] = MAGIC

    def heartbeat(self) -> None:
        self.h[_HEARTBEAT_NS] = time.time_ns()

    def begin_run(
        self, meta: dict[str, Any], n_channels: int, dtype: np.dtype, block_rows: int = 0
    ) -> None:
        """A new run (a new DAQ start): its info, and slots of its shape (``block_rows``: the
        DAQ's block size, rows a slot)."""
        dt = np.dtype(dtype)
        if dt.itemsize not in _DTYPES or dt.kind not in "if":
            raise RingError(f"live ring: samples of {dt} (expected int16 or float64)")
        rows = int(block_rows) if block_rows > 0 else DEFAULT_SLOT_ROWS
        nslots = min(MAX_SLOTS, self._sample_bytes // (rows * n_channels * dt.itemsize))
        if nslots < 2:
            raise RingError(f"live ring: {self._sample_bytes} bytes hold {nslots} slots of "
                            f"{rows} rows x {n_channels} channels (at least 2)")  # fmt: skip
        count = nslots * rows * n_channels
        self._slots = np.frombuffer(self._mm, dt, count, _SAMPLES_AT).reshape(
            nslots, rows, n_channels
        )
        self._p = self._next = 0
        self._shared = False
        h = self.h
        h[_PUBLISHED] = 0
        h[_SLOT_ROWS], h[_CHANNELS], h[_ITEMSIZE], h[_NSLOTS] = (
            rows,
            n_channels,
            dt.itemsize,
            nslots,
        )
        self.put_meta(meta)
        h[_GEN] += 1  # last: a reader seeing the new generation sees all of the above

    def put_meta(self, meta: dict[str, Any]) -> None:
        self._put_json("meta", meta)

    def put_status(self, status: dict[str, Any]) -> None:
        self._put_json("status", status)

    def put_status_json(self, data: bytes) -> None:
        """The status already encoded by :meth:`dumps` (the live side splices in the events'
        JSON, encoded once per new event rather than 25 times a second)."""
        self._put_bytes("status", data)

    # -- the run writer's side (rig.log.writer.SharedBuffers) ----------------------------------
    def buffers(self, n: int, rows: int) -> list[np.ndarray] | None:
        """``n`` slots (rows, c) as a run writer's queue buffers for this run (None: the slots
        are of other rows, or fewer); from then on :meth:`write` copies nothing."""
        slots = self._slots
        if slots is None or rows != slots.shape[1] or n > len(slots):
            return None
        try:  # their memory now, or no sharing (the writer keeps its own buffers)
            with open(self.path, "r+b") as f:
                os.posix_fallocate(f.fileno(), _SAMPLES_AT, n * slots[0].nbytes)
        except OSError:
            return None
        self._shared = True
        return [slots[k] for k in range(n)]

    def begin(self, k: int) -> None:
        """Slot ``k`` is about to be written (its sequence number odd: readers drop it)."""
        self.seqs[k] += 1

    def publish(self, k: int, first_sample: int, n: int) -> None:
        """Slot ``k`` holds ``n`` rows from device sample ``first_sample``: readers may take
        it. The acquisition thread's cost a block: six stores and a clock read."""
        seqs, log, p = self.seqs, self.log, self._p
        seqs[k] += 1
        e = 4 * (p % LOG_ENTRIES)
        log[e], log[e + 1], log[e + 2], log[e + 3] = seqs[k], k, first_sample, n
        self._p = p + 1
        self.h[_WRITTEN_NS] = time.time_ns()  # the page's sample-to-screen latency starts here
        self.h[_PUBLISHED] = p + 1

    def write(self, first_sample: int, data: np.ndarray) -> None:
        """Publish a DAQ block ``data`` (c, n) starting at device sample ``first_sample``,
        copied into the next slots (nothing when a run writer's buffers are the slots)."""
        slots = self._slots
        if slots is None or self._shared:
            return
        rows, n = slots.shape[1], data.shape[1]
        for a in range(0, n, rows):
            m, k = min(rows, n - a), self._next
            self._next = (k + 1) % min(len(slots), OWN_SLOTS)
            self.begin(k)
            np.copyto(slots[k, :m], data[:, a : a + m].T, casting="same_kind")
            self.publish(k, first_sample + a, m)

    def rows_so_far(self) -> np.ndarray:
        """A copy of the current run's rows (n, c) still in the slots (oldest first; the
        blocks the run writer has not yet reused)."""
        slots = self._slots
        if slots is None:
            return np.zeros((0, 0))
        got = [b for p in range(max(0, self._p - LOG_ENTRIES), self._p)
               if (b := _block(self, slots, p)) is not None]  # fmt: skip
        if not got:
            return np.zeros((0, slots.shape[2]), slots.dtype)
        return np.concatenate([rows for _, rows in got])

    def read_command(self) -> tuple[int, Any]:
        return self.get_json("command")

    def close(self, unlink: bool = False) -> None:
        self.h[_CLOSED] = 1
        self.heartbeat()
        self._slots = None
        super().close()
        if unlink:
            self.path.unlink(missing_ok=True)


class RingReader(_Mapped):
    """The server side: reads samples (into its own mirror, :meth:`pull`), run info and status;
    writes commands. Thread-safe (the server's event loop and its worker threads share one)."""

    def __init__(self, path: str | Path, mirror_bytes: int = MIRROR_BYTES) -> None:
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
        self._mirror_bytes = int(mirror_bytes)
        self._lock = threading.Lock()
        self._g = 0  # the generation (run) mirrored
        self._p = 0  # its published blocks looked at so far
        self._slots: np.ndarray | None = None
        self._rows = np.zeros((0, 1), np.float32)  # the mirror (c, cap)
        self._w = 0  # rows of this run in the mirror so far (absolute row numbers)
        self._offset = 0  # device sample less row number (the newest block's)

    @property
    def generation(self) -> int:
        with self._lock:
            self._pull()
            return self._g

    @property
    def rows_written(self) -> int:
        """Rows of the current generation (run) taken into this reader's mirror."""
        with self._lock:
            self._pull()
            return self._w

    @property
    def writer_pid(self) -> int:
        return int(self.h[_PID])

    @property
    def closed(self) -> bool:
        return bool(self.h[_CLOSED])

    @property
    def row_to_sample(self) -> int:
        """Device sample number less row number (rows after a hole keep their time)."""
        with self._lock:
            self._pull()
            return self._offset

    @property
    def written_ns(self) -> int:
        """Wall clock (``time.time_ns``) when the newest block was published (0: none)."""
        return int(self.h[_WRITTEN_NS])

    def heartbeat_age_s(self) -> float:
        return (time.time_ns() - int(self.h[_HEARTBEAT_NS])) / 1e9

    def pull(self) -> None:
        """Take the blocks published since the last look into the mirror (the server calls it
        often enough that the writer has not reused their slots: every frame, every second)."""
        with self._lock:
            self._pull()

    def _pull(self) -> None:
        h = self.h
        for _ in range(10):
            g = int(h[_GEN])
            if g != self._g:
                self._begin(g)
            if self._slots is None:
                return
            end = int(h[_PUBLISHED])
            for p in range(max(self._p, end - LOG_ENTRIES), end):
                got = _block(self, self._slots, p)
                if got is not None:
                    self._append(*got)
            self._p = max(self._p, end)
            if int(h[_GEN]) == g:
                return  # else a new run began while taking: its blocks go to a fresh mirror

    def _begin(self, g: int) -> None:
        """A new run: its slots' layout and an empty mirror."""
        h = self.h
        rows, c, size, nslots = (int(h[i]) for i in (_SLOT_ROWS, _CHANNELS, _ITEMSIZE, _NSLOTS))
        self._g, self._p, self._w, self._offset, self._slots = g, 0, 0, 0, None
        count = nslots * rows * c
        if g == 0 or size not in _DTYPES or min(rows, c, nslots) <= 0:
            return
        if _SAMPLES_AT + count * size > len(self._mm):
            return  # not a layout this file can hold: nothing to show
        self._slots = np.frombuffer(self._mm, _DTYPES[size], count, _SAMPLES_AT).reshape(
            nslots, rows, c
        )
        stored = _STORED[size]
        self._rows = np.empty((c, max(1, self._mirror_bytes // (c * stored.itemsize))), stored)

    def _append(self, first_sample: int, rows: np.ndarray) -> None:
        mirror, n = self._rows, len(rows)
        cap = mirror.shape[1]
        if n > cap:  # a block longer than the mirror: keep its end
            rows, first_sample, n = rows[n - cap :], first_sample + n - cap, cap
        i = self._w % cap
        k = min(n, cap - i)
        mirror[:, i : i + k] = rows[:k].T
        mirror[:, : n - k] = rows[k:].T
        self._offset = first_sample - self._w  # holes: later rows keep their device time
        self._w += n

    def rows_since(
        self, gen: int, cursor: int, most: int | None = None
    ) -> tuple[int, int, int, np.ndarray]:
        """Rows (n, c) of run generation ``gen`` from row ``cursor`` on (a new generation: from
        its oldest row in the mirror; ``most``: only the newest that many). Returns
        (generation, first row, row-to-sample offset, rows)."""
        with self._lock:
            self._pull()
            g, w, offset, mirror = self._g, self._w, self._offset, self._rows
            if self._slots is None:
                return g, 0, 0, np.zeros((0, mirror.shape[0]))
        cap = mirror.shape[1]
        start = cursor if g == gen else 0
        start = max(start, w - cap, w - most if most is not None else 0, 0)
        # The copy is made outside the lock: a whole run's (up to MIRROR_BYTES) takes 10-20 ms,
        # which every frame would wait for. Rows before ``start`` are never written meanwhile;
        # a pull that wrapped the ring over the oldest ones copied leaves them dropped here.
        rows = _oldest_first(mirror, start, max(start, w))
        with self._lock:
            if self._rows is mirror:  # else a new run has a new mirror: this one is intact
                lost = min(self._w - cap - start, len(rows))
                if lost > 0:
                    rows, start = rows[lost:], start + lost
        return g, start, offset, rows

    def send_command(self, command: dict[str, Any]) -> int:
        """Post a command for the campaign process; returns its sequence number."""
        seq = self.seq("command") + 2
        self._put_json("command", {**command, "seq": seq})
        return seq
