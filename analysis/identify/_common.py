"""Shared pieces of the force-coefficient identification: runs, their conditions, revolution
averages (the fit and its statistics: :mod:`analysis.identify._linear`).

Private to ``analysis.identify.facemill`` / ``analysis.identify.endmill`` /
``analysis.identify.validate`` (the public names are re-exported there).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.config import Dynamometer
from analysis.errors import AnalysisError
from analysis.identify._types import Progress
from analysis.modal import DynamometerFilter
from analysis.runs.steady import (
    IDENTIFY_TOLERANCE,
    NoAirError,
    RevolutionStats,
    SyncAverager,
    find_steady,
    refine_period,
    steady_from_stats,
    tooth_peaks,
)

#: Condition keys whose unit cutlab does not use; a run giving them is refused (mixed units).
_FOREIGN_UNITS = ("_in", "_inch", "_ipm", "_ipt", "_m", "_cm", "_um", "_sfm")


@dataclass(frozen=True)
class RunConditions:
    """Cutting conditions of one run (mm, rpm, deg).

    ``width_mm``: face mill — workpiece width across the feed; end mill — radial width of cut
    ae. ``mode``: end mill only, 'up', 'down' or 'slot'. ``center_offset_mm``: face mill only,
    workpiece centre line from the cutter axis along +Y.
    """

    spindle_rpm: float
    fz_mm: float
    depth_mm: float
    width_mm: float = math.nan
    tool: str = ""
    material: str = ""
    center_offset_mm: float = 0.0
    mode: str = "down"
    feed_angle_deg: float = 0.0

    @classmethod
    def from_mapping(cls, d: Mapping[str, Any], where: str = "<conditions>") -> RunConditions:
        """From a run file's conditions (JSON) or a table row; refuses foreign units.

        ``fz_mm`` may be replaced by ``feed_mm_min`` together with ``teeth`` (or ``flutes``).
        """
        for k, v in d.items():
            if any(str(k).endswith(s) for s in _FOREIGN_UNITS):
                raise AnalysisError(
                    f"{where}: {k} = {v!r}: cutlab works in mm, rpm and deg (mixed units); give "
                    f"{str(k).rsplit('_', 1)[0]}_mm"
                )
        units = str(d.get("units", "mm")).strip().lower()
        if units not in ("mm", "metric", ""):
            raise AnalysisError(f"{where}: units = {units!r}: only mm is understood (mixed units)")

        def num(key: str, default: float | None = None) -> float:
            if key not in d or d[key] is None or d[key] == "":
                if default is None:
                    raise AnalysisError(f"{where}: missing condition {key!r}")
                return default
            try:
                return float(d[key])
            except (TypeError, ValueError):
                raise AnalysisError(f"{where}: {key} = {d[key]!r}: not a number") from None

        rpm = num("spindle_rpm")
        if "fz_mm" in d:
            fz = num("fz_mm")
        elif "feed_mm_min" in d and ("teeth" in d or "flutes" in d):
            teeth = num("teeth") if "teeth" in d else num("flutes")
            fz = num("feed_mm_min") / (abs(rpm) * teeth)
        else:
            raise AnalysisError(
                f"{where}: missing condition 'fz_mm' (or feed_mm_min with teeth), mm/tooth"
            )
        c = cls(
            spindle_rpm=rpm,
            fz_mm=fz,
            depth_mm=num("depth_mm"),
            width_mm=num("width_mm", math.nan),
            tool=str(d.get("tool", "")),
            material=str(d.get("material", "")),
            center_offset_mm=num("center_offset_mm", 0.0),
            mode=str(d.get("mode", "down")),
            feed_angle_deg=num("feed_angle_deg", 0.0),
        )
        c.check(where)
        return c

    def check(self, where: str = "<conditions>") -> None:
        for name, lo, hi, unit in (
            ("spindle_rpm", 1.0, 200_000.0, "rpm"),
            ("fz_mm", 1e-4, 5.0, "mm/tooth"),
            ("depth_mm", 1e-3, 100.0, "mm"),
        ):
            v = abs(getattr(self, name)) if name == "spindle_rpm" else getattr(self, name)
            if not lo <= v <= hi:
                hint = " (a feed in mm/min given as mm/tooth?)" if name == "fz_mm" else ""
                raise AnalysisError(
                    f"{where}: {name} = {getattr(self, name)!r}: expected {lo}..{hi} {unit}{hint}"
                )


@dataclass(frozen=True)
class ForceRun:
    """A force record in dynamometer axes: ``force_n`` (n, 3) X, Y, Z in ``force_unit`` (N)."""

    name: str
    force_n: np.ndarray
    rate_hz: float
    conditions: RunConditions
    force_unit: str = "N"


@dataclass(frozen=True)
class RunAverage:
    """A run reduced to its steady part: what the fits use.

    ``waveform_n`` (n_bins, 3) synchronous average over ``revolutions`` revolutions (offset
    removed; bin 0 starts at the steady window's first sample, phase unknown); ``mean_n`` (3,)
    mean force over those revolutions; ``period_s`` revolution period; ``window`` the steady part
    in samples; ``tooth_peak_n`` (teeth,) mean per-tooth peak resultant and ``runout_ratio``;
    ``steady`` how many revolutions were kept and why the rest were dropped;
    ``revolution_means_n`` (revolutions, 3) each kept revolution's mean force (the bootstrap
    resamples them).
    """

    name: str
    conditions: RunConditions
    rate_hz: float
    waveform_n: np.ndarray
    mean_n: np.ndarray
    period_s: float
    revolutions: int
    window: tuple[int, int]
    offset_n: np.ndarray
    tooth_peak_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    runout_ratio: float = 0.0
    force_unit: str = "N"
    steady: str = ""
    revolution_means_n: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


def _revolution_means(seg: np.ndarray, rate_hz: float, period_s: float) -> np.ndarray:
    """Mean force of each whole revolution (refined period) of an offset-corrected segment."""
    stats = RevolutionStats(rate_hz, 60.0 / period_s, len(seg), seg.shape[1], noise=False)
    stats.add(seg, 0)
    return stats.sums / np.maximum(stats.counts, 1)[:, None]


#: Said under every coefficient table: what the intervals do and do not cover.
CI_NOTE = (
    "ci_low/ci_high: 95 % confidence intervals from the measurement noise only; model error "
    "(the force model against the real cut) is not in them, so the truth may fall just outside."
)


def default_bins(rate_hz: float, period_s: float) -> int:
    """Angle bins for a revolution average: one per sample, or (above 4096 samples per
    revolution) a whole number of samples per bin when the revolution holds a whole number of
    samples, so every bin sees the same sample positions. Fewer bins than that would alias the
    modes' ringing, whose frequencies lie far above the revolution's low harmonics."""
    spr = rate_hz * period_s
    whole = round(spr)
    if abs(spr - whole) < 1e-3 and whole >= 16:
        r = max(1, math.ceil(whole / 4096))
        while whole % r:
            r += 1
        return whole // r
    return int(min(4096, max(16, round(spr))))


def reduce_run(
    run: ForceRun, teeth: int, n_bins: int | None = None, tolerance: float = IDENTIFY_TOLERANCE,
    entry_s: float = 0.0) -> RunAverage:  # fmt: skip
    """Steady part, offset removal, synchronous average and tooth peaks of an in-memory run.

    ``tolerance``: revolutions whose mean stays within this fraction of the median count as
    steady (:func:`analysis.runs.steady.find_steady`); the default
    :data:`analysis.runs.steady.IDENTIFY_TOLERANCE` keeps a face mill's partial engagement out.
    ``entry_s``: the geometry's entry time (:func:`analysis.runs.steady.engaged_revolutions`)."""
    x = np.asarray(run.force_n, float)
    if x.ndim != 2 or x.shape[1] != 3:
        raise AnalysisError(f"run {run.name}: forces have shape {x.shape}: expected (n, 3) N")
    if not np.all(np.isfinite(x)):
        k = int(np.argmax(~np.isfinite(x).all(axis=1)))
        raise AnalysisError(
            f"run {run.name}: sample {k} holds {x[k].tolist()} N: forces must be finite numbers"
        )
    c = run.conditions
    try:
        try:
            part = find_steady(x, run.rate_hz, c.spindle_rpm, tolerance, engaged_after_s=entry_s)
        except NoAirError:
            # Cut from start to end (the operator trimmed the air): the record's own zero.
            part = find_steady(x, run.rate_hz, c.spindle_rpm, tolerance, True, np.zeros(3), entry_s)
    except AnalysisError as exc:
        raise type(exc)(f"run {run.name}: {exc}") from None  # keeps NoSteadyCutError
    seg = part.corrected(x[part.window], part.window.start, run.rate_hz)
    nb = n_bins or default_bins(run.rate_hz, part.period_s)
    avg = SyncAverager(run.rate_hz, part.period_s, nb)
    avg.add(seg, 0)
    wave = avg.mean()
    low = float(np.argmin(np.linalg.norm(wave, axis=1)) + 0.5) / nb * 2 * np.pi
    peaks = tooth_peaks(seg, run.rate_hz, part.period_s, teeth, phase_rad=low)
    return RunAverage(
        name=run.name,
        conditions=c,
        rate_hz=run.rate_hz,
        waveform_n=wave,
        mean_n=wave.mean(axis=0),
        period_s=part.period_s,
        revolutions=part.steady_revs,
        window=(part.window.start, part.window.stop),
        offset_n=part.offset_n,
        tooth_peak_n=peaks.mean_peak_n,
        runout_ratio=peaks.runout_ratio,
        force_unit=run.force_unit,
        steady=part.kept,
        revolution_means_n=_revolution_means(seg, run.rate_hz, part.period_s),
    )


