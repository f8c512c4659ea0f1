"""The HDF5 run file: its layout (documented here and only here) and the loader.

``rig.log.writer.RunWriter`` writes run files using the constants below; everything else reads them
through :func:`load_run` (whole run, or a time window) or :mod:`analysis.runs.follow` (a run still
being written). Nothing outside these modules and ``rig.log.writer`` should name an HDF5 path of a
run file.

Layout (format ``cutlab-run``, version 1; HDF5 >= 1.10 "latest" format so that the file can be read
while it is written, SWMR)::

    /                                   attrs: cutlab_format = "cutlab-run"
                                               cutlab_format_version = 1
                                               software_version (analysis.__version__)
                                               created_utc (ISO 8601)
    /forces/                            attrs: rate_hz (Hz, per channel), sample_format
                                               ("raw_int16" | "volts_float64"),
                                               channel_names (force names, e.g. Fx Fy Fz),
                                               physical_channels (e.g. Dev1/ai0), device,
                                               input_range_v (V, symmetric), units_force = "N",
                                               units_volts = "V", units_raw = "ADC code"
    /forces/raw          int16   (n, c)  ADC codes (sample_format raw_int16), or
    /forces/volts        float64 (n, c)  volts     (sample_format volts_float64)
                                         chunked, resizable along n; gzip+shuffle for int16 codes
                                         (they compress about 2x), none for float64 noise (it does
                                         not pay and would halve the sustained rate)
    /forces/scaling_coeff float64 (c, k) raw only: device polynomial, volts = sum_j a[:, j] code^j
                                         (nidaqmx ``ai_dev_scaling_coeff``)
    /forces/flushed      int64   (1,)    samples on disk: set after each flush, so a live reader
                                         reads no further (the dataset's extent can reach the
                                         reader before the samples in it do)
    /calibration/                       attrs: calibration_id, dynamometer, sensitivity_pc_n (c),
                                               amp_sensitivity_pc_n (c), range_n_v (c), sign (c),
                                               crosstalk (c, c) (measured = C @ true)
    /calibration/volts_to_n   float64 (c, c) N/V: force_n = volts_to_n @ (volts - zero - drift)
    /calibration/zero_v       float64 (c,)   V, amplifier output at zero load (reset/operate)
    /calibration/zero_time_s  float64 ()     s on the run clock when the zero was taken
    /calibration/drift_v_s    float64 (c,)   V/s, linear drift removed as drift_v_s * (t - zero_t)
    /events              compound (m,)   sample int64 (device sample index, see below),
                                         lost int64 (samples per channel missing at this point),
                                         time_s float64 (run clock), wall_utc float64 (Unix s),
                                         kind S16 (EVENT_KINDS), message S200
    /nc/blocks           compound (b,)   block int64 (0-based), line int64 (1-based source line),
                                         send_s, ack_s float64 (run clock; ack NaN until acked),
                                         exec_s float64 (run clock: the control started executing
                                         it; NaN if unknown; format 2), text S256 (the block as
                                         sent; full text in meta/program)
    /meta/<name>         uint8 (bytes,)  UTF-8 text, resizable so it can change during the run:
                                         conditions (JSON), rig (JSON), program (NC text),
                                         program_info (JSON: name, sha256, lines),
                                         acquisition (JSON: t0_s, started_utc), status (JSON:
                                         status running|success|abort|fail, reason, closed_utc)

Sample indices and time: the DAQ numbers its samples 0, 1, 2, ... from the start of acquisition
(the device's own count). Stored samples are contiguous in ``/forces/*`` but a dropped block leaves
a hole on the device clock; every hole is an event with ``lost > 0`` (kinds ``gap`` and
``queue_full``) at the device index of the first missing sample. So the device index of stored
sample i is i plus the sum of ``lost`` over events with ``sample`` before it, and its time on the
run clock is ``t0_s + index / rate_hz``. ``t0_s`` is the run clock (SimClock seconds on the
simulated rig, ``time.monotonic`` on hardware) at device sample 0; block send/ack times use the
same clock.

Why the metadata that changes during a run lives in small byte datasets rather than attributes:
under SWMR a writer may not create objects or attributes, so everything is created before SWMR is
switched on and changed later only by writing into existing datasets.

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
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd

from analysis.errors import AnalysisError
from analysis.runs.identity import writer_identity as writer_identity  # re-exported: rig.log

FORMAT_NAME = "cutlab-run"
FORMAT_VERSION = 2  # 2: /nc/blocks has exec_s (format 1 files read with exec_s NaN)

# Root attributes.
ATTR_FORMAT = "cutlab_format"
ATTR_FORMAT_VERSION = "cutlab_format_version"
ATTR_SOFTWARE_VERSION = "software_version"
ATTR_CREATED_UTC = "created_utc"

# Samples.
FORCES = "forces"
RAW = "forces/raw"
VOLTS = "forces/volts"
SCALING_COEFF = "forces/scaling_coeff"
FLUSHED = "forces/flushed"
SAMPLE_FORMAT_RAW = "raw_int16"
SAMPLE_FORMAT_VOLTS = "volts_float64"

# Calibration.
CALIBRATION = "calibration"
CAL_VOLTS_TO_N = "calibration/volts_to_n"
CAL_ZERO_V = "calibration/zero_v"
CAL_ZERO_TIME_S = "calibration/zero_time_s"
CAL_DRIFT_V_S = "calibration/drift_v_s"

# Tables.
EVENTS = "events"
BLOCKS = "nc/blocks"
EVENT_MESSAGE_BYTES = 200
BLOCK_TEXT_BYTES = 256
EVENT_DTYPE = np.dtype(
    [
        ("sample", "<i8"),
        ("lost", "<i8"),
        ("time_s", "<f8"),
        ("wall_utc", "<f8"),
        ("kind", "S16"),
        ("message", f"S{EVENT_MESSAGE_BYTES}"),
    ]
)
BLOCK_DTYPE = np.dtype(
    [
        ("block", "<i8"),
        ("line", "<i8"),
        ("send_s", "<f8"),
        ("ack_s", "<f8"),
        ("exec_s", "<f8"),
        ("text", f"S{BLOCK_TEXT_BYTES}"),
    ]
)

# Event kinds. ``gap`` and ``queue_full`` carry ``lost`` > 0 (samples missing from the file).
EV_START = "start"
EV_STOP = "stop"
EV_PAUSE = "pause"
EV_RESUME = "resume"
EV_OVERFLOW = "overflow"  # the DAQ's buffer overran (DAQmx -200279 and kin)
EV_GAP = "gap"  # samples missing on the device clock (a dropped or unread block)
EV_QUEUE_FULL = "queue_full"  # the logger's queue was full; the block was dropped
EV_INTERLOCK = "interlock"
EV_FAULT = "fault"  # a DAQ or rig error
EV_SATURATION = "saturation"  # samples at the ADC limits
EV_ZERO = "zero"  # amplifier zeroed (reset/operate)
EV_NOTE = "note"
EVENT_KINDS = (
    EV_START,
    EV_STOP,
    EV_PAUSE,
    EV_RESUME,
    EV_OVERFLOW,
    EV_GAP,
    EV_QUEUE_FULL,
    EV_INTERLOCK,
    EV_FAULT,
    EV_SATURATION,
    EV_ZERO,
    EV_NOTE,
)
LOSS_KINDS = (EV_GAP, EV_QUEUE_FULL)

# Text metadata (``/meta/<name>``).
META = "meta"
META_CONDITIONS = "conditions"
META_RIG = "rig"
META_PROGRAM = "program"
META_PROGRAM_INFO = "program_info"
META_ACQUISITION = "acquisition"
META_STATUS = "status"
META_NAMES = (
    META_CONDITIONS,
    META_RIG,
    META_PROGRAM,
    META_PROGRAM_INFO,
    META_ACQUISITION,
    META_STATUS,
)
META_JSON = frozenset(META_NAMES) - {META_PROGRAM}

STATUS_RUNNING = "running"
STATUS_SUCCESS = "success"
STATUS_ABORT = "abort"
STATUS_FAIL = "fail"
STATUS_INTERRUPTED = "interrupted"  # the writer died without closing the file (set on reading)
STATUSES = (STATUS_RUNNING, STATUS_SUCCESS, STATUS_ABORT, STATUS_FAIL, STATUS_INTERRUPTED)
CLOSED_STATUSES = (STATUS_SUCCESS, STATUS_ABORT, STATUS_FAIL)  # what a writer closes with


class RunFileError(AnalysisError):
    """A run file cannot be read: missing, not HDF5, another program's HDF5, or truncated."""


