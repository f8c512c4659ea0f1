"""The run writer's one copy shared with the console's live ring (issue 32): the writer's queue
buffers are the ring's slots, so the copy it makes of each block for the file is the page's too;
a reader takes every block whole or not at all (a slot refilled while it copies is dropped),
and the file is the same with and without the ring. Real HDF5 files, a real shared-memory ring,
its reader in another thread, and the writer stalled for real (``hold``)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import h5py
import numpy as np

from analysis.runs import file as rf
from rig.console.ring import RingReader, RingWriter
from rig.daq import DaqInfo
from rig.log import RunWriter, WriterStats

B = 400  # samples per block
C = 3


def _info(fmt: str = rf.SAMPLE_FORMAT_VOLTS) -> DaqInfo:
    coeff = np.tile([0.0, 10.0 / 32768], (C, 1)) if fmt == rf.SAMPLE_FORMAT_RAW else None
    return DaqInfo("test", tuple(f"t/ai{i}" for i in range(C)), ("Fx", "Fy", "Fz"), 1000.0,
                   fmt, 10.0, B, coeff)  # fmt: skip


def _fill(buf: np.ndarray, first: int) -> np.ndarray:
    """The DAQ's one reused buffer refilled: channel 0 the device index, 1 its negative, 2 the
    index + 1/4 (a row mixed from two blocks, or a stale one, shows)."""
    i = first + np.arange(buf.shape[1])
    buf[0], buf[1], buf[2] = i, -i, i + 0.25
    return buf


def _meta() -> dict:
    return {"campaign": "t", "run": 1, "runs": 1, "channels": ["Fx", "Fy", "Fz"]}


class _Stall:
    """A slow disk: the writer thread held for 20 ms in every 25 ms, from another thread."""

    def __init__(self, writer: RunWriter) -> None:
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._run, args=(writer,), daemon=True)
        self.thread.start()

    def _run(self, writer: RunWriter) -> None:
        while not self.done.is_set():
            with writer.hold():
                time.sleep(0.02)
            time.sleep(0.005)

    def stop(self) -> None:
        self.done.set()
        self.thread.join(timeout=30)
        assert not self.thread.is_alive()


class _Reader:
    """The console server's side, reading the ring while it is written: every row it is given
    must be a row the DAQ delivered, whole, and in order."""

    def __init__(self, path: Path) -> None:
        self.ring = RingReader(path)
        self.bad: list[str] = []
        self.rows_seen = 0
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.done.is_set():
            g, _, _, rows = self.ring.rows_since(-1, 0)
            if len(rows):
                self.rows_seen += len(rows)
                x = rows[:, 0].astype(float)
                if not (np.array_equal(rows[:, 1], -x) and np.array_equal(rows[:, 2], x + 0.25)):
                    self.bad.append(f"a torn row in generation {g}")
                if np.any(np.diff(x) <= 0):
                    self.bad.append(f"rows out of order in generation {g}")

    def stop(self) -> None:
        self.done.set()
        self.thread.join(timeout=30)
        assert not self.thread.is_alive()
        self.ring.close()


def _record(
    path: Path, ring: RingWriter | None, n_blocks: int, *, lossless: bool, queue_blocks: int = 8
) -> RunWriter:
    """The console's tee, as the acquisition thread runs it: the writer first, then the ring;
    a fast DAQ (no pause between blocks) and a writer stalled by a slow disk."""
    info = _info()
    w = RunWriter(path, info, queue_blocks=queue_blocks, flush_interval_s=0.05)
    w.on_start(info, 0.0)
    if ring is not None:
        ring.begin_run(_meta(), C, info.dtype, B)
        assert w.share_buffers(ring)
    stall = _Stall(w)
    buf = np.empty((C, B))
    try:
        for k in range(n_blocks):
            data = _fill(buf, k * B)
            if lossless:
                w.put_block(k * B, data, timeout_s=30.0)
            else:
                w.on_block(k * B, data)
            if ring is not None:
                ring.write(k * B, data)  # as the console's tee does: a shared ring copies nothing
    finally:
        stall.stop()
    return w


def _record_read(
    tmp_path: Path, slots: int, n_blocks: int, *, lossless: bool, queue_blocks: int = 8
) -> tuple[RingWriter, _Reader, WriterStats]:
    """:func:`_record` into run.h5 through a ring of ``slots`` blocks while a :class:`_Reader`
    reads it; the ring (still open), the stopped reader and the writer's closing counts."""
    ring = RingWriter(tmp_path / "r.ring", sample_bytes=C * 8 * B * slots)
    reader = _Reader(ring.path)
    try:
        w = _record(tmp_path / "run.h5", ring, n_blocks, lossless=lossless,
                    queue_blocks=queue_blocks)  # fmt: skip
        return ring, reader, w.close()
    finally:
        reader.stop()


