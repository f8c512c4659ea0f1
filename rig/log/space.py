"""The medium under a run file: the room on its disk (``free_space_problem`` before a recording,
the ``MIN_FREE_MB`` margin while it records), the process's file size limit, and one line for a
write that failed."""

from __future__ import annotations

import errno
import os
import re
import shutil
from pathlib import Path

from rig.log._file import disk_full_reason

#: MB that must stay free on the run file's disk: below it a recording stops (or does not start).
MIN_FREE_MB = 64.0
#: Bytes held for the close's own writes (status, events, indexes, superblock) beyond the samples.
_CLOSE_BYTES = 1 << 20
#: Bytes reserved ahead of the samples at a time (fewer fallocate calls).
_RESERVE_STEP = 4 << 20


def free_bytes(folder: Path) -> int:
    """Free bytes on the file system of ``folder`` (or of its nearest existing parent)."""
    p = Path(folder).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return shutil.disk_usage(p).free


def free_space_problem(
    folder: Path, need_bytes: float, min_free_mb: float = MIN_FREE_MB
) -> str | None:
    """Why a recording of about ``need_bytes`` into ``folder`` should not start (None: room
    enough for it plus the ``min_free_mb`` margin)."""
    free = free_bytes(folder)
    need = need_bytes + min_free_mb * 1e6
    if free >= need:
        return None
    return (
        f"{folder}: {free / 1e6:.0f} MB free, the recording needs about {need_bytes / 1e6:.0f} MB "
        f"plus the {min_free_mb:g} MB margin: free some space or record elsewhere"
    )


def _file_size_limit() -> int | None:
    """This process's file size limit (``ulimit -f``), bytes; None without one."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    except (ImportError, OSError, ValueError):
        return None
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _write_failure(path: Path, exc: BaseException) -> str:
    """One line for a failed write, with the OS error HDF5 buried in its message."""
    text = str(exc)
    m = re.search(r"errno = (\d+), error message = '([^']*)'", text)
    code = getattr(exc, "errno", None) or (int(m[1]) if m else None)
    what = m[2] if m else (os.strerror(code) if code else text.splitlines()[0][:200])
    name = errno.errorcode.get(code, "") if code else ""
    full = disk_full_reason(code, path.parent)
    name = f" ({name})" if name else ""
    return f"{full + ': ' if full else ''}write error on {path}: {what}{name}"