def meta_path(name: str) -> str:
    """HDF5 path of the text metadata ``name`` (one of :data:`META_NAMES`)."""
    return f"{META}/{name}"


def decode_text(ds: h5py.Dataset) -> str:
    """The UTF-8 text held in a ``/meta/<name>`` byte dataset."""
    return bytes(np.asarray(ds[()], dtype=np.uint8)).decode("utf-8")


def raw_to_volts(raw: np.ndarray, coeff: np.ndarray) -> np.ndarray:
    """Scale ADC codes to volts with the device polynomial.

    raw : ndarray, shape (n, c), int16 codes. coeff : ndarray, shape (c, k), volts per code^j.
    Returns float64 volts, shape (n, c).
    """
    x = raw.astype(np.float64)
    out = np.zeros_like(x)
    for j in range(coeff.shape[1] - 1, -1, -1):  # Horner, per channel
        out = out * x + coeff[:, j]
    return out


def volts_to_force(
    volts: np.ndarray,
    time_s: np.ndarray,
    volts_to_n: np.ndarray,
    zero_v: np.ndarray,
    zero_time_s: float,
    drift_v_s: np.ndarray,
) -> np.ndarray:
    """Apply the stored affine calibration (built by ``rig.daq.calibration``).

    volts : (n, c) V; time_s : (n,) run clock s (only read when a drift is set). Returns force,
    (n, c) N: ``force = volts_to_n @ (volts - zero_v - drift_v_s * (t - zero_time_s))`` per
    sample. One (n, c) temporary besides the result: this runs over every sample loaded.
    """
    corrected = np.subtract(volts, zero_v, dtype=np.float64)
    if np.any(drift_v_s):
        dt = np.asarray(time_s, dtype=np.float64)
        dt = dt - (zero_time_s if math.isfinite(zero_time_s) else 0.0)
        corrected -= dt[:, None] * drift_v_s
    # einsum (BLAS through tensordot) is 2-3x faster than ``@`` for an (n, 3) x (3, 3) product.
    return np.asarray(np.einsum("nj,ij->ni", corrected, volts_to_n, optimize=True))


