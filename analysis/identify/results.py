"""The JSON-able result of :func:`analysis.identify.fit_files` (`cutlab analyze forces`), typed
(what the CLI prints and the catalogue caches, key by key), and its parts made after the fit: the
end mill's trust figures (:func:`add_trust`) and the validation (:func:`add_validation`)."""

from __future__ import annotations

from pathlib import Path
from typing import NotRequired, TypedDict

import numpy as np

from analysis.config import Dynamometer, EndMill, EndMillCoefficients, FaceMillCoefficients
from analysis.forces.models import ENDMILL, FACEMILL, ModelTool
from analysis.identify._common import RunAverage
from analysis.identify._linear import LinearFit
from analysis.identify._types import StatsRow
from analysis.identify.adequacy import Adequacy, AdequacyDict
from analysis.identify.axes import AxesCandidate
from analysis.identify.facemill_split import SplitDict
from analysis.identify.trust import (
    Influence,
    RunResidual,
    by_direction,
    influence,
    per_run_residuals,
    statuses,
)
from analysis.identify.validate import (
    ComparisonRow,
    compare_runs,
    plot_comparison,
    plot_waveforms,
)

__all__ = ["EDGE_REASON", "SHORT_NAMES", "AdequacyResult", "AxesPick", "ForcesResult", "LimitRow",
           "RejectedRun", "Validation", "add_trust", "add_validation"]  # fmt: skip

#: End-mill coefficients by their short names (the JSON result's ``Ktc`` ... ``Kae``) and unit.
SHORT_NAMES = {"Ktc": ("Ktc_n_mm2", "N/mm^2"), "Krc": ("Krc_n_mm2", "N/mm^2"),
               "Kac": ("Kac_n_mm2", "N/mm^2"), "Kte": ("Kte_n_mm", "N/mm"),
               "Kre": ("Kre_n_mm", "N/mm"), "Kae": ("Kae_n_mm", "N/mm")}  # fmt: skip
#: The status line's reason for edge (ploughing) terms the adequacy check does not support.
EDGE_REASON = "the runs do not separate edge forces from a size effect (see model adequacy)"


class RejectedRun(TypedDict):
    run: str
    reason: str


class LimitRow(TypedDict):
    """A run beyond the tool's limits and whether the fit kept it (``--keep``)."""

    run: str
    reason: str
    kept: bool


class AdequacyResult(AdequacyDict):
    """The adequacy check with its text line."""

    summary: str


class AxesPick(TypedDict):
    """``--axes auto``: the mapping chosen, the line that says it, the runner-up's fit."""

    axes: str
    line: str
    runner_up: AxesCandidate | None


class Validation(TypedDict):
    max_error_pct: float
    rows: list[ComparisonRow]


class ForcesResult(TypedDict):
    """See :func:`analysis.identify.fit_files`; the keys after ``adequacy`` are there when they
    apply (the end mill's, the face mill's, a validation, plots)."""

    model: str
    tool: str
    success: bool
    message: str
    coefficients: dict[str, float] | None
    statistics: dict[str, StatsRow]
    statistics_note: str
    r_squared: float | None
    residual_rms_n: float | None
    dof: int | None
    runs: list[str]
    rejected: list[RejectedRun]
    #: per run: run, fz_mm, depth_mm, revolutions, steady, mean_force_n, tooth_peak_n,
    #: runout_ratio, axes, zero
    per_run: list[dict[str, object]]
    axes: str | list[str]
    warnings: list[str]
    adequacy: AdequacyResult | None
    coefficient_units: NotRequired[dict[str, str]]
    axes_choice: NotRequired[AxesPick]
    axes_check: NotRequired[list[AxesCandidate]]
    outside_limits: NotRequired[list[LimitRow]]
    speed_limits: NotRequired[str]
    chip_limit: NotRequired[str]
    by_direction: NotRequired[dict[str, dict[str, float]]]
    by_direction_over: NotRequired[str]
    split: NotRequired[SplitDict]
    run_residuals: NotRequired[list[RunResidual]]
    influence: NotRequired[Influence]
    coefficient_status: NotRequired[dict[str, str]]
    validation: NotRequired[Validation]
    plots: NotRequired[list[str]]
    #: added by :func:`analysis.catalog.fit_catalog`: where the runs and the fit came from
    catalog: NotRequired[dict[str, object]]


def add_trust(out: ForcesResult, avgs: list[RunAverage], tool: EndMill, lin: LinearFit,
              adequacy: Adequacy | None) -> None:  # fmt: skip
    """Per-direction fit, per-run residuals, leave-one-out influence and each coefficient's
    status into the result ``out`` (:mod:`analysis.identify.trust`)."""
    Xr = [ENDMILL.mean_design(tool, ENDMILL.cut(tool, a.conditions)) for a in avgs]
    y = np.stack([a.mean_n for a in avgs])
    resid = y - np.stack([x @ lin.values for x in Xr])
    short = list(SHORT_NAMES)
    out["by_direction"] = by_direction(y, resid)
    out["run_residuals"] = per_run_residuals([a.name for a in avgs], y, resid)
    infl = influence(Xr, list(y), short, lin, [a.name for a in avgs])
    out["influence"] = infl
    edge_ok = adequacy is None or adequacy.edge_identified
    status = statuses(short, ("Kte", "Kre", "Kae"), None if edge_ok else EDGE_REASON, infl)
    if not infl["checked"]:
        out["warnings"].append(f"leave-one-out influence unchecked: {infl['reason']}")
    for k, (long, _) in SHORT_NAMES.items():
        if long in out["statistics"]:
            row = out["statistics"][long]
            row["status"] = status[k]
            row["identified"] = status[k] == "identified"
    out["coefficient_status"] = status


def add_validation(
    out: ForcesResult, targets: list[RunAverage], tool: ModelTool,
    coefficients: FaceMillCoefficients | EndMillCoefficients, dynamometer: Dynamometer,
    plot_dir: str | Path | None,
) -> None:  # fmt: skip
    """``validation`` (predicted against measured mean forces) and, with ``plot_dir``, ``plots``
    into the result ``out``."""
    cmp = compare_runs(targets, tool, coefficients, dynamometer)
    out["validation"] = {"max_error_pct": cmp.max_error_pct, "rows": list(cmp.rows)}
    if not plot_dir:
        return
    pngs = plot_comparison(cmp, plot_dir, tool=tool, coef=coefficients,
                           conditions=[a.conditions for a in targets])  # fmt: skip
    if FACEMILL.describes(tool) and isinstance(coefficients, FaceMillCoefficients):
        pngs += plot_waveforms(targets, tool, coefficients, plot_dir, dynamometer)
    out["plots"] = [str(p) for p in pngs]
