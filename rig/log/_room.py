"""The run writer's medium: the disk blocks held ahead of the samples (``fallocate``), the stop
before the disk or the file size limit runs out, a file HDF5 failed to write left alone, and what
a closed file holds. See :mod:`rig.log.writer`'s docstring for the whole story.

A mixin of :class:`rig.log.writer.RunWriter`, which holds the state named below.
"""

from __future__ import annotations

import collections
import contextlib
import errno
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py

from analysis.runs import file as rf
from rig.daq import DaqEvent
from rig.log._file import CHUNK_BYTES, disk_full_reason, reserve_blocks
from rig.log.space import _CLOSE_BYTES, _RESERVE_STEP


class DiskRoom:
    """Room on the disk ahead of the samples, the clean stop without it, the abandoned file."""

    # the RunWriter's state these methods use
    path: Path
    clock: Callable[[], float]
    failure: str | None
    _f: h5py.File
    _fd: int
    _control: collections.deque[tuple[str, Any]]
    _abandoned: bool
    _reserving: bool
    _reserved_to: int
    _pending: int
    _committed: int
    _flushed_rows: int
    _size_limit: int | None

    def _stored_rows(self) -> int:
        """Samples per channel the closed file holds (read back; as the next read will see)."""
        try:
            with h5py.File(self.path, "r") as f:
                return int(rf.samples_dataset(f).shape[0])
        except Exception:  # noqa: BLE001 - not plainly openable: what its repair will keep
            try:
                return rf.load_run(self.path, samples=False, repair=False).samples_stored
            except Exception:  # noqa: BLE001
                return self._flushed_rows

    def _final_status_of(self, status: str, reason: str) -> tuple[str, str]:
        if self.failure is None:
            return status, reason
        if status == rf.STATUS_SUCCESS:
            return rf.STATUS_FAIL, self.failure
        return status, reason if self.failure in reason else f"{reason}; {self.failure}"

    def _abandon(self) -> None:
        """Leave a file HDF5 failed to write: point its descriptor at /dev/null, so that closing
        it (which HDF5 must, or it crashes at exit) writes nothing more to the disk."""
        self._abandoned = True
        with contextlib.suppress(Exception):
            fd = self._f.id.get_vfd_handle()
            null = os.open(os.devnull, os.O_RDWR)
            os.dup2(null, fd)
            os.close(null)
        with contextlib.suppress(Exception):
            self._f.close()

    def _stop(self, why: str) -> bool:
        """Stop recording for ``why`` (a ``fault`` event; :attr:`failure`); False."""
        if self.failure is None:
            self.failure = why
            ev = DaqEvent(rf.EV_FAULT, -1, why[-rf.EVENT_MESSAGE_BYTES :], time_s=self.clock())
            self._control.append(("event", ev))
        return False

    def _ensure_room(self, add_bytes: int) -> bool:
        """Hold the disk blocks the next ``add_bytes`` of samples, the samples written since the
        last flush, a chunk HDF5 may start and the close's writes will go into, before HDF5
        writes any of them; False (recording stopped) when the disk or the file size limit has
        no room for them."""
        if not self._reserving:
            return self.failure is None
        try:
            size = os.fstat(self._fd).st_size
        except OSError:
            return self.failure is None
        need_to = size + self._pending + add_bytes + CHUNK_BYTES + _CLOSE_BYTES
        if need_to <= self._reserved_to:
            return True
        at = f"recording stopped at sample {self._committed}, every sample before it kept"
        limit = self._size_limit
        if limit is not None and need_to > limit:
            return self._stop(f"file size limit reached: {self.path} may grow to {limit} bytes "
                              f"(ulimit -f, RLIMIT_FSIZE): {at}")  # fmt: skip
        want = need_to + _RESERVE_STEP + 2 * add_bytes
        if limit is not None:
            want = min(want, limit)
        err = reserve_blocks(self._fd, size, want - size)
        if err in (errno.ENOSPC, errno.EDQUOT) and want > need_to:
            want = need_to  # the last bytes of the disk are still worth recording into
            err = reserve_blocks(self._fd, size, want - size)
        if err is None:  # the file system cannot: the margin and the write-error path remain
            self._reserving = False
            rf.prepare_reason_sidecar(self.path)  # a reason written later needs no new block
            return self.failure is None
        if err:
            why = disk_full_reason(err, self.path.parent) or f"no disk space: {os.strerror(err)}"
            return self._stop(f"{why}, fewer than the {need_to - size} the next samples and "
                              f"the close may take: {at}")  # fmt: skip
        self._reserved_to = want
        return True
