"""Identify the seed 003 face-milling coefficients (P_T, K_T, P_R, K_R, P_A, K_A) from runs.

Seed 003's method: one feed per tooth, the axial depth of cut varied (0.5 -> 3 mm); ploughing
grows with the engaged edge length l, chip removal with the chip area S, and a least-squares fit
over the runs separates them. Here each run is first reduced (``analysis.runs.steady``) to its
synchronous revolution average with the dynamometer offset removed; the model's regressors
(``analysis.forces.facemill.facemill_design``: force per unit coefficient over a revolution) are
passed through the dynamometer's modes (``analysis.modal.filter``) so the ringing after each insert
entry does not bias the fit; the unknown angular phase of each run is found by a circular
cross-correlation search refined to a fraction of a bin; then one linear least-squares fit over
all runs, channels and angle bins gives the six parameters with standard errors, confidence
intervals, R^2 and residuals. K_R and K_A are ratios (seed 003 prints K_R in N/mm^2; eq 4 makes
it a ratio) whose errors follow by the delta method.

Entry points: ``fit_facemill(averages, tool, dynamometer)`` on reduced runs, ``fit_facemill_runs``
on in-memory ``ForceRun`` records, ``synthetic_facemill_run`` to make records from known
coefficients (tests, bench, demos).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Unpack

import numpy as np

from analysis.config import Dynamometer, EndMill, FaceMill, FaceMillCoefficients
from analysis.errors import AnalysisError
from analysis.forces.facemill import (
    PARAMETERS,
    FaceMillCut,
    coefficients_from_vector,
    facemill_design,
    facemill_forces,
)
from analysis.forces.models import FACEMILL
from analysis.identify._common import (
    ForceRun,
    RunAverage,
    RunConditions,
    axis_order,
    check_units,
    reduce_run,
    reduce_run_file,
    synthetic_run,
    too_few_runs,
    validation_line,
)
from analysis.identify._linear import (
    LinearFit,
    RunBlock,
    bootstrap_intervals,
    linear_fit,
    ratio_with_error,
)
from analysis.identify._types import StatsRow, SyntheticOptions, with_rejected
from analysis.identify.adequacy import Adequacy, runs_adequacy
from analysis.identify.facemill_split import Split, design_split
from analysis.modal import DynamometerFilter
from analysis.runs import IDENTIFY_TOLERANCE

__all__ = [
    "FaceMillFit",
    "ForceRun",
    "LinearFit",
    "RunAverage",
    "RunConditions",
    "axis_order",
    "fit_facemill",
    "fit_facemill_runs",
    "predicted_waveform",
    "reduce_run",
    "reduce_run_file",
    "synthetic_facemill_run",
]


def _bin_offsets(avg: RunAverage) -> np.ndarray:
    """Where a bin's samples sit, in bins from angle 2 pi k / n (see SyncAverager for the edges).

    With a whole number r of samples per bin (and per revolution) every revolution puts its
    samples at the same places, k + i / r; otherwise the samples drift through the bin over
    the revolutions and it holds their average over its width.
    """
    r = avg.rate_hz * avg.period_s / len(avg.waveform_n)
    if abs(r - round(r)) < 1e-3 and round(r) >= 1:
        return np.arange(round(r)) / round(r)
    # The bin's edges sit half a sample early (see analysis.runs.steady.SyncAverager).
    return (np.arange(4) + 0.5) / 4 - 0.5 / r


@dataclass(frozen=True)
class FaceMillFit:
    """Result of :func:`fit_facemill`.

    ``success``/``message``: False with the reason when the runs cannot determine the model.
    ``coefficients``: the identified FaceMillCoefficients (K_R, K_A ratios). ``fit``: the linear
    fit of :data:`analysis.forces.facemill.PARAMETERS` (values, std_errors, ci, r_squared, ...).
    ``summary``: per coefficient name (K_T_n_mm2, K_R, P_T_n_mm, P_R_n_mm, K_A, P_A_n_mm) its
    value, std_error, ci_low, ci_high and the bootstrap's boot_ci_low, boot_ci_high (runs and
    revolutions resampled); ``adequacy`` whether the data support the ploughing coefficients
    (:mod:`analysis.identify.adequacy`); ``split`` per coefficient whether the design splits its
    cutting and edge terms, and its status (:mod:`analysis.identify.facemill_split`).
    ``phases_rad`` (runs,) angle of bin 0 of each run;
    ``residuals_n`` per run (n_bins, 3) N; ``runs`` names used; ``rejected`` (name, reason).
    """

    success: bool
    message: str
    coefficients: FaceMillCoefficients | None = None
    fit: LinearFit | None = None
    summary: dict[str, StatsRow] | None = None
    phases_rad: tuple[float, ...] = ()
    residuals_n: tuple[np.ndarray, ...] = ()
    runs: tuple[str, ...] = ()
    rejected: tuple[tuple[str, str], ...] = ()
    adequacy: Adequacy | None = None
    split: Split | None = None


#: The summary's coefficients from the fitted vector (PARAMETERS order: P_T, K_T, P_R, K_R K_T,
#: P_A, K_A K_T): K_R and K_A are ratios.
SUMMARY = ("K_T_n_mm2", "K_R", "P_T_n_mm", "P_R_n_mm", "K_A", "P_A_n_mm")


def _summary_values(p: np.ndarray) -> np.ndarray:
    return np.array([p[1], p[3] / p[1], p[0], p[2], p[5] / p[1], p[4]])


def _cut(c: RunConditions) -> FaceMillCut:
    return FACEMILL.cut(None, c)


def _filter_for(
    dynamometer: Dynamometer | DynamometerFilter | None, rate_hz: float
) -> DynamometerFilter | None:
    if dynamometer is None:
        return None
    if isinstance(dynamometer, DynamometerFilter):
        if abs(dynamometer.rate_hz - rate_hz) > 1e-9 * rate_hz:
            return DynamometerFilter(dynamometer.modes, rate_hz, dynamometer.crosstalk)
        return dynamometer
    if isinstance(dynamometer, Dynamometer):
        # Run files hold forces with the cross-talk already inverted by the calibration.
        return DynamometerFilter.from_config(
            dynamometer, rate_hz, crosstalk=False, drop_above_nyquist=True
        )
    raise AnalysisError(
        f"dynamometer: expected a Dynamometer config or filter, got {dynamometer!r}"
    )


#: The model is evaluated this many times finer than the bins and passed through the modes there,
#: then sampled where the data's samples sit: the dynamometer answers to the force between
#: samples (an insert's edge enters the workpiece over a fraction of a sample), which a filter run
#: at the sample rate on point samples of the model does not see (issue 33: on data from the
#: model through a 4x oversampled dynamometer that put P_T -8 %, P_R -13 %, K_T +4 % off).
FINE_PER_BIN = 64


def _fine_regressors(
    avg: RunAverage, tool: FaceMill, filt: DynamometerFilter | None, phase: float
) -> tuple[np.ndarray, np.ndarray]:
    """The model's regressors on the fine grid (n_bins * FINE_PER_BIN, 3, 6) from ``phase``,
    through the modes (run at the fine grid's rate: the continuous response to within a fine
    step), and the fine rows (n_bins, samples per bin) where each bin's samples sit."""
    n = len(avg.waveform_n)
    m = n * FINE_PER_BIN
    theta = phase + 2 * np.pi * np.arange(m) / m
    fine = facemill_design(theta, tool, _cut(avg.conditions))
    if filt is not None:
        fast = DynamometerFilter(filt.modes, m / avg.period_s, filt.crosstalk)
        fine = np.moveaxis(fast.periodic_response(np.moveaxis(fine, 1, 2), avg.period_s), 2, 1)
    offs = np.rint(_bin_offsets(avg) * FINE_PER_BIN).astype(np.int64)
    rows = np.arange(n)[:, None] * FINE_PER_BIN + offs[None, :]
    return fine, rows