@dataclass(frozen=True)
class CalibrationRecord:
    """The calibration stored in a run: the affine map and the sheet values it came from."""

    volts_to_n: np.ndarray  # (c, c) N/V
    zero_v: np.ndarray  # (c,) V
    zero_time_s: float  # s, run clock (NaN: not zeroed)
    drift_v_s: np.ndarray  # (c,) V/s
    attrs: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Run:
    """One recorded run, as returned by :func:`load_run`.

    Sample arrays are (n_samples, n_channels), one row per stored sample; ``time_s`` and
    ``sample_index`` account for any hole (see the module docstring).
    """

    path: Path
    rate_hz: float
    channel_names: tuple[str, ...]
    physical_channels: tuple[str, ...]
    device: str
    sample_format: str
    raw: np.ndarray | None  # (n, c) int16 ADC codes, or None when volts were stored
    scaling_coeff: np.ndarray | None  # (c, k)
    volts: np.ndarray  # (n, c) V
    force_n: np.ndarray | None  # (n, c) N, None without a calibration
    sample_index: np.ndarray  # (n,) int64, device sample index
    time_s: np.ndarray  # (n,) s, run clock
    t0_s: float  # s, run clock at device sample 0 (NaN if acquisition never started)
    events: pd.DataFrame
    blocks: pd.DataFrame
    calibration: CalibrationRecord | None
    conditions: dict[str, Any]
    rig: dict[str, Any]
    program_text: str
    program_info: dict[str, Any]
    status: str
    reason: str
    complete: bool  # the writer closed the file (False: killed, or still writing)
    software_version: str
    samples_stored: int  # per channel, in the file
    samples_acquired: int  # per channel, on the device clock (stored + lost)
    samples_lost: int

    @property
    def duration_s(self) -> float:
        """Span of the device clock covered, s (stored plus lost samples)."""
        return self.samples_acquired / self.rate_hz

    def forces(self) -> pd.DataFrame:
        """Calibrated forces (N), or volts if the run has no calibration, indexed by time_s."""
        data = self.force_n if self.force_n is not None else self.volts
        df = pd.DataFrame(data, columns=list(self.channel_names))
        df.index = pd.Index(self.time_s, name="time_s")
        return df

    def executing_block(self, time_s: np.ndarray | None = None) -> np.ndarray:
        """The NC block the control was executing at each time (default: each sample's), from
        the blocks' ``exec_s`` (not their ack: an ack means planned, not cutting); -1 before the
        first block started or where no block records its execution start."""
        t = self.time_s if time_s is None else np.asarray(time_s, dtype=float)
        rows = self.blocks[np.isfinite(self.blocks["exec_s"])].sort_values("exec_s")
        k = np.searchsorted(rows["exec_s"].to_numpy(), t, side="right") - 1
        blocks = np.append(rows["block"].to_numpy(dtype=np.int64), -1)
        return blocks[np.where(k >= 0, k, len(rows))]


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
            old = _json(src, META_STATUS)
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


