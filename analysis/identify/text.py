"""The fit of `cutlab analyze forces` as text: the coefficients with their status, how far the fit
holds (per direction, per run, leave-one-out) and the validation."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from analysis.output import table_lines

__all__ = ["forces_lines"]


def forces_lines(out_json: Mapping[str, object]) -> list[str]:
    """The text report of a fit (:func:`analysis.identify.fit_files`' result), as lines."""
    out: Any = out_json  # the job's JSON result, read by key
    lines: list[str] = []
    lines.append(
        f"{out['model']} fit of {len(out['runs'])} run(s), tool {out['tool']}: {out['message']}"
    )
    axes = out["axes"] if isinstance(out["axes"], str) else "; ".join(out["axes"])
    lines.append(f"axes: {axes} (x feed, y cross-feed, z tool axis)")
    if "axes_choice" in out:
        lines.append(f"axes {out['axes_choice']['line']}")
    for w in out["warnings"]:  # beside the figures, not only on stderr
        if w.startswith("axes "):
            lines.append(f"warning: {w}")
    if "chip_limit" in out:
        lines.append(
            f"tool limits: chip thickness {out['chip_limit']}; speeds {out['speed_limits']}"
        )
    for r in out.get("outside_limits", []):
        how = "kept (--keep)" if r["kept"] else "left out (--keep fits it)"
        lines.append(f"beyond the tool's limits, {how}: {r['run']}: {r['reason']}")
    if out["statistics"]:
        # the status on the number's own line: a coefficient is never shown without it
        rows = [
            {
                "coefficient": k,
                "value": row["value"],
                "status": row.get("status", ""),
                **{c: v for c, v in row.items() if c not in ("identified", "value", "status")},
            }
            for k, row in out["statistics"].items()
        ]
        lines += table_lines(rows, cell_max=400)
        lines.append(out["statistics_note"])
    lines += _trust_lines(out)
    if out["adequacy"]:
        lines.append(out["adequacy"]["summary"])
    for r in out["per_run"]:
        lines.append(f"{r['run']}: {r['steady']}")
    if "validation" in out:
        lines.append("")
        keys = ("run", "fz_mm", "depth_mm", "measured_resultant_n", "predicted_resultant_n")
        lines += table_lines(
            [
                {**{k: r[k] for k in keys}, "error_pct": r["resultant_error_pct"]}
                for r in out["validation"]["rows"]
            ]
        )
    return lines


def _trust_lines(out: dict[str, Any]) -> list[str]:
    """How far an end-mill fit holds: per direction, per run, leave-one-out influence."""
    lines: list[str] = []
    if out.get("by_direction"):
        over = f" over {out['by_direction_over']}" if out.get("by_direction_over") else ""
        lines.append(
            f"fit per direction{over}: "
            + "; ".join(
                f"{d}: R^2 {v['r_squared']:.4f}, RMS {v['rms_n']:.3g} N"
                for d, v in out["by_direction"].items()
            )
            + f" (pooled R^2 {out['r_squared']:.4f})"
        )
    if out.get("run_residuals"):
        lines.append(
            "mean-force residual per run (measured - fitted; % of the run's mean resultant):"
        )
        lines += table_lines(
            [
                {
                    "run": r["run"],
                    **{f"{d}_n": v for d, v in zip("xyz", r["residual_n"])},
                    **{f"{d}_pct": v for d, v in zip("xyz", r["residual_pct"])},
                }
                for r in out["run_residuals"]
            ]
        )
    infl = out.get("influence")
    if infl is not None:
        if not infl["checked"]:
            lines.append(f"leave-one-out influence: unchecked: {infl['reason']}")
        for r in infl["runs"]:
            if r["moved"]:
                lines.append(
                    f"leave-one-out: run {r['run']} moves "
                    + ", ".join(
                        f"{k} by {r['shift'][k]:.4g} (without it {r['without'][k]:.4g})"
                        for k in r["moved"]
                    )
                    + ": more than its interval"
                )
    return lines