def _regressors(
    avg: RunAverage, tool: FaceMill, filt: DynamometerFilter | None, phase: float
) -> np.ndarray:
    """Mode-filtered regressors at the bins' samples (n_bins, 3, 6), bin 0 starting at
    ``phase``."""
    fine, rows = _fine_regressors(avg, tool, filt, phase)
    out: np.ndarray = fine[rows % len(fine)].mean(axis=1)
    return out


def _phase(avg: RunAverage, tool: FaceMill, filt: DynamometerFilter | None) -> float:
    """Angle of bin 0 that best explains the run's waveform (least-squares residual)."""
    y = avg.waveform_n
    n = len(y)
    # The filtered model on the fine grid, once: a phase candidate is an index shift of it (the
    # steady response to a periodic force shifts with the force).
    fine, rows = _fine_regressors(avg, tool, filt, 0.0)
    X = fine[rows].mean(axis=1)  # (n, 3, 6)
    xtx = np.einsum("bck,bcl->kl", X, X)
    if np.linalg.matrix_rank(xtx) < 1:
        raise AnalysisError(f"run {avg.name}: the model predicts no cutting for its conditions")
    inv = np.linalg.pinv(xtx)
    # r[s, k] = sum_b,c X[b + s, c, k] y[b, c]: model shifted by s bins against the data.
    fx = np.fft.rfft(X, axis=0)
    fy = np.fft.rfft(y, axis=0)
    r = np.fft.irfft(np.einsum("fck,fc->fk", fx, np.conj(fy)), n=n, axis=0)
    gain = np.einsum("sk,kl,sl->s", r, inv, r)
    s = int(np.argmax(gain))
    # Data bin b matches model bin b + s, i.e. bin 0 of the data starts at 2 pi s / n.
    base = 2 * np.pi * s / n

    yy = y.reshape(-1)
    m0 = s * FINE_PER_BIN

    def rss(m: int) -> float:
        Xd = fine[(m0 + m + rows) % len(fine)].mean(axis=1).reshape(-1, 6)
        # Normal equations: the 6 x 6 system is well conditioned here and far cheaper than SVD.
        xty = Xd.T @ yy
        p = np.linalg.lstsq(Xd.T @ Xd, xty, rcond=None)[0]
        return float(yy @ yy - p @ xty)

    # Point samples make the residual step-wise in the phase (an entry jump moves from one sample
    # to the next), so a derivative-free bracket search can stall on a step: use nested grids.
    best = 0
    for spacing in (FINE_PER_BIN // 8, 1):
        grid = best + spacing * np.arange(-8, 9)
        best = int(grid[int(np.argmin([rss(int(g)) for g in grid]))])
    return float(base + 2 * np.pi * best / (n * FINE_PER_BIN))


def fit_facemill(
    averages: Sequence[RunAverage],
    tool: FaceMill | EndMill,
    dynamometer: Dynamometer | DynamometerFilter | None = None,
    confidence: float = 0.95,
) -> FaceMillFit:
    """Fit the face-mill model to reduced runs (see module docstring).

    Needs at least 3 runs at 2 or more depths of cut (ploughing scales with l, chip removal with
    S; one depth cannot tell them apart well). Returns ``success=False`` with the reason when
    the runs cannot determine the model; raises :class:`AnalysisError` for input that is wrong
    (mixed units, a tool the model cannot describe).
    """
    if not FACEMILL.describes(tool):
        raise AnalysisError(
            f"tool of kind {getattr(tool, 'kind', type(tool).__name__)!r}: the seed 003 model "
            "describes face mills only (use analysis.identify.endmill for end mills)"
        )
    check_units(averages)
    names = tuple(a.name for a in averages)
    few = too_few_runs(
        averages, "depth_mm", "depth(s)", "the face-mill fit needs >= 3 runs at >= 2 depths of "
        "cut to separate ploughing (~ l) from chip removal (~ S)",
    )  # fmt: skip
    if few:
        return FaceMillFit(False, few, runs=names)
    Xs, ys, phases, blocks = [], [], [], []
    filters: dict[float, DynamometerFilter | None] = {}
    for a in averages:
        if a.rate_hz not in filters:
            filters[a.rate_hz] = _filter_for(dynamometer, a.rate_hz)

    def regressors(a: RunAverage) -> tuple[float, np.ndarray]:
        ph = _phase(a, tool, filters[a.rate_hz])
        return ph, _regressors(a, tool, filters[a.rate_hz], ph)

    # Each run's phase search is its own; numpy releases the GIL in most of it, so threads
    # share the cores (a 30-run fit: 3.1 -> 2.1 s on 2).
    with ThreadPoolExecutor(max_workers=max(1, min(len(averages), os.cpu_count() or 1))) as pool:
        prepared = list(pool.map(regressors, averages))
    for a, (ph, Xr) in zip(averages, prepared):
        phases.append(ph)
        blocks.append(RunBlock.of(Xr, a.waveform_n, a.revolution_means_n))
        Xs.append(Xr.reshape(-1, 6))
        ys.append(a.waveform_n.reshape(-1))
    X, y = np.vstack(Xs), np.concatenate(ys)
    try:
        fit, resid = linear_fit(X, y, PARAMETERS, confidence)
    except AnalysisError as exc:
        return FaceMillFit(False, str(exc), runs=names)
    p = fit.values
    if p[1] <= 0:
        return FaceMillFit(
            False, f"fitted K_T = {p[1]:.4g} N/mm^2 is not positive: the runs do not show chip "
            "removal growing with the chip area", fit=fit, runs=names,
        )  # fmt: skip
    lo, hi = bootstrap_intervals(blocks, confidence=confidence)
    fit = replace(fit, boot_low=lo, boot_high=hi)
    blo, bhi = bootstrap_intervals(blocks, _summary_values, confidence)
    rows = (_row(fit, 1), _ratio_row(fit, 3, 1), _row(fit, 0), _row(fit, 2),
            _ratio_row(fit, 5, 1), _row(fit, 4))  # fmt: skip
    summary: dict[str, StatsRow] = {
        name: {**row, "boot_ci_low": float(bl), "boot_ci_high": float(bh)}
        for name, row, bl, bh in zip(SUMMARY, rows, blo, bhi)
    }
    adequacy, split = _identifiable(X, averages, tool, summary)
    try:
        coef = coefficients_from_vector(p)
    except Exception as exc:  # pydantic range check: report, do not crash
        why = validation_line(exc)
        return FaceMillFit(False, f"fitted coefficients out of range: {why}", fit=fit,
                           summary=summary, runs=names, split=split)  # fmt: skip
    n_per = [len(a.waveform_n) * 3 for a in averages]
    res_runs = tuple(r.reshape(-1, 3) for r in np.split(resid, np.cumsum(n_per)[:-1]))
    msg = f"fitted {len(averages)} runs ({len(y)} points), R^2 = {fit.r_squared:.5f}"
    if not adequacy.edge_identified:
        msg += f"; ploughing coefficients P_T, P_R, P_A not identified: {adequacy.reason}"
    return FaceMillFit(True, msg + split.clause(), coef, fit, summary, tuple(phases), res_runs,
                       names, adequacy=adequacy, split=split)  # fmt: skip


def _identifiable(
    X: np.ndarray, averages: Sequence[RunAverage], tool: FaceMill, summary: dict[str, StatsRow]
) -> tuple[Adequacy, Split]:
    """The adequacy check (edge forces against a size effect) and the design's split of cutting
    and edge terms; each summary row gets its ``identified`` and ``status``."""
    adequacy = runs_adequacy(averages)
    split = design_split(X, [a.conditions.fz_mm for a in averages], adequacy.edge_identified,
                         float(tool.lead_angle_deg))  # fmt: skip
    for name, row in summary.items():
        row.update(identified=split.identified[name], status=split.status[name])
    return adequacy, split


def _row(fit: LinearFit, i: int) -> dict[str, float]:
    return {
        "value": float(fit.values[i]),
        "std_error": float(fit.std_errors[i]),
        "ci_low": float(fit.ci_low[i]),
        "ci_high": float(fit.ci_high[i]),
    }


def _ratio_row(fit: LinearFit, num: int, den: int) -> dict[str, float]:
    v, se, lo, hi = ratio_with_error(fit, num, den)
    return {"value": v, "std_error": se, "ci_low": lo, "ci_high": hi}


def entry_s(tool: object, c: RunConditions) -> float:
    """Seconds from a face mill's first touch of a block it is fed into along X' to its arc
    being wholly over the block (the geometry's bound on the entry; 0 for a tool without a lead
    angle, i.e. not a face mill, or conditions that do not place the block). The first touch is
    the top of the cut's edge (depth x tan(lead) beyond the radius) on the ray nearest the
    feed's line inside the block's width; the arc is in once its ends, on the block's far side
    across the feed, are past the block's front. At 1 mm/s (0.1 mm/tooth, one insert, 600 rpm)
    a 125 mm cutter 20 mm off a 50 mm block's centre takes 19.3-19.9 s (0.5-3 mm deep), centred
    5.4-6.0 s: revolutions in that time can lie within 2 % of the steady level, not steady."""
    if not FACEMILL.describes(tool):  # only a face mill has a lead angle
        return 0.0
    lead = tool.lead_angle_deg
    v_mm_s = c.fz_mm * tool.inserts * abs(c.spindle_rpm) / 60.0
    if not v_mm_s > 0 or not np.isfinite(c.width_mm) or c.width_mm <= 0:
        return 0.0
    radius = float(tool.diameter_mm) / 2
    reach = radius + max(c.depth_mm, 0.0) * float(np.tan(np.radians(lead)))
    y = np.array([-0.5, 0.5]) * c.width_mm + c.center_offset_mm
    near = 0.0 if y[0] <= 0.0 <= y[1] else float(np.abs(y).min())
    far = min(float(np.abs(y).max()), radius)
    front = np.sqrt(max(reach**2 - near**2, 0.0))
    return float(max(front - np.sqrt(radius**2 - far**2), 0.0) / v_mm_s)


def tool_entry_s(name: str, c: RunConditions, tools_path: str | Path | None = None) -> float:
    """:func:`entry_s` of a catalogued tool (the user's ``tools_path`` first); 0 without one."""
    from analysis.config import get_tool, user_catalogs

    if not name:
        return 0.0
    with user_catalogs(tools=tools_path):
        return entry_s(get_tool(name), c)


def fit_facemill_runs(
    runs: Sequence[ForceRun],
    tool: FaceMill,
    dynamometer: Dynamometer | DynamometerFilter | None = None,
    n_bins: int | None = None,
    tolerance: float = IDENTIFY_TOLERANCE,
) -> FaceMillFit:
    """Reduce in-memory runs (steady part within ``tolerance``, offset, averaging) and fit. Runs
    that cannot be reduced (no cutting, too short) are listed in ``rejected`` with the reason."""
    if not FACEMILL.describes(tool):
        return fit_facemill([], tool)  # raises: names the tool kind
    check_units(runs)
    avgs, rejected = [], []
    for r in runs:  # as reduce_runs, each with its entry time
        try:
            avgs.append(reduce_run(r, tool.inserts, n_bins, tolerance, entry_s(tool, r.conditions)))
        except AnalysisError as exc:
            rejected.append((r.name, str(exc)))
    return with_rejected(fit_facemill(avgs, tool, dynamometer), rejected)


def predicted_waveform(
    avg: RunAverage, tool: FaceMill, coef: FaceMillCoefficients,
    dynamometer: Dynamometer | DynamometerFilter | None = None, phase_rad: float = 0.0,
) -> np.ndarray:  # fmt: skip
    """The model's revolution waveform (n_bins, 3) N for a reduced run's conditions."""
    from analysis.forces.facemill import coefficient_vector

    X = _regressors(avg, tool, _filter_for(dynamometer, avg.rate_hz), phase_rad)
    out: np.ndarray = X @ coefficient_vector(coef)
    return out


def synthetic_facemill_run(
    name: str,
    tool: FaceMill,
    coef: FaceMillCoefficients,
    conditions: RunConditions,
    rate_hz: float = 20_000.0,
    cut_s: float = 3.0,
    **record: Unpack[SyntheticOptions],
) -> ForceRun:
    """A force record made from the model: air, ``cut_s`` of steady cutting, air.

    ``record``: air_s, noise_frac, dynamometer (DynamometerFilter), rng, offset_n, drift_n_s,
    phase_rad, as :func:`analysis.identify._common.synthetic_run` (modes, offset with drift, noise).
    """
    cut = _cut(conditions)
    return synthetic_run(
        name, conditions, lambda th: facemill_forces(th, tool, coef, cut), rate_hz, cut_s, **record
    )