def reduce_runs(
    runs: Sequence[ForceRun],
    teeth: int,
    n_bins: int | None = None,
    tolerance: float = IDENTIFY_TOLERANCE,
) -> tuple[list[RunAverage], list[tuple[str, str]]]:
    """:func:`reduce_run` over runs: (averages, rejected (name, reason)) — a run that cannot be
    reduced (no cutting, too short) is listed with the reason instead of stopping the others."""
    check_units(runs)
    avgs, rejected = [], []
    for r in runs:
        try:
            avgs.append(reduce_run(r, teeth, n_bins, tolerance))
        except AnalysisError as exc:
            rejected.append((r.name, str(exc)))
    return avgs, rejected


def synthetic_run(
    name: str,
    conditions: RunConditions,
    forces: Callable[[np.ndarray], np.ndarray],
    rate_hz: float,
    cut_s: float,
    *,
    air_s: float = 0.5,
    noise_frac: float = 0.02,
    dynamometer: DynamometerFilter | None = None,
    rng: np.random.Generator | None = None,
    offset_n: Sequence[float] = (0.0, 0.0, 0.0),
    drift_n_s: Sequence[float] = (0.0, 0.0, 0.0),
    phase_rad: float = 0.0,
    angle_rpm: float | None = None,
    oversample: int = 16,
) -> ForceRun:
    """A force record made from a model: air, ``cut_s`` of steady cutting, air.

    ``forces(theta_rad (m,)) -> (m, 3)`` N is the model at cutter angles (called in chunks of
    20 000 samples so memory stays bounded); the angle turns at ``angle_rpm`` (default the
    conditions' spindle rpm) from ``phase_rad``. The true force passes through ``dynamometer``
    (a DynamometerFilter: modes), computed ``oversample`` times faster than the record and every
    so many-th sample kept (the dynamometer answers to the force between samples: an insert's
    edge enters the workpiece within a sample), then an offset with linear drift and white noise
    of ``noise_frac`` x the peak resultant force are added.
    """
    rng = rng or np.random.default_rng(0)
    rpm = conditions.spindle_rpm if angle_rpm is None else angle_rpm
    n_air, n_cut = int(air_s * rate_hz), int(cut_s * rate_hz)
    n = 2 * n_air + n_cut
    t = np.arange(n) / rate_hz
    k = max(1, int(oversample)) if dynamometer is not None else 1
    theta = phase_rad + 2 * np.pi * rpm / 60.0 * np.arange(n * k) / (rate_hz * k)
    f = np.zeros((n * k, 3))
    for i in range(n_air * k, (n_air + n_cut) * k, 20_000):
        j = min(i + 20_000, (n_air + n_cut) * k)
        f[i:j] = forces(theta[i:j])
    if dynamometer is not None:
        if k > 1:
            dynamometer = DynamometerFilter(dynamometer.modes, dynamometer.rate_hz * k,
                                            dynamometer.crosstalk)  # fmt: skip
        f = dynamometer.apply(f)[::k]
    peak = float(np.linalg.norm(f, axis=1).max())
    f += np.asarray(offset_n, float) + t[:, None] * np.asarray(drift_n_s, float)
    f += rng.normal(scale=noise_frac * peak, size=f.shape)
    return ForceRun(name, f, rate_hz, conditions)