def open_run_file(path: str | Path) -> h5py.File:
    """Open a run file for reading with errors that say what is wrong with it."""
    p = Path(path)
    if not p.exists():
        raise RunFileError(f"{p}: run file not found")
    if p.is_dir():
        raise RunFileError(f"{p}: is a folder, expected an HDF5 run file")
    with p.open("rb") as fh:
        head = fh.read(8)
    if not h5py.is_hdf5(str(p)):
        what = "an empty file" if not head else f"starts with {head!r}"
        raise RunFileError(f"{p}: not an HDF5 file ({what}); expected a cutlab run file")
    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        msg = str(exc)
        if "already open for write" in msg:
            # Killed writer (consistency flags left set) or a live one: SWMR read works for both.
            try:
                f = h5py.File(p, "r", libver="latest", swmr=True)
            except OSError as exc2:
                raise RunFileError(f"{p}: cannot open the run file: {exc2}") from None
            _check_format(f, p)
            return f
        if "truncated" in msg:
            m = re.search(r"stored_eof = (\d+)", msg)
            want = f" of the {m.group(1)} it should have" if m else ""
            raise RunFileError(
                f"{p}: truncated HDF5 file: {p.stat().st_size} bytes{want} (an interrupted "
                "copy or download?)"
            ) from None
        raise RunFileError(f"{p}: cannot open as HDF5: {msg}") from None
    _check_format(f, p)
    return f


def _check_format(f: h5py.File, p: Path) -> None:
    fmt = f.attrs.get(ATTR_FORMAT)
    if isinstance(fmt, bytes):
        fmt = fmt.decode()
    if fmt != FORMAT_NAME:
        top = ", ".join(sorted(f.keys())[:8]) or "nothing"
        f.close()
        raise RunFileError(
            f"{p}: HDF5 file of another program (no '{ATTR_FORMAT}' = '{FORMAT_NAME}' attribute; "
            f"top level holds {top}); expected a cutlab run file"
        )
    ver = int(f.attrs.get(ATTR_FORMAT_VERSION, -1))
    if ver > FORMAT_VERSION:
        f.close()
        raise RunFileError(
            f"{p}: run file format version {ver} is newer than this cutlab reads "
            f"({FORMAT_VERSION}); update cutlab"
        )