def _expected(index: np.ndarray) -> np.ndarray:
    x = index.astype(float)
    return np.column_stack([x, -x, x + 0.25])


def test_a_slow_writer_and_a_fast_daq_lose_nothing_through_the_shared_ring(
    tmp_path: Path,
) -> None:
    # The writer's 8 buffers are 8 of the ring's slots: a stalled writer holds them, a fast DAQ
    # waits (lossless) and the reader, copying while they are refilled, sees whole rows only.
    ring, reader, stats = _record_read(tmp_path, 10, 300, lossless=True)
    assert stats.samples_dropped == 0 and stats.samples_missing == 0
    run = rf.load_run(tmp_path / "run.h5")
    assert run.samples_stored == 300 * B
    np.testing.assert_array_equal(run.volts, _expected(np.arange(300 * B)))
    assert not reader.bad and reader.rows_seen > 0
    # a reader opened now finds what the slots still hold (the last 8 blocks), at device time
    r = RingReader(ring.path)
    _, first, offset, rows = r.rows_since(-1, 0)
    assert first == 0 and offset == 292 * B and len(rows) == 8 * B
    np.testing.assert_array_equal(rows, _expected(np.arange(292 * B, 300 * B)))
    r.close()
    ring.close()


def test_blocks_dropped_on_a_full_queue_are_counted_and_the_rest_is_exact(
    tmp_path: Path,
) -> None:
    # on_block never waits: with the writer stalled, blocks are dropped (queue_full events with
    # their ranges); every delivered sample is in the file or in a dropped range, and the file
    # holds exactly the delivered values of what it kept (no slot overwritten before its append).
    ring, reader, stats = _record_read(tmp_path, 64, 600, lossless=False, queue_blocks=4)
    run = rf.load_run(tmp_path / "run.h5")
    q = run.events[run.events["kind"] == rf.EV_QUEUE_FULL]
    dropped = np.concatenate([np.arange(s, s + n) for s, n in zip(q["sample"], q["lost"])])
    assert stats.samples_dropped == len(dropped) > 0  # the stall dropped blocks
    kept = np.setdiff1d(np.arange(600 * B), dropped)
    assert len(kept) + len(dropped) == 600 * B and run.samples_stored == len(kept)
    np.testing.assert_array_equal(run.sample_index, kept)
    np.testing.assert_array_equal(run.volts, _expected(kept))
    assert not reader.bad
    ring.close()


def test_a_reader_takes_no_slot_being_refilled(tmp_path: Path) -> None:
    # the order a writer keeps: begin (the slot's sequence odd), copy, publish (even, logged)
    ring = RingWriter(tmp_path / "r.ring", sample_bytes=C * 8 * B * 2)
    r = RingReader(ring.path)
    ring.begin_run(_meta(), C, np.dtype(np.float64), B)
    slots = ring.buffers(2, B)
    assert slots is not None and [s.shape for s in slots] == [(B, C)] * 2
    buf = np.empty((C, B))
    ring.begin(0)
    slots[0][:] = _fill(buf, 0).T
    ring.publish(0, 0, B)
    ring.begin(0)  # block 0 published, its slot being refilled before the reader looked
    assert r.rows_written == 0  # not taken: it may be torn
    slots[0][:] = _fill(buf, B).T
    ring.publish(0, B, B)
    g, first, offset, rows = r.rows_since(-1, 0)
    assert (g, first, offset) == (1, 0, B)  # the block refilled, at its device time
    np.testing.assert_array_equal(rows, _expected(np.arange(B, 2 * B)))
    ring.write(9 * B, buf)  # the slots are a writer's now: the ring copies nothing itself
    assert r.rows_written == B
    r.close()
    ring.close()


