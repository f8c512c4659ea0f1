"""Stability lobes as the commands give them: the CSV (one row per speed, numbers round-trip
exact) and the one-line summary."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from analysis.errors import AnalysisError
from analysis.stability.case import load_case
from analysis.stability.lobes import Lobes, plot_lobes, stability_lobes
from analysis.validation import JsonObject

__all__ = ["lobes_file", "summary_line", "write_lobes_csv"]


def lobes_file(
    config: str | Path, csv: Path, method: str = "sd", steps: int | None = None,
    max_depth_mm: float | None = None, png: Path | None = None,
    note: Callable[[str], None] = lambda message: None,
) -> tuple[JsonObject, str]:  # fmt: skip
    """``cutlab analyze stability``: the lobes of the case file ``config`` (searched to
    ``max_depth_mm`` if given) by ``method`` written to ``csv`` (and plotted to ``png``), each
    file written and each warning told to ``note``; the result as JSON and its summary line."""
    case = load_case(config)
    if max_depth_mm is not None:
        case = dataclasses.replace(case, depth_max_mm=max_depth_mm)
    lobes = stability_lobes(case, method, steps)
    write_lobes_csv(lobes, csv)
    note(f"wrote {csv} ({lobes.depth_limit_mm.size} speeds)")
    if png:
        note(f"wrote {plot_lobes(lobes, png, case.name, case)}")
    for w in lobes.warnings:
        note(f"warning: {w}")
    out: JsonObject = {"config": str(config), "csv": str(csv), **lobes.to_json()}
    return out, summary_line(case.name, lobes)


def write_lobes_csv(lobes: Lobes, path: Path) -> None:
    """spindle_rpm, depth_limit_mm, chatter_hz, kind, steps, convergence_pct per speed; a
    speed stable up to the deepest depth searched reads inf, nan, stable."""
    finite = np.isfinite(lobes.depth_limit_mm)
    steps = lobes.steps if lobes.steps is not None else np.zeros(finite.size, int)
    rel = (
        lobes.convergence_rel if lobes.convergence_rel is not None else np.full(finite.size, np.nan)
    )
    lines = ["spindle_rpm,depth_limit_mm,chatter_hz,kind,steps,convergence_pct"] + [
        # repr: the shortest text that reads back as the same float (round-trip exact)
        f"{float(n)!r},{float(a)!r},{float(f) if ok else math.nan!r},{k or 'stable'},"
        f"{int(m) if m > 0 else ''},{float(r * 100)!r}"
        for n, a, f, k, m, r, ok in zip(
            lobes.spindle_rpm,
            lobes.depth_limit_mm,
            lobes.chatter_hz,
            lobes.kind,
            steps,
            rel,
            finite,
        )
    ]
    try:
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    except OSError as exc:
        raise AnalysisError(f"{path}: cannot write the lobes: {exc}") from None


def summary_line(name: str, lobes: Lobes) -> str:
    """The method, its convergence, the lowest limit and how many speeds are limited."""
    finite = np.isfinite(lobes.depth_limit_mm)
    rpm, mm = lobes.minimum()
    conv = lobes.convergence()
    if not conv["checked"]:
        how = f", convergence unchecked ({conv['reason']})"
    else:
        how = (
            f", {lobes.steps_per_period}-{conv['max_steps']} steps per tooth period, "
            f"converged within {conv['max_change_pct']:.2f} % (doubling check)"
        )
        if conv["unconverged_speeds"]:
            how = (
                f", {conv['unconverged_speeds']} speeds NOT converged within 1 % at "
                f"{conv['max_steps']} steps"
            )
    low = f"lowest limit {mm:.4g} mm at {rpm:.0f} rpm" if finite.any() else "no limit found"
    return (
        f"{name}: {lobes.method}{how}; {low}; {int(finite.sum())} of {finite.size} "
        f"speeds limited below {lobes.depth_max_mm:.4g} mm"
    )
