"""The HDF5 run file's loader, and the one namespace of the whole run file.

``rig.log.writer.RunWriter`` writes run files using the layout's constants; everything else reads
them through :func:`load_run` (whole run, or a time window) or :mod:`analysis.runs.follow` (a run
still being written). Nothing outside these modules and ``rig.log.writer`` should name an HDF5 path
of a run file.

The layout (its paths, dtypes, event kinds and statuses) is documented in
:mod:`analysis.runs.layout`, the repair of a file whose writer died in :mod:`analysis.runs.repair`;
both are re-exported here, the one namespace readers and the writer name (``from analysis.runs
import file as rf``: ``rf.EVENTS``, ``rf.repair_run``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd

from analysis.runs.layout import *  # noqa: F403 (the rf. namespace: see the docstring)
from analysis.runs.layout import (  # the names this module uses
    ATTR_FORMAT,
    ATTR_FORMAT_VERSION,
    ATTR_SOFTWARE_VERSION,
    BLOCK_DTYPE,
    BLOCKS,
    CAL_DRIFT_V_S,
    CAL_VOLTS_TO_N,
    CAL_ZERO_TIME_S,
    CAL_ZERO_V,
    CALIBRATION,
    CLOSED_STATUSES,
    EVENT_DTYPE,
    EVENTS,
    FLUSHED,
    FORCES,
    FORMAT_NAME,
    FORMAT_VERSION,
    LOSS_KINDS,
    META_ACQUISITION,
    META_CONDITIONS,
    META_PROGRAM,
    META_PROGRAM_INFO,
    META_RIG,
    META_STATUS,
    RAW,
    SAMPLE_FORMAT_RAW,
    SCALING_COEFF,
    STATUS_RUNNING,
    VOLTS,
    RunFileError,
    meta_json,
    meta_text,
    names_attr,
    read_table,
    samples_dataset,
)
from analysis.runs.repair import *  # noqa: F403
from analysis.runs.repair import (  # the names this module uses
    dead_writer_status,
    repair_run,
    writer_alive,
)


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
        events = read_table(f, EVENTS)
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
    status = meta_json(f, META_STATUS)
    state = str(status.get("status", STATUS_RUNNING))
    if state == STATUS_RUNNING and FLUSHED in f:
        # Past the last flush the extent may hold samples not yet (or never) written: zeros.
        n_stored = min(n_stored, int(f[FLUSHED][0]))
    reason = str(status.get("reason", ""))
    if state == STATUS_RUNNING and not writer_alive(status):
        state, reason = dead_writer_status(p, n_stored)  # not rewritten (no room, read-only)
    events = read_table(f, EVENTS)
    lo, hi = 0, n_stored
    if start_s is not None:
        lo = device_to_stored_index(math.ceil(start_s * rate_hz), n_stored, events)
    if stop_s is not None:
        hi = device_to_stored_index(math.ceil(stop_s * rate_hz), n_stored, events)
    if not samples:
        lo = hi = 0
    hi = max(lo, hi)
    acq = meta_json(f, META_ACQUISITION)
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
        blocks=blocks_frame(read_table(f, BLOCKS)),
        calibration=cal,
        conditions=meta_json(f, META_CONDITIONS),
        rig=meta_json(f, META_RIG),
        program_text=meta_text(f, META_PROGRAM),
        program_info=meta_json(f, META_PROGRAM_INFO),
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