def validation_line(exc: Exception) -> str:
    """A pydantic range check's failure as one line, field by field (``Ktc_n_mm2 = -723.5:
    Input should be greater than 0``); no pydantic dump reaches the user."""
    errors = getattr(exc, "errors", None)
    if not callable(errors):
        return str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    parts = []
    for e in errors():
        loc = ".".join(str(x) for x in e.get("loc", ())) or "value"
        val = e.get("input")
        shown = f"{val:.6g}" if isinstance(val, float) else repr(val)
        parts.append(f"{loc} = {shown}: {e.get('msg', 'out of range')}")
    return "; ".join(parts)


def too_few_runs(averages: Sequence[RunAverage], varied: str, label: str, why: str) -> str | None:
    """None when there are >= 3 runs over >= 2 values of ``conditions.<varied>``, else the
    reason (``label``: what the values are, e.g. 'depth(s)'; ``why``: the model's need)."""
    values = {round(getattr(a.conditions, varied), 9) for a in averages}
    if len(averages) >= 3 and len(values) >= 2:
        return None
    return f"too few runs for the unknowns: {len(averages)} run(s) at {len(values)} {label}; {why}"


def check_units(items: Sequence[ForceRun | RunAverage]) -> None:
    units = {r.force_unit for r in items}
    if len(units) > 1 or (units and units != {"N"}):
        listing = ", ".join(f"{r.name} in {r.force_unit}" for r in items)
        raise AnalysisError(
            f"runs mix force units or are not in newtons ({listing}): convert all to N first"
        )


