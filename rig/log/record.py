"""Record one run: a DAQ into a :class:`rig.log.writer.RunWriter` for a given time.

Used by ``cutlab daq record`` (:func:`plan_recording` checks its options, ``NiDaq.from_rig`` /
``SimDaq.from_rig`` make the DAQ, :func:`record_rig` records); the campaign runner can use
:func:`record` too. Also holds the synthetic milling-force source that ``--sim`` records when no
simulated machine drives the DAQ.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from analysis.runs import file as rf
from rig.daq import Calibration, Daq, DaqInfo
from rig.errors import RigError
from rig.log.writer import MIN_FREE_MB, RunWriter, WriterStats, free_space_problem

if TYPE_CHECKING:
    from analysis.config import Dynamometer, RigConfig


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


def aliasing_warning(rate_hz: float, dynamometer: Dynamometer) -> str | None:
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
class RecordPlan:
    """The checked options of one recording on the rig of ``rig`` (read from ``where``)."""

    rig: RigConfig
    where: str
    path: Path
    seconds: float
    rate_hz: float
    overwrite: bool
    conditions: dict[str, Any]
    notes: list[str]  # warnings to show and store as note events (aliasing)
    min_free_mb: float = MIN_FREE_MB  # MB kept free on the disk (the writer stops below it)


def plan_recording(
    rig_path: str | Path | None,
    path: str | Path,
    seconds: float,
    *,
    rate_hz: float | None = None,
    overwrite: bool = False,
    conditions: Mapping[str, object] | None = None,
    min_free_mb: float = MIN_FREE_MB,
) -> RecordPlan:
    """Check a recording before any device is opened: the rig config (None: configs/rig.toml),
    ``seconds`` > 0, ``rate_hz`` in (0, 1e7] Hz (None or 0: the config's), ``path`` new unless
    ``overwrite``, room on its disk for the recording (float64 bound) and the writer's margin
    ``min_free_mb``;
    ``notes`` gets the aliasing warning of the rate."""
    from analysis.config import load_rig

    rig = load_rig(rig_path)
    if not seconds > 0:
        raise RigError(f"--seconds = {seconds}: must be > 0 (s)")
    rate = float(rate_hz or rig.daq.rate_hz)
    if not 0 < rate <= 10_000_000:
        raise RigError(f"--rate-hz = {rate}: must be in (0, 1e7] Hz")
    out = Path(path)
    if out.exists() and not overwrite:
        raise RigError(f"{out}: file exists; --force overwrites it")
    if not 0 <= min_free_mb <= 1e6:
        raise RigError(f"--min-free-mb = {min_free_mb}: must be in [0, 1e6] MB")
    need = seconds * rate * len(rig.daq.channels) * 8
    problem = free_space_problem(out.parent, need, min_free_mb)
    if problem:
        raise RigError(problem)
    notes = [w for w in [aliasing_warning(rate, rig.dynamometer)] if w]
    where = str(rig_path or "configs/rig.toml")
    return RecordPlan(rig, where, out, seconds, rate, overwrite, dict(conditions or {}), notes,
                      float(min_free_mb))  # fmt: skip


class RecordSummary(TypedDict):
    """`cutlab daq record --json`: file, status, channels, rate (Hz), samples acquired /
    written / dropped / missing and the duration acquired (s)."""

    file: str
    status: str
    reason: str
    channels: list[str]
    rate_hz: float
    samples_acquired: int
    samples_written: int
    samples_dropped: int
    samples_missing: int
    duration_s: float


@dataclass(frozen=True)
class RecordResult:
    path: Path
    status: str
    reason: str
    samples_acquired: int
    writer: WriterStats
    info: DaqInfo | None = None  # the DAQ's

    def summary(self) -> RecordSummary:
        """File, status, channels, rate (Hz), samples acquired/written/dropped/missing and the
        duration (s) acquired, as ``cutlab daq record`` prints them."""
        rate_hz = self.info.rate_hz if self.info is not None else float("nan")
        return {
            "file": str(self.path),
            "status": self.status,
            "reason": self.reason,
            "channels": list(self.info.channel_names) if self.info is not None else [],
            "rate_hz": rate_hz,
            "samples_acquired": self.samples_acquired,
            "samples_written": self.writer.samples_written,
            "samples_dropped": self.writer.samples_dropped,
            "samples_missing": self.writer.samples_missing,
            "duration_s": self.samples_acquired / rate_hz,
        }


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
    conditions: Mapping[str, object] | None = None,
    rig: Mapping[str, object] | None = None,
    progress: Callable[[float], None] | None = None,
    notes: Sequence[str] = (),
    min_free_mb: float = MIN_FREE_MB,
) -> RecordResult:
    """Acquire for ``seconds`` of device time (or until the DAQ ends by itself) into ``path``.

    ``progress(seconds_acquired)`` is called about ten times a second. Ctrl-C ends the run with
    status ``abort``; a DAQ error or a failing medium (disk nearly full, write error) with status
    ``fail`` (the file keeps what was acquired, or flushed).
    ``notes`` (e.g. :func:`aliasing_warning`) are stored as ``note`` events at sample 0.
    ``min_free_mb``: the writer's margin (it stops below it). The result's ``writer`` counts
    what the closed file holds.
    """
    writer = RunWriter(
        path,
        daq.info,
        calibration,
        clock=clock,
        flush_interval_s=flush_interval_s,
        queue_blocks=queue_blocks,
        overwrite=overwrite,
        min_free_mb=min_free_mb,
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
            if got >= seconds * rate - 0.5 or writer.failure is not None:
                break
        daq.stop()
        if daq.error is not None:
            status, reason = rf.STATUS_FAIL, f"DAQ error: {daq.error}"
        elif writer.failure is not None:
            status, reason = rf.STATUS_FAIL, writer.failure
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
    return RecordResult(Path(path), status, reason, int(daq.samples_acquired), stats, daq.info)


def record_rig(
    daq: Daq,
    plan: RecordPlan,
    *,
    flush_interval_s: float = 1.0,
    progress: Callable[[float], None] | None = None,
) -> RecordResult:
    """:func:`record` of ``plan`` with a DAQ made by ``NiDaq.from_rig`` or ``SimDaq.from_rig``,
    which carries the ``calibration``, ``run_clock`` and ``rig_meta`` to record with;
    ``progress(seconds_acquired)``, capped at ``plan.seconds``, ends with the total acquired."""

    def report(t_s: float) -> None:
        if progress is not None:
            progress(round(min(t_s, plan.seconds), 3))

    res = record(
        daq, plan.path, plan.seconds, calibration=daq.calibration, clock=daq.run_clock,
        flush_interval_s=flush_interval_s, overwrite=plan.overwrite, conditions=plan.conditions,
        rig=daq.rig_meta, progress=report, notes=plan.notes, min_free_mb=plan.min_free_mb,
    )  # fmt: skip
    report(res.samples_acquired / daq.info.rate_hz)
    return res