def test_a_reader_that_looks_away_finds_the_last_blocks_and_a_hole(tmp_path: Path) -> None:
    info = _info()
    ring = RingWriter(tmp_path / "r.ring", sample_bytes=C * 8 * B * 8)
    r = RingReader(ring.path)
    w = RunWriter(tmp_path / "run.h5", info, queue_blocks=4)
    w.on_start(info, 0.0)
    ring.begin_run(_meta(), C, info.dtype, B)
    assert w.share_buffers(ring)
    buf = np.empty((C, B))
    w.put_block(0, _fill(buf, 0))
    assert not w.share_buffers(ring)  # only before the first block
    for k in range(1, 3):
        w.put_block(k * B, _fill(buf, k * B))
    assert r.rows_written == 3 * B  # the writer's copies, published as it made them
    # the reader looks away while 10 blocks pass through the writer's 4 buffers (reused in
    # turn): it finds the last 4, after a hole, at their device time
    for k in range(3, 13):
        assert w.wait_idle()
        w.put_block(k * B, _fill(buf, k * B))
    _, first, offset, rows = r.rows_since(-1, 0)
    assert first == 0 and len(rows) == 7 * B and first + offset + len(rows) == 13 * B
    np.testing.assert_array_equal(rows, _expected(np.r_[0 : 3 * B, 9 * B : 13 * B]))
    w.close()
    np.testing.assert_array_equal(rf.load_run(tmp_path / "run.h5").volts,
                                  _expected(np.arange(13 * B)))  # fmt: skip
    r.close()
    ring.close()


def test_the_file_is_the_same_with_and_without_the_ring(tmp_path: Path) -> None:
    for fmt in (rf.SAMPLE_FORMAT_VOLTS, rf.SAMPLE_FORMAT_RAW):
        info = _info(fmt)
        files = []
        for shared in (False, True):
            ring = RingWriter(tmp_path / f"{fmt}{shared}.ring") if shared else None
            p = tmp_path / f"{fmt}-{shared}.h5"
            w = RunWriter(p, info)
            w.on_start(info, 0.0)
            if ring is not None:
                ring.begin_run(_meta(), C, info.dtype, B)
                assert w.share_buffers(ring)
            buf = np.empty((C, B), info.dtype)
            for k in range(50):
                buf[:] = (np.arange(B) * 7 + k * 13 + np.arange(C)[:, None] * 1000) % 30000
                w.put_block(k * B, buf)
            w.close()
            files.append(p)
            if ring is not None:
                r = RingReader(ring.path)  # the page got the writer's rows, as it wrote them
                _, _, offset, rows = r.rows_since(-1, 0)
                assert (offset, len(rows)) == (0, 50 * B)  # 50 blocks, 64 buffers: all
                with h5py.File(p) as f:
                    tail = rf.samples_dataset(f)[-len(rows) :]
                np.testing.assert_array_equal(rows, tail.astype(rows.dtype))
                r.close()
                ring.close()
        with h5py.File(files[0]) as a, h5py.File(files[1]) as b:
            sa, sb = rf.samples_dataset(a), rf.samples_dataset(b)
            assert sa.dtype == sb.dtype == info.dtype and sa.chunks == sb.chunks
            np.testing.assert_array_equal(sa[()], sb[()])


def test_a_ring_closed_mid_run_leaves_the_recording_whole(tmp_path: Path) -> None:
    # the console's side ends (its ring closed, even failing) while the DAQ still delivers
    info = _info()
    ring = RingWriter(tmp_path / "r.ring", sample_bytes=C * 8 * B * 8)
    w = RunWriter(tmp_path / "run.h5", info, queue_blocks=4)
    w.on_start(info, 0.0)
    ring.begin_run(_meta(), C, info.dtype, B)
    assert w.share_buffers(ring)
    buf = np.empty((C, B))
    for k in range(10):
        if k == 3:
            ring.close(unlink=True)
        if k == 6:
            ring.publish = None  # type: ignore[method-assign, assignment]  # (a broken reader)
        w.put_block(k * B, _fill(buf, k * B))
    w.close()
    np.testing.assert_array_equal(rf.load_run(tmp_path / "run.h5").volts,
                                  _expected(np.arange(10 * B)))  # fmt: skip