def axis_order(
    channel_names: Sequence[str], dynamometer: Dynamometer | None = None
) -> list[int]:
    """Column of X, Y, Z among a run's channels (names from the rig config, else Fx, Fy, Fz)."""
    names = [n.lower() for n in channel_names]
    order = [-1, -1, -1]
    if dynamometer is not None:
        for ch in dynamometer.channels:
            if ch.name.lower() in names:
                order["xyz".index(ch.axis)] = names.index(ch.name.lower())
    for ax, default in enumerate(("fx", "fy", "fz")):
        if order[ax] < 0 and default in names:
            order[ax] = names.index(default)
    if min(order) < 0:
        if len(names) == 3:
            return [0, 1, 2]
        raise AnalysisError(f"cannot tell X, Y, Z among channels {list(channel_names)}")
    return order


#: Samples read at once when a run file is streamed (24 MB of forces; 2^18-2^20 ran equally fast
#: here, smaller chunks pay the per-read overhead).
CHUNK_SAMPLES = 1 << 20
#: Samples of the steady part that refine the revolution period and give the tooth peaks.
PROBE_SAMPLES = 1 << 20


def iter_run_chunks(
    path: str | Path, chunk_samples: int = CHUNK_SAMPLES, start: int = 0, stop: int | None = None
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield (device sample indices (m,), force (m, 3) N in X, Y, Z) of a run file in chunks.

    Reads through :func:`analysis.runs.file.iter_forces` (the numbers of ``load_run`` time
    windows, the file opened once), so memory is bounded by the chunk.
    """
    from analysis.runs import load_run
    from analysis.runs.file import iter_forces

    meta = load_run(path, samples=False)
    if meta.calibration is None:
        raise AnalysisError(f"{path}: the run has no calibration: forces in N are unknown")
    end = meta.samples_acquired if stop is None else min(stop, meta.samples_acquired)
    order = axis_order(meta.channel_names)
    same = order == [0, 1, 2] and len(meta.channel_names) == 3
    windows = ((a, min(a + chunk_samples, end)) for a in range(start, end, chunk_samples))
    for idx, force in iter_forces(path, windows, meta):
        # The loader's own array: reordered (a copy) only when the channels are not X, Y, Z.
        yield idx, force if same else force[:, order]


def reduce_run_file(
    path: str | Path, teeth: int, conditions: RunConditions | None = None,
    n_bins: int | None = None, chunk_samples: int = CHUNK_SAMPLES, progress: Progress | None = None,
    tolerance: float = IDENTIFY_TOLERANCE, entry_s: float = 0.0) -> RunAverage:  # fmt: skip
    """:func:`reduce_run` streamed from an HDF5 run file in two passes over chunks.

    Pass 1 gathers per-revolution statistics (steady part, offset, drift); the revolution period
    is refined on the steady part's first :data:`PROBE_SAMPLES` (at least 4 revolutions); pass 2
    averages the steady part synchronously. Memory: the chunk and the probe (and the window's
    arrays while it is read and calibrated) plus O(revolutions + bins). ``tolerance``: the
    steady window, as :func:`reduce_run`; ``entry_s`` likewise.

    One BLAS thread: its only BLAS call, the calibration's (m, 3) x (3, 3) product, is no faster
    on two, and OpenBLAS's idle threads spin, taking the core a second reduction (a dask task
    beside this one) would use: 0.62 s wall and 1.21 s CPU per 10^7 samples with them, 0.65 and
    0.65 without.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _reduce_run_file(path, teeth, conditions, n_bins, chunk_samples, progress,
                                tolerance, entry_s)  # fmt: skip


