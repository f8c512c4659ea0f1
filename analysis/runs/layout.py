"""The HDF5 run file's layout (documented here and only here): its paths, dtypes, event kinds
and statuses, and the readers of its small parts. :mod:`analysis.runs.file` re-exports them all
(``rf.EVENTS``, ``rf.STATUS_SUCCESS``): that namespace is what readers and the writer name.

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
"""

from __future__ import annotations

import json
from typing import Any

import h5py
import numpy as np

from analysis.errors import AnalysisError

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "ATTR_FORMAT",
    "ATTR_FORMAT_VERSION",
    "ATTR_SOFTWARE_VERSION",
    "ATTR_CREATED_UTC",
    "FORCES",
    "RAW",
    "VOLTS",
    "SCALING_COEFF",
    "FLUSHED",
    "SAMPLE_FORMAT_RAW",
    "SAMPLE_FORMAT_VOLTS",
    "CALIBRATION",
    "CAL_VOLTS_TO_N",
    "CAL_ZERO_V",
    "CAL_ZERO_TIME_S",
    "CAL_DRIFT_V_S",
    "EVENTS",
    "BLOCKS",
    "EVENT_MESSAGE_BYTES",
    "BLOCK_TEXT_BYTES",
    "EVENT_DTYPE",
    "BLOCK_DTYPE",
    "EV_START",
    "EV_STOP",
    "EV_PAUSE",
    "EV_RESUME",
    "EV_OVERFLOW",
    "EV_GAP",
    "EV_QUEUE_FULL",
    "EV_INTERLOCK",
    "EV_FAULT",
    "EV_SATURATION",
    "EV_ZERO",
    "EV_NOTE",
    "EVENT_KINDS",
    "LOSS_KINDS",
    "META",
    "META_CONDITIONS",
    "META_RIG",
    "META_PROGRAM",
    "META_PROGRAM_INFO",
    "META_ACQUISITION",
    "META_STATUS",
    "META_NAMES",
    "META_JSON",
    "STATUS_RUNNING",
    "STATUS_SUCCESS",
    "STATUS_ABORT",
    "STATUS_FAIL",
    "STATUS_INTERRUPTED",
    "STATUSES",
    "CLOSED_STATUSES",
    "RunFileError",
    "meta_path",
    "decode_text",
    "names_attr",
    "meta_text",
    "meta_json",
    "read_table",
    "samples_dataset",
]

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


def names_attr(v: np.ndarray | list[str] | bytes | str) -> tuple[str, ...]:
    """An HDF5 attribute of names (bytes or str, one or many) as a tuple of str."""
    return tuple(x.decode() if isinstance(x, bytes) else str(x) for x in np.atleast_1d(v))


def meta_text(f: h5py.File, name: str) -> str:
    """The text metadata ``name`` of an open run file ("" if it has none)."""
    p = meta_path(name)
    return decode_text(f[p]) if p in f else ""


def meta_json(f: h5py.File, name: str) -> dict[str, Any]:
    """The JSON metadata ``name`` of an open run file ({} if it has none)."""
    try:  # half-written under SWMR is impossible; a corrupt file is not
        doc = json.loads(meta_text(f, name) or "{}")
    except json.JSONDecodeError:
        doc = None
    if not isinstance(doc, dict):
        raise RunFileError(f"{f.filename}: /{meta_path(name)} is not a valid JSON object")
    return doc


def read_table(f: h5py.File, path: str) -> np.ndarray:
    """The events or blocks table at ``path``, in today's dtype (empty if absent)."""
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


def samples_dataset(f: h5py.File) -> h5py.Dataset:
    """The dataset holding the samples (codes or volts) of an open run file."""
    return f[RAW] if RAW in f else f[VOLTS]
