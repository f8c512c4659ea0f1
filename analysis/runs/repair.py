"""Run files whose writer died: telling a live writer from a dead one, the repair that makes
such a file open in plain h5py again, the reason a writer leaves beside a file it could not
close, and the leftovers of a repair killed mid-way.

A file whose writer was killed holds everything up to the writer's last flush, but HDF5 leaves it
marked "open for writing" (the superblock's status flags), so plain h5py and HDFView refuse it
("file is already open for write", which ``h5clear`` would fix). :func:`load_run` repairs such a
file when its writer is gone (the status names the writer's process and host): every object is
copied, the samples cut at ``/forces/flushed`` (what lies past it may be zeros), into a fresh file
that replaces the original atomically once it verifies (the original is kept as ``.bak`` until
then), with status ``interrupted``. Where it cannot be rewritten (a read-only folder) it is read in
SWMR mode and still reported ``interrupted``. :attr:`Run.complete` is False for both. A writer
that stopped on a failed write and could not rewrite its file (no room) leaves its reason in a
sidecar ``.NAME.reason``; the repair takes status and reason from it (and removes it). A repair
killed mid-way leaves ``.NAME.repair-PID`` and ``NAME.bak-PID``: the next read of a run file in
that folder removes those of dead processes (a ``.bak`` is restored if the run file is missing or
no longer opens, else removed).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import socket
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from analysis.runs.identity import writer_identity
from analysis.runs.layout import (
    CLOSED_STATUSES,
    EV_FAULT,
    EV_NOTE,
    EVENT_DTYPE,
    EVENT_MESSAGE_BYTES,
    EVENTS,
    FLUSHED,
    META_STATUS,
    STATUS_INTERRUPTED,
    STATUS_RUNNING,
    RunFileError,
    meta_json,
    meta_path,
    samples_dataset,
)

__all__ = [
    "writer_identity",
    "writer_alive",
    "prepare_reason_sidecar",
    "write_reason_sidecar",
    "remove_reason_sidecar",
    "sweep_repair_leftovers",
    "repair_run",
    "dead_writer_status",
]


def writer_alive(status: Mapping[str, object]) -> bool:
    """The writer named in a run's status (:func:`writer_identity`) still runs. A writer on another
    host cannot be checked and is taken as alive; a file that names none (older files) as dead."""
    w = status.get("writer")
    pid = w.get("pid") if isinstance(w, dict) else None
    if not isinstance(w, dict) or not isinstance(pid, int) or pid <= 0:
        return False
    if w.get("host") != socket.gethostname():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # alive, another user's
    with contextlib.suppress(OSError, IndexError):  # a killed child its parent has not reaped
        if Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z":
            return False
    return True


def _reason_sidecar(p: Path) -> Path:
    return p.with_name(f".{p.name}.reason")


_SIDECAR_BYTES = 4096


def prepare_reason_sidecar(path: str | Path) -> None:
    """Create the reason sidecar of a run file now, blank (spaces), so that a reason written into
    it later needs no new disk block (for a writer that cannot hold blocks ahead)."""
    with contextlib.suppress(OSError):
        _reason_sidecar(Path(path)).write_bytes(b" " * _SIDECAR_BYTES)


def write_reason_sidecar(path: str | Path, status: str, reason: str) -> None:
    """Leave ``status`` and ``reason`` beside a run file its writer could not close (best effort:
    the next repair uses them instead of "interrupted"). Written over a prepared blank sidecar in
    place (padded with spaces, still JSON), so a full disk does not refuse it."""
    text = json.dumps({"status": status, "reason": reason[:2000], "writer": writer_identity()})
    data = text.encode().ljust(_SIDECAR_BYTES)
    with contextlib.suppress(OSError):
        fd = os.open(_reason_sidecar(Path(path)), os.O_WRONLY | os.O_CREAT, 0o644)
        try:
            os.pwrite(fd, data, 0)
        finally:
            os.close(fd)


def remove_reason_sidecar(path: str | Path) -> None:
    with contextlib.suppress(OSError):
        _reason_sidecar(Path(path)).unlink()


def _sidecar_reason(p: Path) -> tuple[str, str] | None:
    """(status, reason) a writer left beside ``p``, or None."""
    try:
        d = json.loads(_reason_sidecar(p).read_text())
        st, why = str(d["status"]), str(d["reason"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return (st, why) if st in CLOSED_STATUSES else None


_LEFTOVER = re.compile(r"^(?:\.(?P<tmp>.+)\.repair-(?P<p1>\d+)|(?P<bak>.+)\.bak-(?P<p2>\d+))$")
_swept: dict[str, int] = {}  # folder -> its mtime (ns) when last swept


def sweep_repair_leftovers(folder: str | Path) -> list[str]:
    """Remove what repairs killed mid-way left in ``folder`` (their process is gone): the copy
    ``.NAME.repair-PID``, and ``NAME.bak-PID`` (put back as NAME if NAME is missing or does not
    open, else removed). Returns what was done, a line each. A folder unchanged since its last
    sweep in this process is not listed again."""
    d = Path(folder)
    try:
        mtime = d.stat().st_mtime_ns
    except OSError:
        return []
    if _swept.get(str(d)) == mtime:
        return []
    done: list[str] = []
    try:
        names = [e.name for e in os.scandir(d) if ".repair-" in e.name or ".bak-" in e.name]
    except OSError:
        names = []
    host = socket.gethostname()
    for name in names:
        m = _LEFTOVER.match(name)
        if m is None:
            continue
        pid = int(m["p1"] or m["p2"])
        if pid == os.getpid() or writer_alive({"writer": {"pid": pid, "host": host}}):
            continue
        leftover = d / name
        with contextlib.suppress(OSError):
            if m["tmp"] is not None:
                leftover.unlink()
                done.append(f"removed {leftover} (a repair's copy; process {pid} gone)")
                continue
            original = d / m["bak"]
            if _opens(original):
                leftover.unlink()
                done.append(f"removed {leftover} ({original} is intact)")
            else:
                os.replace(leftover, original)
                done.append(f"restored {original} from {leftover}")
    with contextlib.suppress(OSError):
        _swept[str(d)] = d.stat().st_mtime_ns
    return done


def _opens(p: Path) -> bool:
    """``p`` is an HDF5 file that opens (plainly or, a writer's, in SWMR mode)."""
    if not p.is_file() or not h5py.is_hdf5(str(p)):
        return False
    for kw in ({}, {"libver": "latest", "swmr": True}):
        try:
            h5py.File(p, "r", **kw).close()
            return True
        except OSError:
            continue
    return False


def _needs_repair(p: Path) -> bool:
    """HDF5 refuses a plain open: the file is marked open for writing (a live or dead writer), or
    a writer that failed mid-flush recorded an end of file beyond the bytes it wrote."""
    try:
        h5py.File(p, "r").close()
    except OSError as exc:
        return "already open for write" in str(exc) or "truncated file" in str(exc)
    return False


def repair_run(
    path: str | Path,
    status: str = STATUS_INTERRUPTED,
    reason: str | None = None,
    *,
    writer_gone: bool = False,
) -> bool:
    """Make the file of a dead writer open in plain h5py/HDFView again (what ``h5clear`` does,
    without it): copy every object into a fresh file, samples cut at the last flush, with
    ``status`` (default ``interrupted``) and ``reason``; replace the original atomically once the
    copy verifies. ``writer_gone``: the caller is the writer and has given the file up. True if
    repaired; False (nothing changed) if it needs no repair, its writer is alive, or it cannot be
    rewritten (no room, a read-only folder).
    """
    p = Path(path)
    sweep_repair_leftovers(p.parent)
    if not p.is_file() or not _needs_repair(p):
        if p.is_file() and _reason_sidecar(p).exists() and _opens(p):
            remove_reason_sidecar(p)  # its file was repaired (or closed) after all
        return False
    tmp = p.with_name(f".{p.name}.repair-{os.getpid()}")
    bak = p.with_name(f"{p.name}.bak-{os.getpid()}")
    try:
        with h5py.File(p, "r", libver="latest", swmr=True) as src:
            old = meta_json(src, META_STATUS)
            dead = writer_gone or not writer_alive(old)
            if old.get("status", STATUS_RUNNING) != STATUS_RUNNING or not dead:
                return False
            left = _sidecar_reason(p) if reason is None else None
            if left is not None:  # the writer's own reason (disk full ...), not "interrupted"
                status, reason = left
            kept = _copy_flushed(src, tmp, old, status, reason)
        with h5py.File(tmp, "r") as chk:  # the copy opens plainly and holds what was kept
            if int(samples_dataset(chk).shape[0]) != kept:
                raise OSError(f"copy holds {samples_dataset(chk).shape[0]} samples, not {kept}")
        os.link(p, bak)  # the original stays reachable until the copy is in place
        os.replace(tmp, p)
        bak.unlink()
        remove_reason_sidecar(p)
        return True
    except (OSError, KeyError, RunFileError):
        return False
    finally:
        # Nothing of the repair outlives it, whatever stopped it (an exception, Ctrl-C).
        with contextlib.suppress(OSError):
            tmp.unlink()
        with contextlib.suppress(OSError):
            if bak.exists():
                if p.exists():
                    bak.unlink()  # the original (same file) or the verified copy is in place
                else:
                    os.replace(bak, p)


def _copy_flushed(
    src: h5py.File, dst_path: Path, old: dict[str, Any], status: str, reason: str | None
) -> int:
    """Copy ``src`` into a new file at ``dst_path``: samples up to the last flush, ``status``
    with ``reason`` (also an event at the end of the record). Returns the samples kept."""
    with h5py.File(dst_path, "w", libver="latest") as dst:
        for k, v in src.attrs.items():
            dst.attrs[k] = v
        for name in src:
            src.copy(src[name], dst, name=name)
        ds = samples_dataset(dst)
        kept = int(ds.shape[0])
        if FLUSHED in dst:
            kept = min(kept, int(dst[FLUSHED][0]))
            ds.resize((kept, ds.shape[1]))
        why = _interrupted_reason(kept) if reason is None else reason
        if EVENTS in dst:
            row = np.zeros(1, dtype=EVENT_DTYPE)
            row["sample"], row["time_s"] = -1, math.nan
            row["kind"] = (EV_NOTE if status == STATUS_INTERRUPTED else EV_FAULT).encode()
            row["message"] = why.encode()[:EVENT_MESSAGE_BYTES]
            ev = dst[EVENTS]
            ev.resize((ev.shape[0] + 1,))
            ev[-1:] = row
        text = json.dumps(
            {"status": status, "reason": why, "writer": old.get("writer"),
             "repaired_by": writer_identity()}
        ).encode()  # fmt: skip
        meta = dst[meta_path(META_STATUS)]
        meta.resize((len(text),))
        meta[:] = np.frombuffer(text, dtype=np.uint8)
    return kept


def _interrupted_reason(kept: int) -> str:
    return (
        f"the writer stopped without closing the file (killed or crashed); {kept} samples per "
        "channel kept, up to its last flush"
    )


def dead_writer_status(path: str | Path, kept: int) -> tuple[str, str]:
    """(status, reason) of a run file whose writer died and that was not rewritten (no room, a
    read-only folder): the reason the writer left beside it, else "interrupted"."""
    left = _sidecar_reason(Path(path))
    return left if left is not None else (STATUS_INTERRUPTED, _interrupted_reason(kept))