def names_attr(v: np.ndarray | list[str] | bytes | str) -> tuple[str, ...]:
    return tuple(x.decode() if isinstance(x, bytes) else str(x) for x in np.atleast_1d(v))


def _text(f: h5py.File, name: str) -> str:
    p = meta_path(name)
    return decode_text(f[p]) if p in f else ""


def _json(f: h5py.File, name: str) -> dict[str, Any]:
    try:  # half-written under SWMR is impossible; a corrupt file is not
        doc = json.loads(_text(f, name) or "{}")
    except json.JSONDecodeError:
        doc = None
    if not isinstance(doc, dict):
        raise RunFileError(f"{f.filename}: /{meta_path(name)} is not a valid JSON object")
    return doc


def _table(f: h5py.File, path: str) -> np.ndarray:
    dtype = EVENT_DTYPE if path == EVENTS else BLOCK_DTYPE
    if path not in f:
        return np.zeros(0, dtype=dtype)
    rows: np.ndarray = f[path][()]
    if rows.dtype == dtype:
        return rows
    out = np.zeros(len(rows), dtype=dtype)  # an older format: fields it lacks are NaN
    for name in dtype.names or ():
        out[name] = rows[name] if name in (rows.dtype.names or ()) else np.nan
    return out


def events_frame(rows: np.ndarray) -> pd.DataFrame:
    """Events table rows (EVENT_DTYPE) as a DataFrame with str columns."""
    df = pd.DataFrame({n: rows[n] for n in EVENT_DTYPE.names or ()})
    for col in ("kind", "message"):
        df[col] = [b.decode("utf-8", "replace") for b in rows[col]]
    return df


def blocks_frame(rows: np.ndarray) -> pd.DataFrame:
    """NC blocks table rows (BLOCK_DTYPE) as a DataFrame with str text."""
    df = pd.DataFrame({n: rows[n] for n in BLOCK_DTYPE.names or ()})
    df["text"] = [b.decode("utf-8", "replace") for b in rows["text"]]
    return df


