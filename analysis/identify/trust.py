"""How far an end-mill fit holds, run by run: each run's mean-force residual per direction, the
fit per direction (R^2, RMS: a pooled R^2 hides a poor feed or axial fit behind the large
cross-feed forces), runs whose conditions lie outside the tool's limits (named before the fit),
and leave-one-out influence: a run without which a coefficient moves by more than its interval.
A coefficient that depends on one run is not identified.

Leave-one-out compares the shift with its own interval under the noise of the other runs
(Var(b_all - b_without) = s^2 ((X'X)_without^-1 - (X'X)_all^-1), s from the fit without the run;
Student-t at 1 - (1 - confidence) / 20, i.e. 99.75 %, for the many runs and coefficients tested)
and names it when it is also at least 1 % of the coefficient: a run that bends the fit widens the
full fit's interval with its own misfit, so that interval cannot judge it (the twin's overloaded
0.1 mm slot moved Ktc by 721 N/mm^2 against a full-fit half-width of 686; noise-only runs of the
same sweep scored up to 5.8 against the threshold 7.45, the overloaded one 630-1030).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TypedDict

import numpy as np

from analysis.config import EndMill
from analysis.errors import AnalysisError
from analysis.identify._common import RunAverage
from analysis.identify._linear import LinearFit, linear_fit

__all__ = ["Influence", "InfluenceRun", "RunResidual", "by_direction", "influence",
           "outside_limits", "per_run_residuals", "statuses"]  # fmt: skip


class RunResidual(TypedDict):
    """One run's mean-force residual per direction (N, % of its measured mean resultant)."""

    run: str
    residual_n: list[float]
    residual_pct: list[float]


class InfluenceRun(TypedDict):
    """The fit without one run: each parameter's shift, value, score; the ones it moved."""

    run: str
    shift: dict[str, float]
    without: dict[str, float]
    score: dict[str, float]
    moved: list[str]


class Influence(TypedDict):
    """:func:`influence`: whether checked (else ``reason``), per run, the runs each parameter
    depends on."""

    checked: bool
    reason: str
    runs: list[InfluenceRun]
    depends: dict[str, list[str]]

DIRECTIONS = ("x", "y", "z")
#: A shift below this fraction of the coefficient (the fit without the run) is not named, however
#: clear against the noise (the README's DynoWare runs: 0.0885 N residual, shifts of 0.01 %).
RELATIVE_FLOOR = 0.01


def by_direction(y: np.ndarray, resid: np.ndarray) -> dict[str, dict[str, float]]:
    """R^2 and residual RMS (N) of each direction over the runs: ``y`` and ``resid`` (runs, 3)."""
    out = {}
    for j, d in enumerate(DIRECTIONS):
        rss = float((resid[:, j] ** 2).sum())
        tss = float(((y[:, j] - y[:, j].mean()) ** 2).sum())
        out[d] = {"r_squared": 1.0 - rss / tss if tss > 0 else math.nan,
                  "rms_n": math.sqrt(rss / len(y))}  # fmt: skip
    return out


def per_run_residuals(
    names: Sequence[str], y: np.ndarray, resid: np.ndarray
) -> list[RunResidual]:
    """Each run's mean-force residual (measured - fitted) per direction in N and in % of the
    run's measured mean resultant (a direction's own mean can be near zero)."""
    out: list[RunResidual] = []
    for n, yy, r in zip(names, y, resid):
        scale = max(float(np.linalg.norm(yy)), 1e-9)
        out.append({"run": n, "residual_n": [float(v) for v in r],
                    "residual_pct": [float(v / scale * 100) for v in r]})  # fmt: skip
    return out


def max_chip_mm(tool: EndMill, fz_mm: float, mode: str, width_mm: float) -> float:
    """Largest uncut chip thickness of a flat-end-mill cut (mm): fz at a half immersion or more,
    else fz sin(phi_exit) with cos(phi) = 1 - 2 ae / D (radial chip thinning)."""
    d = tool.diameter_mm
    if mode == "slot" or not math.isfinite(width_mm) or width_mm >= d / 2:
        return fz_mm
    return fz_mm * 2 * math.sqrt(width_mm * (d - width_mm)) / d