def _reduce_run_file(
    path: str | Path, teeth: int, conditions: RunConditions | None, n_bins: int | None,
    chunk_samples: int, progress: Progress | None, tolerance: float, entry_s: float = 0.0,
) -> RunAverage:  # fmt: skip
    from analysis.runs import load_run

    meta = load_run(path, samples=False)
    name = Path(str(path)).stem
    c = conditions or RunConditions.from_mapping(meta.conditions, str(path))
    rate, n = meta.rate_hz, meta.samples_acquired
    del meta
    stats = RevolutionStats(rate, c.spindle_rpm, n, 3)
    for idx, f in iter_run_chunks(path, chunk_samples):
        bad = ~np.isfinite(f).all(axis=1)
        if bad.any():  # a gap the writer could not fill, a corrupt file: say where, do not guess
            k = int(np.argmax(bad))
            raise AnalysisError(
                f"{path}: sample {int(idx[k])} (t = {idx[k] / rate:.6g} s) holds "
                f"{f[k].tolist()} N: forces must be finite numbers"
            )
        stats.add(f, idx)
        if progress:
            progress(len(idx))
    try:
        try:
            part = steady_from_stats(stats, rate, c.spindle_rpm, tolerance, None, entry_s)
        except NoAirError:
            part = steady_from_stats(stats, rate, c.spindle_rpm, tolerance, np.zeros(3), entry_s)
    except AnalysisError as exc:
        raise type(exc)(f"run {name}: {exc}") from None
    lo = part.window.start
    # The period refinement and the tooth peaks look at the steady part's first 2^20 samples (at
    # least 4 revolutions), whatever the chunk size.
    n_probe = min(part.window.stop - lo, max(PROBE_SAMPLES, int(4 * stats.spr)))
    probe = next(iter_run_chunks(path, n_probe, lo, lo + n_probe))
    part = part.with_period(
        refine_period(
            np.linalg.norm(probe[1] - probe[1].mean(axis=0), axis=1), rate, part.period_s
        ),
        rate,
    )
    nb = n_bins or default_bins(rate, part.period_s)
    avg = SyncAverager(rate, part.period_s, nb)
    revs = RevolutionStats(rate, 60.0 / part.period_s, part.window.stop - lo, 3, noise=False)
    for idx, f in iter_run_chunks(path, chunk_samples, part.window.start, part.window.stop):
        f -= part.offset_n
        if np.any(part.drift_n_s):
            f -= ((idx - lo) / rate)[:, None] * part.drift_n_s
        avg.add(f, idx - lo)
        revs.add(f, idx - lo)
        if progress:
            progress(len(idx))
    wave = avg.mean()
    # Tooth peaks from the in-memory probe (up to 2^20 samples of the steady part).
    low = (float(np.argmin(np.linalg.norm(wave, axis=1))) + 0.5) / nb * 2 * np.pi
    t = (probe[0] - lo) / rate
    seg = probe[1] - part.offset_n - t[:, None] * part.drift_n_s
    peaks = tooth_peaks(seg, rate, part.period_s, teeth, phase_rad=low)
    return RunAverage(
        name=name, conditions=c, rate_hz=rate, waveform_n=wave, mean_n=wave.mean(axis=0),
        period_s=part.period_s, revolutions=part.steady_revs,
        window=(part.window.start, part.window.stop), offset_n=part.offset_n,
        tooth_peak_n=peaks.mean_peak_n, runout_ratio=peaks.runout_ratio, steady=part.kept,
        revolution_means_n=revs.sums / np.maximum(revs.counts, 1)[:, None],
    )  # fmt: skip
