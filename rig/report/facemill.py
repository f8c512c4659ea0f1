"""Report section for seed 003's campaign: identify the face-mill coefficients from the runs of the
identification groups, compare them with the simulator's truth (simulated rig), and predict the
mean forces of the validation runs (seed 003 Figs 7-14 as a table and plots)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import pandas as pd

from analysis.errors import AnalysisError
from analysis.identify import CI_NOTE
from rig.report.base import LoadedRun, Section, md_table

if TYPE_CHECKING:
    from analysis.identify.facemill import ForceRun
    from rig.campaign.config import Campaign

#: (axis, its key in LoadedRun.steady_means)
_MEAN_N: tuple[tuple[str, Literal["Fx_mean_N", "Fy_mean_N", "Fz_mean_N"]], ...] = (
    ("x", "Fx_mean_N"),
    ("y", "Fy_mean_N"),
    ("z", "Fz_mean_N"),
)

#: Said under the table: what the bootstrap intervals are.
BOOT_NOTE = (
    "boot_ci_low/boot_ci_high: 95 % bootstrap intervals, the runs and each run's revolutions "
    "resampled (what differs from run to run and revolution to revolution is in them)."
)

#: The coefficients seed 003 reports, then the axial pair cutlab adds.
COEFFS = ("K_T_n_mm2", "K_R", "P_T_n_mm", "P_R_n_mm", "K_A", "P_A_n_mm")


def force_run(lr: LoadedRun) -> ForceRun:
    """The run as an identification record (forces in X, Y, Z; conditions from the run)."""
    from analysis.identify.facemill import ForceRun, RunConditions, axis_order

    run = lr.run
    if run.force_n is None:
        raise AnalysisError(f"{lr.path}: the run has no calibration, so no forces in N")
    cond = RunConditions.from_mapping(lr.conditions, f"{lr.path}: conditions")
    return ForceRun(lr.name, run.force_n[:, axis_order(run.channel_names)], run.rate_hz, cond)


def _predicted_mean(tool: Any, coef: Any, c: dict[str, Any]) -> np.ndarray:
    """Model mean force (3,) N over one revolution for a run's conditions (the dynamometer's
    modes have unit static gain, so they do not change the mean)."""
    from analysis.identify import RunConditions, predicted_mean

    return predicted_mean(RunConditions.from_mapping(c, "conditions"), tool, coef)


def _truth(runs: list[LoadedRun]) -> dict[str, float] | None:
    for lr in runs:
        t = (lr.run.rig.get("sim_truth") or {}).get("facemill")
        if t:
            return t
    return None


def facemill_section(campaign: Campaign, runs: list[LoadedRun], out: Path) -> Section:
    from analysis.forces import FACEMILL
    from analysis.identify import fit_facemill_runs

    tool = campaign.tool
    assert FACEMILL.describes(tool)  # the config refuses this analysis without a face mill
    spec = campaign.spec.analysis
    ident = [lr for lr in runs if lr.group in spec.identify_groups]
    valid = [lr for lr in runs if lr.group in spec.validate_groups]
    # The library's steady window (analysis.runs.IDENTIFY_TOLERANCE), as `cutlab analyze forces`.
    fit = fit_facemill_runs([force_run(lr) for lr in ident], tool,
                            campaign.rig.dynamometer)  # fmt: skip
    truth = _truth(runs)
    summary: dict[str, Any] = {
        "success": fit.success,
        "message": fit.message,
        "identify_runs": len(ident),
        "validate_runs": len(valid),
    }
    md = [f"Identification over {len(ident)} runs ({', '.join(spec.identify_groups)}): "
          f"{fit.message}\n"]  # fmt: skip
    if not fit.success:
        (out / "coefficients.json").write_text(json.dumps(summary, indent=2))
        return Section("facemill-coefficients", "\n".join(md), summary)
    # a successful fit has its linear fit, adequacy and split
    assert fit.fit is not None and fit.adequacy is not None and fit.split is not None
    rows = _coefficient_rows(fit, truth)
    pd.DataFrame(rows).to_csv(out / "coefficients.csv", index=False)
    summary["coefficients"] = rows
    summary["r_squared"] = fit.fit.r_squared
    summary["adequacy"] = fit.adequacy.as_dict()
    summary["split"] = fit.split.as_dict()
    if truth is not None:
        # over the coefficients the design identifies (a not-identified one's error is no claim)
        errs = [abs(r["error_pct"]) for r in rows if r["status"] == "identified"]
        summary["max_error_pct_seed003"] = max(errs) if errs else None
    md += ["", md_table(rows), "", CI_NOTE, BOOT_NOTE, "", fit.adequacy.line()]
    # Validation: predicted vs measured mean forces of every run (identification runs too).
    vrows = _validation_rows(campaign, fit, ident + valid)
    pd.DataFrame(vrows).to_csv(out / "validation.csv", index=False)
    v_only = [r for r in vrows if r["group"] in spec.validate_groups]
    if v_only:
        summary["validation_max_abs_error_pct"] = max(abs(r["Fxy_error_pct"]) for r in v_only)
    from rig.report.plots import plot_pred_vs_meas

    plot_pred_vs_meas(vrows, out / "predicted_vs_measured.png",
                      f"{campaign.name}: mean force per run")  # fmt: skip
    _plot_fit(campaign, fit.coefficients, ident, out / "fit_vs_depth.png")
    (out / "coefficients.json").write_text(json.dumps(summary, indent=2, default=float))
    md += [
        "\nPredicted (identified model) against measured mean forces, validation groups "
        f"({', '.join(spec.validate_groups)}): largest error of the feed-plane resultant "
        f"{summary.get('validation_max_abs_error_pct', math.nan):.2f} %.\n",
        "![fit](fit_vs_depth.png) ![predicted vs measured](predicted_vs_measured.png)\n",
        md_table(
            [
                {
                    k: r[k]
                    for k in (
                        "run",
                        "fz_mm",
                        "depth_mm",
                        "Fx_measured_N",
                        "Fx_predicted_N",
                        "Fy_measured_N",
                        "Fy_predicted_N",
                        "Fxy_error_pct",
                    )
                }
                for r in v_only
            ]
        ),  # fmt: skip
    ]
    return Section("facemill-coefficients", "\n".join(md), summary,
                   ("coefficients.csv", "validation.csv", "coefficients.json"))  # fmt: skip


def _coefficient_rows(fit: Any, truth: Any) -> list[dict[str, Any]]:
    """One row per coefficient: the value, its intervals, its status and (seed 003) the truth."""
    rows = []
    for name in COEFFS:
        s = fit.summary[name]
        row = {"coefficient": name, "identified": s["value"], "std_error": s["std_error"],
               "ci_low": s["ci_low"], "ci_high": s["ci_high"],
               "boot_ci_low": s["boot_ci_low"], "boot_ci_high": s["boot_ci_high"]}  # fmt: skip
        # the status beside the number (issues 27, 33): from the design's split of cutting and
        # edge terms and the adequacy check (analysis.identify.facemill_split)
        row["status"] = s["status"]
        if truth is not None:
            tv = float(truth[name])
            row["truth"] = tv
            row["error_pct"] = 100.0 * (s["value"] - tv) / tv if tv else math.nan
        rows.append(row)
    return rows


def _validation_rows(campaign: Campaign, fit: Any, runs: list[LoadedRun]) -> list[dict[str, Any]]:
    """Predicted (identified model) against measured mean forces, per run with steady cutting."""
    vrows = []
    for lr in runs:
        meas = lr.steady_means
        if not meas["revs"]:
            continue
        pred = _predicted_mean(campaign.tool, fit.coefficients, lr.conditions)
        row = {"run": lr.name, "group": lr.group, "fz_mm": lr.conditions["fz_mm"],
               "depth_mm": lr.conditions["depth_mm"]}  # fmt: skip
        for k, (a, key) in enumerate(_MEAN_N):
            m = meas[key]
            row[f"F{a}_measured_N"] = m
            row[f"F{a}_predicted_N"] = float(pred[k])
        res_m = math.hypot(meas["Fx_mean_N"], meas["Fy_mean_N"])
        res_p = math.hypot(float(pred[0]), float(pred[1]))
        row["Fxy_error_pct"] = 100.0 * (res_p - res_m) / res_m if res_m else math.nan
        vrows.append(row)
    return vrows


def _plot_fit(campaign: Campaign, coef: Any, ident: list[LoadedRun], path: Path) -> None:
    from rig.report.plots import _plt

    plt = _plt()
    if not ident:
        return
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    d = np.array([lr.conditions["depth_mm"] for lr in ident])
    meas = np.array([[lr.steady_means[key] for _, key in _MEAN_N] for lr in ident])
    c0 = dict(ident[0].conditions)
    dd = np.linspace(max(0.05, d.min() * 0.5), d.max() * 1.05, 40)
    pred = np.array([_predicted_mean(campaign.tool, coef, {**c0, "depth_mm": x}) for x in dd])
    for k, a in enumerate("xyz"):
        ax.plot(d, meas[:, k], "o", ms=4, label=f"F{a} measured")
        ax.plot(dd, pred[:, k], "-", lw=1, color=ax.lines[-1].get_color())
    ax.set_xlabel("axial depth of cut, mm")
    ax.set_ylabel("mean force per revolution, N")
    ax.set_title(f"fz = {c0['fz_mm']} mm/tooth: measured (points), identified model (lines)",
                 fontsize=8)  # fmt: skip
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
