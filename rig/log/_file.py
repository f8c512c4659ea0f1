"""Creating a run file for :class:`rig.log.writer.RunWriter`: every object before SWMR is
switched on.

The layout itself is documented in :mod:`analysis.runs.layout`; this module only builds it.
"""

from __future__ import annotations

import contextlib
import ctypes
import datetime as dt
import errno
import json
import os
import re
import shutil
from collections.abc import Mapping
from dataclasses import asdict, is_dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from analysis import __version__
from analysis.runs import file as rf
from rig.daq import SAMPLE_FORMAT_RAW, Calibration, DaqInfo
from rig.errors import RigError

CHUNK_BYTES = 1 << 20  # 1 MiB chunks: large sequential writes, cheap SWMR tail reads


class RunWriterError(RigError):
    """The run file cannot be created or written."""


def utc_now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")


def jsonable(obj: Any) -> Any:
    """Plain JSON types from dataclasses, pydantic models, numpy values and paths."""
    if is_dataclass(obj) and not isinstance(obj, type):
        return jsonable(asdict(obj))
    if hasattr(obj, "model_dump"):
        return jsonable(obj.model_dump())
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, list | tuple):
        return [jsonable(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    return obj


_FALLOC_FL_KEEP_SIZE = 1
_fallocate: Any = None


def reserve_blocks(fd: int, offset: int, length: int) -> int | None:
    """Allocate the disk blocks of bytes [offset, offset + length) of the open file ``fd``
    without changing its size (Linux ``fallocate`` with FALLOC_FL_KEEP_SIZE): HDF5's later
    writes there cannot fail for lack of space. 0 on success, the errno on failure (ENOSPC,
    EDQUOT ...), None where the system or file system cannot (then nothing is reserved)."""
    global _fallocate
    if _fallocate is None:
        try:
            f = ctypes.CDLL(None, use_errno=True).fallocate
            f.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int64, ctypes.c_int64]
            _fallocate = f
        except (OSError, AttributeError):
            _fallocate = False
    if not _fallocate:
        return None
    if _fallocate(fd, _FALLOC_FL_KEEP_SIZE, offset, length) == 0:
        return 0
    err = ctypes.get_errno()
    return None if err in (errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL) else err


def release_blocks(path: Path) -> None:
    """Give back the blocks reserved past the end of ``path`` (a truncate to its own size frees
    them on ext4, xfs and tmpfs)."""
    with contextlib.suppress(OSError):
        os.truncate(path, path.stat().st_size)


def free_bytes(folder: Path) -> int:
    """Free bytes on the file system of ``folder`` (or of its nearest existing parent)."""
    p = Path(folder).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return shutil.disk_usage(p).free


def disk_full_reason(errno_code: int | None, folder: Path) -> str:
    """``disk full: FOLDER has N free bytes`` (ENOSPC, EDQUOT) or ``file size limit ...`` (EFBIG,
    ``ulimit -f``) or "" for other errors: what a failed write's reason starts with."""
    if errno_code in (errno.ENOSPC, errno.EDQUOT):
        try:
            return f"disk full: {folder} has {free_bytes(folder)} free bytes"
        except OSError:
            return f"disk full: {folder}"
    if errno_code == errno.EFBIG:
        return "file size limit reached (ulimit -f, RLIMIT_FSIZE)"
    return ""


def chunk_rows(info: DaqInfo) -> int:
    """Samples per chunk of the samples dataset (about CHUNK_BYTES)."""
    return max(1024, CHUNK_BYTES // (info.dtype.itemsize * info.n_channels))


def write_text(f: h5py.File, name: str, text: str) -> None:
    """Replace the UTF-8 text of ``/meta/<name>`` (resizing its byte dataset)."""
    data = np.frombuffer(text.encode("utf-8"), dtype=np.uint8)
    ds = f[rf.meta_path(name)]
    ds.resize((len(data),))
    if len(data):
        ds[:] = data


def append_rows(ds: h5py.Dataset, rows: np.ndarray) -> int:
    """Append ``rows`` to a resizable 1-D table (events, NC blocks); return the first new row."""
    n = int(ds.shape[0])
    ds.resize((n + len(rows),))
    ds[n:] = rows
    return n


def write_acks(
    ds: h5py.Dataset, block_rows: Mapping[int, int], blocks: np.ndarray, acks: np.ndarray
) -> list[int]:
    """Set ``ack_s`` of the NC-blocks table rows of ``blocks`` (``block_rows``: block -> row);
    return the blocks that have no row."""
    unknown = []
    for b, a in zip(blocks.tolist(), acks.tolist()):
        row = block_rows.get(b)
        if row is None:
            unknown.append(b)
            continue
        rec = ds[row]
        rec["ack_s"] = a
        ds[row] = rec
    return unknown


def write_zero_and_drift(f: h5py.File, cal: Calibration) -> None:
    """Update the calibration's zero and drift in place (the sheet values are fixed at creation)."""
    f[rf.CAL_ZERO_V][...] = cal.zero_v
    f[rf.CAL_ZERO_TIME_S][()] = float(cal.zero_time_s)
    f[rf.CAL_DRIFT_V_S][...] = cal.drift_v_s


def create_run_file(
    path: Path,
    info: DaqInfo,
    cal: Calibration | None,
    *,
    compression: str | None,
    overwrite: bool,
) -> tuple[h5py.File, h5py.Dataset]:
    """Create the file with every group, dataset and attribute, switch SWMR on; return the file
    and its samples dataset. ``compression``: "auto" (gzip 1 + shuffle for int16 codes, none for
    float64), "gzip" or None.

    The file is built under a hidden name and renamed into place once SWMR is on: a process
    killed before that leaves no file HDF5 cannot open (not SWMR yet, still marked open)."""
    if path.exists() and not overwrite:
        raise RunWriterError(f"{path}: file exists (overwrite=True replaces it)")
    path.parent.mkdir(parents=True, exist_ok=True)
    building = path.with_name(f".{path.name}.new")
    c = info.n_channels
    block_bytes = info.block_samples * c * info.dtype.itemsize
    try:
        f = h5py.File(
            building,
            "w",
            libver="latest",
            # Room for the chunks a block spans, so a block ending mid-chunk leaves that chunk
            # in the cache until the next block completes it (no read-back).
            rdcc_nbytes=max(16 * CHUNK_BYTES, 3 * block_bytes),
            rdcc_nslots=1009,
        )
    except OSError as exc:
        building.unlink(missing_ok=True)
        raise RunWriterError(_cannot_create(path, exc)) from None
    try:
        ds = _build(f, info, cal, compression)
        os.replace(building, path)  # the open file keeps its descriptor
    except Exception as exc:
        # A full disk while building: HDF5 cannot close a file it failed to write (and crashes
        # at exit if left to try), so its descriptor goes to /dev/null first.
        with contextlib.suppress(Exception):
            null = os.open(os.devnull, os.O_RDWR)
            os.dup2(null, f.id.get_vfd_handle())
            os.close(null)
        with contextlib.suppress(Exception):
            f.close()
        building.unlink(missing_ok=True)
        raise RunWriterError(_cannot_create(path, exc)) from None
    return f, ds


def _cannot_create(path: Path, exc: BaseException) -> str:
    m = re.search(r"errno = (\d+)", str(exc))
    code = getattr(exc, "errno", None) or (int(m[1]) if m else None)
    full = disk_full_reason(code, path.parent)
    what = f"{full}" if full else str(exc).splitlines()[0][:300]
    return f"{path}: cannot create the run file: {what}"


def _build(f: h5py.File, info: DaqInfo, cal: Calibration | None, compression: str | None) -> Any:
    """Every object of a new run file in ``f``; SWMR on; returns the samples dataset."""
    c = info.n_channels
    f.attrs[rf.ATTR_FORMAT] = rf.FORMAT_NAME
    f.attrs[rf.ATTR_FORMAT_VERSION] = rf.FORMAT_VERSION
    f.attrs[rf.ATTR_SOFTWARE_VERSION] = __version__
    f.attrs[rf.ATTR_CREATED_UTC] = utc_now()
    g = f.create_group(rf.FORCES)
    g.attrs.update(
        rate_hz=float(info.rate_hz),
        sample_format=info.sample_format,
        channel_names=list(cal.channel_names if cal else info.channel_names),
        physical_channels=list(info.physical_channels),
        device=info.device,
        input_range_v=float(info.input_range_v),
        units_force="N",
        units_volts="V",
        units_raw="ADC code",
    )
    if compression == "auto":
        compression = "gzip" if info.sample_format == SAMPLE_FORMAT_RAW else None
    kw: dict[str, Any] = {}
    if compression:
        kw = {"compression": compression, "shuffle": True}
        if compression == "gzip":
            kw["compression_opts"] = 1
    name = rf.RAW if info.sample_format == SAMPLE_FORMAT_RAW else rf.VOLTS
    ds = f.create_dataset(
        name,
        shape=(0, c),
        maxshape=(None, c),
        chunks=(chunk_rows(info), c),
        dtype=info.dtype,
        **kw,
    )
    f.create_dataset(rf.FLUSHED, data=np.zeros(1, np.int64))
    if info.sample_format == SAMPLE_FORMAT_RAW:
        f.create_dataset(rf.SCALING_COEFF, data=np.asarray(info.scaling_coeff, np.float64))
    if cal is not None:
        cg = f.create_group(rf.CALIBRATION)
        for k, v in cal.as_attrs().items():
            cg.attrs[k] = v
        f.create_dataset(rf.CAL_VOLTS_TO_N, data=cal.volts_to_n)
        f.create_dataset(rf.CAL_ZERO_V, data=cal.zero_v)
        f.create_dataset(rf.CAL_ZERO_TIME_S, data=float(cal.zero_time_s))
        f.create_dataset(rf.CAL_DRIFT_V_S, data=cal.drift_v_s)
    for table, dtype, chunk in ((rf.EVENTS, rf.EVENT_DTYPE, 256), (rf.BLOCKS, rf.BLOCK_DTYPE, 512)):
        f.create_dataset(
            table, shape=(0,), maxshape=(None,), chunks=(chunk,), dtype=dtype,
            compression="gzip", compression_opts=1, shuffle=True,
        )  # fmt: skip
    for meta in rf.META_NAMES:
        f.create_dataset(
            rf.meta_path(meta), shape=(0,), maxshape=(None,), chunks=(4096,), dtype=np.uint8
        )
    # The writer's process and host: a reader tells a killed writer from a live one by them.
    status = {"status": rf.STATUS_RUNNING, "writer": rf.writer_identity()}
    write_text(f, rf.META_STATUS, json.dumps(status))
    f.swmr_mode = True
    f.flush()
    return ds
