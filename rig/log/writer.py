"""Crash-safe HDF5 run writer: a bounded queue and one writer thread, SWMR, periodic flush.

The acquisition thread calls :meth:`RunWriter.on_block`, which copies the block (transposed to the
file's (samples, channels) rows) into a free buffer of a fixed pool and returns at once; the writer
thread appends filled buffers to the chunked dataset (the chunk cache holds a partly filled chunk
until the next block completes it, so no chunk is read back) and returns them to the pool. When
the pool is empty (disk too slow) the block is dropped and recorded as a ``queue_full`` event with
its exact device sample index and length, so the acquisition never waits on the disk and nothing
is lost silently. Every dataset is created before SWMR is switched on, so
``analysis.runs.follow.RunFollower`` can read the file while it grows, and a writer killed at any
moment leaves a file that opens and holds everything up to its last flush (default every 1 s).

The medium: the writer thread checks the free space of the file's folder at every flush and, below
``min_free_mb``, stops recording cleanly (a ``fault`` event, everything so far flushed) before the
disk is full; :func:`free_space_problem` checks a recording's expected size before it starts. A
disk that another program fills at once is met by a reservation: before HDF5 writes anything the
writer allocates the disk blocks it will go into, past the file's end (Linux ``fallocate``
KEEP_SIZE), the next samples plus room for the close; when the disk (or ``ulimit -f``) cannot
give more, recording stops there cleanly ("disk full: ... free bytes") and the close writes its
status into blocks already held, so the file closes normally and plain h5py opens it; blocks
held and unused are given back at the close. A write error HDF5 still meets (EIO, a file system
without ``fallocate``) stops the writer too: HDF5 cannot close a file it failed to write (and
crashes the process at exit if left to try), so the file is abandoned (its descriptor pointed at
/dev/null so nothing more reaches the disk) and rewritten at :meth:`close` with every flushed
sample and status ``fail``; if there is no room for that copy the reason is left in a small
sidecar (``.NAME.reason``) and the next read repairs the file with it. Either way
:attr:`RunWriter.failure` says why, for the run to end with that reason, and :meth:`stats` after
the close counts the samples the file holds.

The layout is documented in :mod:`analysis.runs.layout` and written here only through its constants.

Other threads (the DNC streamer, the campaign runner) write through thread-safe methods that
queue small records for the writer thread: :meth:`append_blocks`, :meth:`ack_blocks`,
:meth:`event`, :meth:`set_conditions`, :meth:`set_rig`, :meth:`set_program`,
:meth:`set_calibration`; :meth:`close` ends the run with a status and reason.
"""

from __future__ import annotations

import collections
import contextlib
import json
import math
import queue
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from analysis.runs import file as rf
from rig.daq import Calibration, DaqEvent, DaqInfo
from rig.log import space
from rig.log._control import ControlRecords
from rig.log._file import RunWriterError, create_run_file, release_blocks, utc_now, write_text
from rig.log._room import DiskRoom
from rig.log.space import (  # noqa: F401 - MIN_FREE_MB, free_space_problem: importable from here
    _RESERVE_STEP,
    MIN_FREE_MB,
    _file_size_limit,
    _write_failure,
    free_space_problem,
)

__all__ = [
    "MIN_FREE_MB",
    "RunWriter",
    "RunWriterError",
    "SharedBuffers",
    "WriterStats",
    "free_space_problem",
]

_STOP = object()


class SharedBuffers(Protocol):
    """Memory a reader beside the writer shares (the console's live ring, rig.console.ring):
    the writer's queue buffers are its slots, so the one copy of each block the writer makes
    is the reader's too. The writer marks a slot before it copies a block in and publishes it
    after."""

    def buffers(self, n: int, rows: int) -> list[np.ndarray] | None:
        """``n`` buffers (rows, c) of the run's type, or None (the writer keeps its own)."""

    def begin(self, k: int) -> None:
        """Buffer ``k`` is about to be overwritten."""

    def publish(self, k: int, first_sample: int, n: int) -> None:
        """Buffer ``k`` holds ``n`` rows from device sample ``first_sample``."""


