"""Stability lobes as the commands give them: the CSV (one row per speed, numbers round-trip
exact) and the one-line summary."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from analysis.errors import AnalysisError
from analysis.stability.lobes import Lobes

__all__ = ["summary_line", "write_lobes_csv"]


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
