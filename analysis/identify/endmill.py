"""Identify end-mill cutting and edge coefficients by the average-force method (Altintas).

The mean force over whole revolutions is linear in the feed per tooth: F_mean = F_c f_z + F_e.
For a flat end mill the closed forms (``analysis.forces.endmill.mean_force_design``, valid for
slotting and any immersion, up or down milling, any helix) give the mean X, Y, Z force per unit
value of each of K_tc, K_rc, K_ac, K_te, K_re, K_ae; ball and bull-nose end mills use the same
relation with the model averaged numerically over a revolution. Stacking every run's three mean
forces gives one linear least-squares problem for the six coefficients, with standard errors,
confidence intervals, R^2 and residuals. The mean is untouched by the dynamometer's modes (their
static gain is one), so no modal correction is needed.

Runs at two or more feeds per tooth are needed (cutting vs edge); at least three runs so that
the fit has degrees of freedom left (3 equations per run, 6 unknowns).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Unpack

import numpy as np

from analysis.config import EndMill, EndMillCoefficients, FaceMill
from analysis.errors import AnalysisError
from analysis.forces.endmill import (
    PARAMETERS,
    EndMillCut,
    coefficients_from_vector,
    endmill_forces,
    mean_force_design,
)
from analysis.forces.models import ENDMILL
from analysis.identify._common import (
    ForceRun,
    RunAverage,
    RunConditions,
    check_units,
    reduce_runs,
    synthetic_run,
    too_few_runs,
    validation_line,
)
from analysis.identify._linear import LinearFit, RunBlock, bootstrap_intervals, linear_fit
from analysis.identify._types import SyntheticOptions, with_rejected
from analysis.identify.adequacy import Adequacy, runs_adequacy
from analysis.runs import IDENTIFY_TOLERANCE

__all__ = ["EndMillFit", "fit_endmill", "fit_endmill_runs", "synthetic_endmill_run"]


def _cut(tool: EndMill, c: RunConditions) -> EndMillCut:
    return ENDMILL.cut(tool, c)


@dataclass(frozen=True)
class EndMillFit:
    """Result of :func:`fit_endmill`: ``success``/``message``; ``coefficients``
    (EndMillCoefficients); ``fit`` (LinearFit over :data:`analysis.forces.endmill.PARAMETERS`);
    ``residuals_n`` (runs, 3) N mean-force residuals; ``runs``; ``rejected`` (name, reason);
    ``adequacy`` whether the data support the edge coefficients (linear model against a size
    effect, :mod:`analysis.identify.adequacy`)."""

    success: bool
    message: str
    coefficients: EndMillCoefficients | None = None
    fit: LinearFit | None = None
    residuals_n: np.ndarray | None = None
    runs: tuple[str, ...] = ()
    rejected: tuple[tuple[str, str], ...] = ()
    adequacy: Adequacy | None = None


def fit_endmill(
    averages: Sequence[RunAverage], tool: EndMill | FaceMill, confidence: float = 0.95
) -> EndMillFit:
    """Average-force fit over reduced runs (see module docstring)."""
    if not ENDMILL.describes(tool):
        raise AnalysisError(
            f"tool of kind {getattr(tool, 'kind', type(tool).__name__)!r}: the average-force "
            "method here describes flat, ball and bull end mills (face mills: fit_facemill)"
        )
    check_units(averages)
    names = tuple(a.name for a in averages)
    few = too_few_runs(
        averages, "fz_mm", "feed(s) per tooth", "the average-force method needs >= 3 runs at "
        ">= 2 feeds per tooth (3 mean forces per run, 6 coefficients; cutting and edge parts "
        "separate by feed)",
    )  # fmt: skip
    if few:
        return EndMillFit(False, few, runs=names)
    Xr = [mean_force_design(tool, _cut(tool, a.conditions)) for a in averages]
    X = np.concatenate(Xr)
    y = np.concatenate([a.mean_n for a in averages])
    try:
        fit, resid = linear_fit(X, y, PARAMETERS, confidence)
    except AnalysisError as exc:
        return EndMillFit(False, str(exc), runs=names)
    blocks = [RunBlock.of(x[None], a.mean_n[None], a.revolution_means_n)
              for x, a in zip(Xr, averages)]  # fmt: skip
    lo, hi = bootstrap_intervals(blocks, confidence=confidence)
    fit = replace(fit, boot_low=lo, boot_high=hi)
    adequacy = runs_adequacy(averages)
    try:
        coef = coefficients_from_vector(fit.values)
    except Exception as exc:  # pydantic range check (e.g. a negative K_tc): report it
        return EndMillFit(False, f"fitted coefficients out of range: {validation_line(exc)}",
                          fit=fit, runs=names)  # fmt: skip
    msg = f"fitted {len(averages)} runs ({len(y)} mean forces), R^2 = {fit.r_squared:.5f}"
    if not adequacy.edge_identified:
        msg += f"; edge coefficients Kte, Kre, Kae not identified: {adequacy.reason}"
    return EndMillFit(True, msg, coef, fit, resid.reshape(-1, 3), names, adequacy=adequacy)


def fit_endmill_runs(
    runs: Sequence[ForceRun],
    tool: EndMill,
    n_bins: int | None = None,
    tolerance: float = IDENTIFY_TOLERANCE,
) -> EndMillFit:
    """Reduce in-memory runs and fit; runs without steady cutting go to ``rejected``."""
    if not ENDMILL.describes(tool):
        return fit_endmill([], tool)  # raises: names the tool kind
    avgs, rejected = reduce_runs(runs, tool.flutes, n_bins, tolerance)
    return with_rejected(fit_endmill(avgs, tool), rejected)


def synthetic_endmill_run(
    name: str,
    tool: EndMill,
    coef: EndMillCoefficients,
    conditions: RunConditions,
    rate_hz: float = 20_000.0,
    cut_s: float = 2.0,
    n_discs: int = 16,
    **record: Unpack[SyntheticOptions],
) -> ForceRun:
    """A record made from the end-mill model (air, steady cut, air) with modes, offset, noise;
    ``record`` as :func:`analysis.identify._common.synthetic_run`."""
    cut = _cut(tool, conditions)
    return synthetic_run(
        name, conditions, lambda phi: endmill_forces(phi, tool, coef, cut, n_discs), rate_hz,
        cut_s, angle_rpm=abs(conditions.spindle_rpm), **record,
    )  # fmt: skip