@dataclass(frozen=True)
class WriterStats:
    """Counts at the time of asking; samples are per channel."""

    samples_written: int
    blocks_written: int
    blocks_dropped: int
    samples_dropped: int
    samples_missing: int  # holes reported as gap events
    flushes: int
    max_queue_depth: int
    max_write_s: float  # longest single append of a block (disk stalls show here)
    max_flush_s: float  # longest flush


class RunWriter(ControlRecords, DiskRoom):
    """Write one run file; implements :class:`rig.daq.base.DaqSink`.

    Parameters
    ----------
    path : the run file (``.h5``); an existing file is an error unless ``overwrite``.
    info : what the DAQ acquires (channels, rate, sample format, scaling).
    calibration : volts -> newtons of the channels (stored; newtons are derived on load).
    clock : the run clock (``SimClock.now`` on the simulated rig), s; block and event times use it.
    flush_interval_s : at most this long between flushes (what a killed run can lose), s.
    queue_blocks : blocks the queue can hold before blocks are dropped (``queue_full`` events).
    compression : "auto" (gzip level 1 + shuffle for int16 codes, none for float64), "gzip", None.
    min_free_mb : free space (MB) below which recording stops before the disk fills.
    """

    #: a reader's buffers the queue uses (:meth:`share_buffers`), and each one's slot by its id
    _shared: SharedBuffers | None = None
    _slot_of: dict[int, tuple[int, np.ndarray]]

    def __init__(
        self,
        path: str | Path,
        info: DaqInfo,
        calibration: Calibration | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
        flush_interval_s: float = 1.0,
        queue_blocks: int = 64,
        compression: str | None = "auto",
        overwrite: bool = False,
        min_free_mb: float = MIN_FREE_MB,
    ) -> None:
        if not 0 < flush_interval_s <= 60:
            raise RunWriterError(f"flush_interval_s = {flush_interval_s}: must be in (0, 60] s")
        if queue_blocks < 1:
            raise RunWriterError(f"queue_blocks = {queue_blocks}: must be >= 1")
        if calibration is not None and calibration.n_channels != info.n_channels:
            raise RunWriterError(
                f"calibration has {calibration.n_channels} channels "
                f"({', '.join(calibration.channel_names)}), the DAQ task has {info.n_channels}"
            )
        self.path = Path(path)
        self.info = info
        self.clock = clock
        self.flush_interval_s = float(flush_interval_s)
        self.min_free_mb = float(min_free_mb)
        self._c = info.n_channels
        self._dtype = info.dtype
        self._f, self._ds = create_run_file(
            self.path, info, calibration, compression=compression, overwrite=overwrite
        )

        # Producer side (acquisition thread): a pool of free buffers is the bounded queue.
        self._free: queue.SimpleQueue[np.ndarray] = queue.SimpleQueue()
        for _ in range(queue_blocks):
            buf = np.empty((info.block_samples, self._c), self._dtype)
            buf.fill(0)  # touch the pages now, not on the acquisition thread's first copy
            self._free.put(buf)
        self._pool_size = queue_blocks
        self._idle = threading.Condition()
        self._filled: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._control: collections.deque[tuple[str, Any]] = collections.deque()
        self._expect = 0
        self._drop: list[int] | None = None  # [first, n] of the drop being coalesced
        self._lock = threading.Lock()  # producer-side bookkeeping shared with event()
        self._t0_s = math.nan
        self._held = threading.Event()
        self._held.set()

        # Writer side.
        self._committed = 0  # rows written to the dataset
        self._block_rows: dict[int, int] = {}  # block index -> its latest row in the table
        self._blocks_written = 0
        self._blocks_dropped = 0
        self._samples_dropped = 0
        self._samples_missing = 0
        self._flushes = 0
        self._max_depth = 0
        self._max_write_s = 0.0
        self._max_flush_s = 0.0
        self.error: BaseException | None = None
        #: Why recording stopped on its own (disk nearly full, write error); None while it records.
        self.failure: str | None = None
        self._abandoned = False  # HDF5 failed a write: the file is left alone, rewritten at close
        self._closed = False
        self._close_as = (rf.STATUS_SUCCESS, "")
        # The disk blocks held past the file's end (see the module docstring).
        self._fd = self._f.id.get_vfd_handle()
        self._reserving = True  # False where fallocate is not supported
        self._reserved_to = 0  # file offset up to which blocks are held
        self._pending = 0  # bytes of samples written since the last flush (maybe not on disk yet)
        self._flushed_rows = 0
        self._row_bytes = self._c * self._dtype.itemsize
        self._size_limit = _file_size_limit()
        self._ensure_room(0)
        self._thread = threading.Thread(target=self._run, name=f"RunWriter({self.path.name})")
        self._thread.daemon = True
        self._thread.start()

    # ------------------------------------------------------------------------------------------
    # DaqSink: called from the acquisition thread. Never blocks on the disk.
    # ------------------------------------------------------------------------------------------

    def on_start(self, info: DaqInfo, t0_s: float) -> None:
        if info.n_channels != self._c or info.dtype != self._dtype:
            raise RunWriterError(
                f"DAQ delivers {info.n_channels} channels of {info.dtype}; the run file was "
                f"created for {self._c} channels of {self._dtype}"
            )
        self._t0_s = float(t0_s)
        acq = {"t0_s": self._t0_s, "started_utc": utc_now(), "block_samples": info.block_samples}
        self._control.append(("text", (rf.META_ACQUISITION, json.dumps(acq))))
        self._control.append(("event", DaqEvent(rf.EV_START, 0, "acquisition started")))

    def on_block(self, first_sample: int, data: np.ndarray) -> None:
        """Queue a copy of ``data`` (c, n) starting at device sample ``first_sample``; if the
        queue is full the block is dropped and recorded (``queue_full``). Never waits."""
        self._enqueue(first_sample, data, None)

    def put_block(self, first_sample: int, data: np.ndarray, timeout_s: float = 60.0) -> None:
        """Like :meth:`on_block` but waits up to ``timeout_s`` for room in the queue (for
        offline writers such as converters and benchmarks, where waiting beats dropping)."""
        self._enqueue(first_sample, data, timeout_s)

    def _enqueue(self, first_sample: int, data: np.ndarray, wait_s: float | None) -> None:
        if self.failure is not None:
            return  # recording has stopped (the reason is an event and ``failure``)
        n = int(data.shape[1])
        with self._lock:
            if first_sample != self._expect:
                if first_sample > self._expect:
                    lost = first_sample - self._expect
                    self._samples_missing += lost
                    ev = DaqEvent(rf.EV_GAP, self._expect, f"{lost} samples missing", lost=lost)
                else:
                    ev = DaqEvent(
                        rf.EV_FAULT,
                        first_sample,
                        f"block starts at {first_sample}, before the expected {self._expect}; "
                        "overlap dropped",
                    )
                    self._control.append(("event", ev))
                    return
                self._control.append(("event", ev))
            self._expect = first_sample + n
            try:
                buf = self._free.get(timeout=wait_s) if wait_s else self._free.get_nowait()
            except queue.Empty:
                self._record_drop(first_sample, n)
                return
            if self._drop is not None:
                self._flush_drop()
        shared = self._shared
        k = -1 if shared is None else self._slot_of[id(buf)][0]
        if buf.shape[0] < n:
            buf = np.empty((n, self._c), self._dtype)  # a longer block than announced (rare)
            k = -1  # (not in a shared slot: a reader misses it, the file has it)
        # The one copy: (c, n) from the DAQ into (n, c) rows, the file's layout.
        if k >= 0 and shared is not None:
            k = self._tell(shared.begin, k)
        np.copyto(buf[:n], data.T)
        if k >= 0 and shared is not None:
            self._tell(shared.publish, k, first_sample, n)
        self._filled.put((first_sample, n, buf))

    def _tell(self, fn: Callable[..., None], k: int, *args: int) -> int:
        """A call to the reader sharing the buffers; -1 if it failed (a closed ring): the reader
        is not told again, the recording goes on."""
        try:
            fn(k, *args)
            return k
        except Exception:  # noqa: BLE001 - a reader's view must never stop the recording
            self._shared = None
            return -1

    def share_buffers(self, shared: SharedBuffers) -> bool:
        """Take the queue's buffers from ``shared`` (the console's live ring) for this run:
        the one copy of each block is then the reader's too. Only before the first block
        (from the acquisition thread, e.g. in the DAQ's ``on_start``); False: not taken (no
        buffers of this shape there, or blocks already came), the writer keeps its own."""
        with self._lock:
            if self._expect != 0 or self._shared is not None:
                return False
            views = shared.buffers(self._pool_size, self.info.block_samples)
            want = (self.info.block_samples, self._c)
            if not views or any(v.shape != want or v.dtype != self._dtype for v in views):
                return False
            for _ in range(self._pool_size):  # none is out: no block has come
                self._free.get_nowait()
            for v in views:
                v.fill(0)  # touch the pages now, not on the acquisition thread's first copy
                self._free.put(v)
            self._slot_of = {id(v): (k, v) for k, v in enumerate(views)}
            self._shared = shared
            return True

    def on_event(self, event: DaqEvent) -> None:
        if event.kind == rf.EV_STOP:
            with self._lock:
                if event.sample > self._expect:  # blocks missing at the very end
                    lost = event.sample - self._expect
                    self._samples_missing += lost
                    self._control.append(
                        ("event", DaqEvent(rf.EV_GAP, self._expect, f"{lost} samples missing "
                                           "before stop", lost=lost))
                    )  # fmt: skip
                    self._expect = event.sample
        self._control.append(("event", event))

    @contextlib.contextmanager
    def hold(self) -> Iterator[None]:
        """Pause the writer thread: blocks pile up in the queue and, once it is full, are dropped
        as ``queue_full`` events (what a stalled disk does; used to prove the drop path)."""
        self._held.clear()
        try:
            yield
        finally:
            self._held.set()

    def wait_idle(self, timeout_s: float = 10.0) -> bool:
        """Wait until the writer thread has taken every queued block (False on timeout)."""
        with self._idle:
            return self._idle.wait_for(
                lambda: self._free.qsize() >= self._pool_size or self.error is not None,
                timeout_s,
            )

    @property
    def chunk_rows(self) -> int:
        """Samples per chunk of the samples dataset."""
        return int(self._ds.chunks[0])

    @property
    def t0_s(self) -> float:
        return self._t0_s

    def stats(self) -> WriterStats:
        return WriterStats(
            samples_written=self._committed,
            blocks_written=self._blocks_written,
            blocks_dropped=self._blocks_dropped,
            samples_dropped=self._samples_dropped,
            samples_missing=self._samples_missing,
            flushes=self._flushes,
            max_queue_depth=self._max_depth,
            max_write_s=self._max_write_s,
            max_flush_s=self._max_flush_s,
        )

    def close(self, status: str = rf.STATUS_SUCCESS, reason: str = "") -> WriterStats:
        """Write what is queued, record the exit status and close the file. Idempotent.

        After a :attr:`failure` the status is ``fail`` with that reason (an ``abort`` stays, the
        failure added to its reason); a caller that closes with ``success`` not having noticed
        the failure gets a RunWriterError, after the file is closed."""
        if status not in rf.CLOSED_STATUSES:
            raise RunWriterError(f"status {status!r}: expected success, abort or fail")
        if self._closed:
            return self.stats()
        self._closed = True
        self._held.set()
        with self._lock:
            if self._drop is not None:
                self._flush_drop()
        # Written by the writer thread after the last sample is flushed, so a follower that sees
        # a closed status has every sample.
        self._close_as = (status, reason)
        self._filled.put(_STOP)
        self._thread.join()
        if not self._abandoned:
            try:
                self._f.close()
            except Exception as exc:  # noqa: BLE001 - a failed last write is a failure too
                self.failure = self.failure or _write_failure(self.path, exc)
                self._abandon()
        release_blocks(self.path)  # the held blocks back to the disk: room for what follows
        final, why = self._final_status_of(status, reason)
        if self._abandoned:
            # The reason first (the room just given back holds it), then the flushed samples
            # into a fresh file with the status; without room for that copy the next read
            # repairs the file with this reason.
            rf.write_reason_sidecar(self.path, final, why)
            if rf.repair_run(self.path, status=final, reason=why, writer_gone=True):
                rf.remove_reason_sidecar(self.path)
        elif not self._reserving:
            rf.remove_reason_sidecar(self.path)  # closed normally: the blank sidecar goes
        self._committed = self._stored_rows()  # what the file holds, not what was handed over
        if self.failure is not None and status == rf.STATUS_SUCCESS:
            raise RunWriterError(self.failure)
        return self.stats()

    def __enter__(self) -> RunWriter:
        return self

    def __exit__(self, exc_type: type | None, exc: BaseException | None, tb: object) -> None:
        if exc is None:
            self.close(rf.STATUS_SUCCESS)
        elif isinstance(exc, KeyboardInterrupt):
            self.close(rf.STATUS_ABORT, "interrupted")
        else:
            self.close(rf.STATUS_FAIL, f"{type(exc).__name__}: {exc}"[:500])

    # ------------------------------------------------------------------------------------------
    # Writer thread.
    # ------------------------------------------------------------------------------------------

    def _run(self) -> None:
        last_flush = time.monotonic()
        try:
            while True:
                try:
                    item = self._filled.get(timeout=min(0.05, self.flush_interval_s))
                except queue.Empty:
                    item = None
                # Held: the taken buffer is not returned to the pool until released, so the pool
                # (= queue capacity) stays exact.
                self._held.wait()
                if item is _STOP:
                    break
                if item is not None:
                    # Blocks out of the pool (queued or this one): the queue depth.
                    depth = self._pool_size - self._free.qsize()
                    self._max_depth = max(self._max_depth, depth)
                    self._take(item)
                self._drain_control()
                if time.monotonic() - last_flush >= self.flush_interval_s:
                    self._flush()
                    last_flush = time.monotonic()
            # Closing: samples first, then control records (the status last), then flush.
            while True:
                try:
                    self._take(self._filled.get_nowait())
                except queue.Empty:
                    break
            self._drain_control()
            self._flush()
            status, reason = self._final_status_of(*self._close_as)
            closed = {"status": status, "reason": reason, "closed_utc": utc_now()}
            write_text(self._f, rf.META_STATUS, json.dumps(closed))
            self._f.flush()
        except BaseException as exc:  # noqa: BLE001 - surfaced by close() and ``failure``
            # failure before error: a waiter woken by the error reads the failure
            self.failure = self.failure or _write_failure(self.path, exc)
            self.error = exc
            self._abandon()
        finally:
            with self._idle:
                self._idle.notify_all()

    def _take(self, item: tuple[int, int, np.ndarray]) -> None:
        """Append the first n rows of a filled pool buffer (n, c) to the samples dataset and
        return the buffer to the pool."""
        _, n, buf = item
        if self.failure is not None or not self._ensure_room(n * self._row_bytes):
            self._free.put(buf)  # stopped: the buffer goes back, nothing more is written
            return
        t = time.perf_counter()
        end = self._committed + n
        self._ds.resize((end, self._c))
        self._ds[self._committed : end] = buf[:n]
        self._committed = end
        self._pending += n * self._row_bytes
        self._max_write_s = max(self._max_write_s, time.perf_counter() - t)
        self._blocks_written += 1
        self._free.put(buf)
        with self._idle:
            self._idle.notify_all()

    def _flush(self) -> None:
        """Flush everything written so far to the file, for SWMR readers and crash safety; then
        say how many samples that was (a live reader reads no further)."""
        t = time.perf_counter()
        self._f.flush()
        flushed = self._f[rf.FLUSHED]
        flushed[0] = self._committed
        flushed.flush()
        self._pending = 0
        self._flushed_rows = self._committed
        self._flushes += 1
        self._max_flush_s = max(self._max_flush_s, time.perf_counter() - t)
        free = space.free_bytes(self.path.parent)  # looked up here: tests set it
        if self.failure is None and free < self.min_free_mb * 1e6:
            word = "disk full" if free < _RESERVE_STEP else "disk nearly full"
            self._stop(
                f"{word}: {self.path.parent} has {free} free bytes ({free / 1e6:.0f} MB"
                f" free), below the {self.min_free_mb:g} MB margin: recording stopped at sample "
                f"{self._committed} before the disk fills"
            )