def _holes(events: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sample holes of a run from its loss events: (stored_at (k,), cum_lost (k+1,)) int64.

    Hole j sits before stored sample ``stored_at[j]``; ``cum_lost[j]`` samples were lost before it
    (``cum_lost[0] = 0``, ``cum_lost[-1]`` the total).
    """
    loss = events[np.isin(events["kind"], [k.encode() for k in LOSS_KINDS]) & (events["lost"] > 0)]
    order = np.argsort(loss["sample"], kind="stable")
    at = loss["sample"][order].astype(np.int64)
    cum = np.concatenate([[0], np.cumsum(loss["lost"][order], dtype=np.int64)])
    return at - cum[:-1], cum


def stored_to_device_index(n_stored: int, events: np.ndarray, start: int = 0) -> np.ndarray:
    """Device sample index of stored samples ``start..n_stored-1``, (n_stored - start,) int64."""
    stored_at, cum = _holes(events)
    idx = np.arange(start, n_stored, dtype=np.int64)
    if not len(stored_at):
        return idx
    # Every hole at or before a stored sample shifts it by that hole's loss.
    return np.asarray(idx + cum[np.searchsorted(stored_at, idx, side="right")])


def device_to_stored_index(device: int, n_stored: int, events: np.ndarray) -> int:
    """The first stored sample whose device index is >= ``device`` (``n_stored`` if none).

    O(holes): a window of a long run costs no whole-run index.
    """
    stored_at, cum = _holes(events)
    k = int(np.searchsorted(stored_at + cum[1:], device, side="right"))  # holes ending <= device
    stored = device - int(cum[k])
    if k < len(stored_at):  # inside hole k: the first sample after it
        stored = min(stored, int(stored_at[k]))
    return min(max(stored, 0), n_stored)


def _read_samples(f: h5py.File, p: Path, sl: slice) -> tuple[np.ndarray | None, np.ndarray]:
    fmt = f[FORCES].attrs["sample_format"]
    fmt = fmt.decode() if isinstance(fmt, bytes) else str(fmt)
    try:
        if fmt == SAMPLE_FORMAT_RAW:
            raw = f[RAW][sl]
            return raw, raw_to_volts(raw, f[SCALING_COEFF][()])
        return None, np.asarray(f[VOLTS][sl], dtype=np.float64)
    except (OSError, KeyError) as exc:
        raise RunFileError(f"{p}: samples cannot be read (truncated or corrupt): {exc}") from None


def samples_dataset(f: h5py.File) -> h5py.Dataset:
    return f[RAW] if RAW in f else f[VOLTS]


def load_run(
    path: str | Path,
    start_s: float | None = None,
    stop_s: float | None = None,
    *,
    samples: bool = True,
    repair: bool = True,
) -> Run:
    """Load a run file (optionally the samples between ``start_s`` and ``stop_s`` after t0).

    ``start_s``/``stop_s`` are seconds of the device clock from its first sample. With
    ``samples=False`` only metadata, events and blocks are read (sample arrays have 0 rows; the
    counts are still filled in): cheap for a large run.

    A file whose writer died is repaired first (:func:`repair_run`; ``repair=False`` leaves it
    as it is) and reads with status ``interrupted``, its samples up to the writer's last flush.

    Raises :class:`RunFileError` for a missing file, a non-HDF5 file, another program's HDF5
    file, a newer format version, or a truncated file.
    """
    p = Path(path)
    if repair:
        repair_run(p)
    f = open_run_file(p)
    try:
        return _load(f, p, start_s, stop_s, samples)
    except (OSError, KeyError) as exc:
        raise RunFileError(f"{p}: damaged run file (truncated or corrupt): {exc}") from None
    finally:
        f.close()


def iter_forces(
    path: str | Path, windows: Iterable[tuple[int, int]], meta: Run
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(device sample index (m,), force (m, c) N) of each device-sample window [a, b) of a run
    file: what ``load_run(path, (a - 0.5) / rate, (b - 0.5) / rate)`` gives as ``sample_index``
    and ``force_n``, the same numbers, with the file opened and ``meta`` (its
    ``load_run(path, samples=False)``, which also repairs it) read once: for streaming readers,
    whose per-window cost was the metadata. ``meta`` needs a calibration."""
    p = Path(path)
    cal, n_stored = meta.calibration, meta.samples_stored
    if cal is None:
        raise RunFileError(f"{p}: the run has no calibration: forces in N are unknown")
    f = open_run_file(p)
    try:
        events = _table(f, EVENTS)
        for a, b in windows:
            lo = device_to_stored_index(a, n_stored, events)
            hi = max(lo, device_to_stored_index(b, n_stored, events))
            _, volts, idx, time_s = _window(f, p, lo, hi, events, meta.rate_hz, meta.t0_s)
            yield idx, volts_to_force(volts, time_s, cal.volts_to_n, cal.zero_v,
                                      cal.zero_time_s, cal.drift_v_s)  # fmt: skip
    except (OSError, KeyError) as exc:
        raise RunFileError(f"{p}: damaged run file (truncated or corrupt): {exc}") from None
    finally:
        f.close()


def _window(
    f: h5py.File, p: Path, lo: int, hi: int, events: np.ndarray, rate_hz: float, t0_s: float
) -> tuple[np.ndarray | None, np.ndarray, np.ndarray, np.ndarray]:
    """Stored samples [lo, hi): raw codes (or None), volts, device sample index, run clock s."""
    raw, volts = _read_samples(f, p, slice(lo, hi))
    sample_index = stored_to_device_index(hi, events, start=lo)
    time_s = (0.0 if math.isnan(t0_s) else t0_s) + sample_index / rate_hz
    return raw, volts, sample_index, time_s


def _load(f: h5py.File, p: Path, start_s: float | None, stop_s: float | None, samples: bool) -> Run:
    fa = f[FORCES].attrs
    rate_hz = float(fa["rate_hz"])
    ds = samples_dataset(f)
    n_stored = int(ds.shape[0])
    status = _json(f, META_STATUS)
    state = str(status.get("status", STATUS_RUNNING))
    if state == STATUS_RUNNING and FLUSHED in f:
        # Past the last flush the extent may hold samples not yet (or never) written: zeros.
        n_stored = min(n_stored, int(f[FLUSHED][0]))
    reason = str(status.get("reason", ""))
    if state == STATUS_RUNNING and not writer_alive(status):
        state, reason = STATUS_INTERRUPTED, _interrupted_reason(n_stored)
        left = _sidecar_reason(p)
        if left is not None:  # not rewritten (no room, read-only): the writer's reason still
            state, reason = left
    events = _table(f, EVENTS)
    lo, hi = 0, n_stored
    if start_s is not None:
        lo = device_to_stored_index(math.ceil(start_s * rate_hz), n_stored, events)
    if stop_s is not None:
        hi = device_to_stored_index(math.ceil(stop_s * rate_hz), n_stored, events)
    if not samples:
        lo = hi = 0
    hi = max(lo, hi)
    acq = _json(f, META_ACQUISITION)
    t0_s = float(acq.get("t0_s", math.nan))
    raw, volts, sample_index, time_s = _window(f, p, lo, hi, events, rate_hz, t0_s)

    cal = None
    force_n = None
    if CAL_VOLTS_TO_N in f:
        cal = CalibrationRecord(
            volts_to_n=f[CAL_VOLTS_TO_N][()],
            zero_v=f[CAL_ZERO_V][()],
            zero_time_s=float(f[CAL_ZERO_TIME_S][()]),
            drift_v_s=f[CAL_DRIFT_V_S][()],
            attrs={k: _attr_value(v) for k, v in f[CALIBRATION].attrs.items()},
        )
        force_n = volts_to_force(
            volts, time_s, cal.volts_to_n, cal.zero_v, cal.zero_time_s, cal.drift_v_s
        )
    lost = int(_holes(events)[1][-1])
    return Run(
        path=p,
        rate_hz=rate_hz,
        channel_names=names_attr(fa["channel_names"]),
        physical_channels=names_attr(fa.get("physical_channels", [])),
        device=str(_attr_value(fa.get("device", ""))),
        sample_format=str(_attr_value(fa["sample_format"])),
        raw=raw,
        scaling_coeff=f[SCALING_COEFF][()] if SCALING_COEFF in f else None,
        volts=volts,
        force_n=force_n,
        sample_index=sample_index,
        time_s=time_s,
        t0_s=t0_s,
        events=events_frame(events),
        blocks=blocks_frame(_table(f, BLOCKS)),
        calibration=cal,
        conditions=_json(f, META_CONDITIONS),
        rig=_json(f, META_RIG),
        program_text=_text(f, META_PROGRAM),
        program_info=_json(f, META_PROGRAM_INFO),
        status=state,
        reason=reason,
        complete=state in CLOSED_STATUSES,
        software_version=str(_attr_value(f.attrs.get(ATTR_SOFTWARE_VERSION, ""))),
        samples_stored=n_stored,
        samples_acquired=n_stored + lost,
        samples_lost=lost,
    )


def _attr_value(v: Any) -> Any:
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.ndarray):
        if v.dtype.kind in "SO":
            return [x.decode() if isinstance(x, bytes) else x for x in v.tolist()]
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    return v
