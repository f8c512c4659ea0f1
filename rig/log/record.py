"""Record one run: a DAQ into a :class:`rig.log.writer.RunWriter` for a given time.

Used by ``cutlab daq record``; the campaign runner can use it too. Also holds the synthetic
milling-force source that ``--sim`` records when no simulated machine drives the DAQ.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from analysis.runs import file as rf
from rig.daq import Calibration, Daq
from rig.log.writer import RunWriter, WriterStats


def milling_force_source(
    cal: Calibration | None,
    channels: int,
    tooth_hz: float = 100.0,
    mean_n: tuple[float, float, float] = (150.0, 80.0, 60.0),
    amplitude_n: tuple[float, float, float] = (120.0, 90.0, 40.0),
) -> Callable[[float, int, float], np.ndarray]:
    """A tooth-passing force pattern (N), turned into amplifier volts by ``cal``.

    Each tooth pass gives a half-sine pulse per axis; without a calibration (or with a channel
    count other than the calibration's) the pattern is given in volts at 1 V per 100 N.
    """
    m = np.resize(np.asarray(mean_n, float), channels)
    a = np.resize(np.asarray(amplitude_n, float), channels)
    phase = np.arange(channels) * 0.7

    def source(t0_s: float, n: int, rate_hz: float) -> np.ndarray:
        t = t0_s + np.arange(n) / rate_hz
        pulse = np.abs(np.sin(np.pi * tooth_hz * t[None, :] + phase[:, None]))
        force = m[:, None] + a[:, None] * (pulse - 2 / np.pi)
        if cal is not None and cal.n_channels == channels:
            return cal.volts_from_force(force.T, t).T
        return force / 100.0

    return source


def aliasing_warning(rate_hz: float, dynamometer: Any) -> str | None:
    """A one-line warning when ``rate_hz`` (Hz per channel) is below twice the highest mode of
    ``dynamometer`` (an ``analysis.config.Dynamometer``, modes with the workpiece mounted, seed 003
    Table 2), else None. Below that the mode aliases into the force band and cannot be filtered."""
    modes = tuple(getattr(dynamometer, "modes", ()))
    if not modes:
        return None
    top = max(modes, key=lambda m: m.frequency_hz)
    need_hz = 2.0 * top.frequency_hz
    if rate_hz >= need_hz:
        return None
    return (
        f"warning: sample rate {rate_hz:g} Hz is below twice the highest mode of the "
        f"{dynamometer.model} ({top.axis} {top.frequency_hz:g} Hz): use >= {need_hz:g} Hz"
    )


@dataclass(frozen=True)
class RecordResult:
    path: Path
    status: str
    reason: str
    samples_acquired: int
    writer: WriterStats


def record(
    daq: Daq,
    path: str | Path,
    seconds: float,
    *,
    calibration: Calibration | None = None,
    clock: Callable[[], float] = time.monotonic,
    flush_interval_s: float = 1.0,
    queue_blocks: int = 64,
    overwrite: bool = False,
    conditions: Mapping[str, Any] | None = None,
    rig: Mapping[str, Any] | None = None,
    progress: Callable[[float], None] | None = None,
    notes: Sequence[str] = (),
) -> RecordResult:
    """Acquire for ``seconds`` of device time (or until the DAQ ends by itself) into ``path``.

    ``progress(seconds_acquired)`` is called about ten times a second. Ctrl-C ends the run with
    status ``abort``; a DAQ error with status ``fail`` (the file keeps what was acquired).
    ``notes`` (e.g. :func:`aliasing_warning`) are stored as ``note`` events at sample 0.
    """
    writer = RunWriter(
        path,
        daq.info,
        calibration,
        clock=clock,
        flush_interval_s=flush_interval_s,
        queue_blocks=queue_blocks,
        overwrite=overwrite,
    )
    if conditions:
        writer.set_conditions(conditions)
    if rig:
        writer.set_rig(rig)
    for note in notes:
        writer.event(rf.EV_NOTE, note, sample=0)
    status, reason = rf.STATUS_SUCCESS, ""
    try:
        daq.start(writer)
        rate = daq.info.rate_hz
        while not daq.wait(0.1):
            got = daq.samples_acquired
            if progress is not None:
                progress(got / rate)
            if got >= seconds * rate - 0.5:
                break
        daq.stop()
        if daq.error is not None:
            status, reason = rf.STATUS_FAIL, f"DAQ error: {daq.error}"
    except KeyboardInterrupt:
        daq.stop()
        status, reason = rf.STATUS_ABORT, "interrupted (Ctrl-C)"
    except BaseException as exc:
        daq.close()
        writer.close(rf.STATUS_FAIL, f"{type(exc).__name__}: {exc}"[:500])
        if daq.samples_acquired == 0:
            Path(path).unlink(missing_ok=True)  # the DAQ never started: no run to keep
        raise
    daq.close()
    stats = writer.close(status, reason)
    return RecordResult(Path(path), status, reason, int(daq.samples_acquired), stats)