def outside_limits(
    averages: Sequence[RunAverage], tool: EndMill, spindle_min_rpm: float = 0.0,
    spindle_max_rpm: float = math.inf,
) -> list[tuple[str, str]]:  # fmt: skip
    """(run, reason) for runs whose conditions exceed the tool's chip-thickness limit
    (``max_chip_mm``) or the spindle's speed range: above them the force law changes (the chip
    jams in the chip breaker) and a linear fit bends to follow."""
    out = []
    for a in averages:
        c = a.conditions
        why = []
        if tool.max_chip_mm is not None:
            h = max_chip_mm(tool, c.fz_mm, c.mode, c.width_mm)
            if h > tool.max_chip_mm * (1 + 1e-9):
                why.append(f"max chip thickness {h:.4g} mm > the tool's max_chip_mm "
                           f"{tool.max_chip_mm:g} mm")  # fmt: skip
        rpm = abs(c.spindle_rpm)
        if rpm > spindle_max_rpm or rpm < spindle_min_rpm:
            why.append(f"spindle {rpm:g} rpm outside the rig's {spindle_min_rpm:g}.."
                       f"{spindle_max_rpm:g} rpm")  # fmt: skip
        if why:
            out.append((a.name, "; ".join(why)))
    return out


def influence(
    Xr: Sequence[np.ndarray], yr: Sequence[np.ndarray], names: Sequence[str], fit: LinearFit,
    runs: Sequence[str],
) -> Influence:  # fmt: skip
    """Leave-one-out: refit without each run (design ``Xr[i]`` (3, p), means ``yr[i]`` (3,));
    ``runs`` the runs' names, ``names`` the parameters'. Returns ``{"checked": bool, "reason",
    "runs": [{run, shift {name: value}, moved [names]}], "depends": {name: [runs]}}``; unchecked
    when a run cannot be left out (the others do not determine the fit with a residual)."""
    rows: list[InfluenceRun] = []
    depends: dict[str, list[str]] = {n: [] for n in names}
    for i, run in enumerate(runs):
        keep = [k for k in range(len(runs)) if k != i]
        X = np.concatenate([Xr[k] for k in keep])
        y = np.concatenate([yr[k] for k in keep])
        try:
            loo, _ = linear_fit(X, y, names, fit.confidence)
        except AnalysisError as exc:
            return {"checked": False, "runs": [], "depends": {},
                    "reason": f"without run {run} the other runs do not determine the fit "
                    f"({exc}): add runs"}  # fmt: skip
        shift = fit.values - loo.values
        # The shift's own standard error under the other runs' noise: Var(b_all - b_without)
        # = s^2 ((X'X)_without^-1 - (X'X)_all^-1) (nested least squares).
        a_all = np.linalg.pinv(np.concatenate(Xr).T @ np.concatenate(Xr))
        a_loo = np.linalg.pinv(X.T @ X)
        s2 = (loo.residual_rms**2) * len(y) / loo.dof
        se = np.sqrt(np.maximum(np.diag(a_loo - a_all), 0.0) * s2)
        tq = _t(1 - (1 - fit.confidence) / 20, loo.dof)
        score = np.abs(shift) / np.maximum(se, 1e-300)
        # ... and large enough to matter: near noise-free runs make a 0.01 % shift "significant"
        big = np.abs(shift) > RELATIVE_FLOOR * np.abs(loo.values)
        moved = [n for n, z, b in zip(names, score, big) if z > tq and b]
        for n in moved:
            depends[n].append(run)
        rows.append({"run": run, "shift": {n: float(s) for n, s in zip(names, shift)},
                     "without": {n: float(v) for n, v in zip(names, loo.values)},
                     "score": {n: float(z) for n, z in zip(names, score)},
                     "moved": moved})  # fmt: skip
    return {"checked": True, "reason": "", "runs": rows, "depends": depends}


def _t(q: float, dof: int) -> float:
    from scipy import stats

    return float(stats.t.ppf(q, dof))


def statuses(names: Sequence[str], edge: Sequence[str], edge_reason: str | None,
             infl: Influence) -> dict[str, str]:  # fmt: skip
    """Each coefficient's status: 'identified', or 'not identified: <reason>' (the edge terms
    when the adequacy check does not support them; any coefficient that one run moves by more
    than its interval)."""
    out = {}
    for n in names:
        why = []
        if edge_reason and n in edge:
            why.append(edge_reason)
        runs = infl.get("depends", {}).get(n, [])
        if runs:
            moves = []
            for r in infl["runs"]:
                if r["run"] in runs:
                    moves.append(f"{r['run']} (without it {r['without'][n]:.4g})")
            why.append("depends on one run: " + ", ".join(moves))
        out[n] = "identified" if not why else "not identified: " + "; ".join(why)
    return out
