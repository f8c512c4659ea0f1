"""Stability lobes of a case by either method, with the chatter frequency and the kind of
instability per speed, warnings where the zero-order approximation cannot follow, and the plot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.errors import AnalysisError
from analysis.stability.case import StabilityCase
from analysis.stability.sd import critical_depths, discretise
from analysis.stability.zoa import zoa_lobes, zoa_minimum

__all__ = ["Lobes", "plot_lobes", "stability_lobes"]

METHODS = ("sd", "zoa")
#: the default deepest cut searched, as a multiple of the ZOA's lowest limit
DEPTH_MAX_FACTOR = 30.0
#: the depth grid the search marches up: from this fraction of the ZOA minimum (a limit below
#: it is bracketed from 0 still), by this ratio
GRID_START, GRID_RATIO = 0.4, 1.15  # at 1.5 it stepped over unstable islands (Insperger a/D 0.1
# up milling at 12000 rpm read 4.86 mm where 3.22 mm chatters: the authors' code found it)
#: ZOA "cannot follow" where SD finds flip lobes this much below it
FLIP_MARGIN = 0.9


@dataclass(frozen=True)
class Lobes:
    """Per speed: ``depth_limit_mm`` (inf: stable up to ``depth_max_mm``), ``chatter_hz`` and
    ``kind`` ('hopf', 'flip' (period doubling) or '' when stable); with ``warnings``."""

    method: str
    spindle_rpm: np.ndarray
    depth_limit_mm: np.ndarray
    chatter_hz: np.ndarray
    kind: tuple[str, ...]
    depth_max_mm: float
    steps_per_period: int | None
    warnings: list[str] = field(default_factory=list)

    def minimum(self) -> tuple[float, float]:
        """(speed rpm, depth mm) of the lowest limit."""
        i = int(np.argmin(self.depth_limit_mm))
        return float(self.spindle_rpm[i]), float(self.depth_limit_mm[i])

    def to_json(self) -> dict[str, Any]:
        """JSON-able result: the rows, with null and a reason where no limit was found."""
        rows = []
        for n, a, f, k in zip(self.spindle_rpm, self.depth_limit_mm, self.chatter_hz, self.kind):
            row: dict[str, Any] = {"spindle_rpm": float(n)}
            if math.isfinite(a):
                row |= {"depth_limit_mm": float(a), "chatter_hz": float(f), "kind": k}
            else:
                why = f"stable up to depth_max_mm = {self.depth_max_mm:.4g} mm"
                row |= {"depth_limit_mm": None, "depth_limit_mm_reason": why,
                        "chatter_hz": None, "chatter_hz_reason": why, "kind": None}  # fmt: skip
            rows.append(row)
        rpm, mm = self.minimum()
        low: dict[str, Any] = {"spindle_rpm": rpm, "depth_limit_mm": mm}
        if not math.isfinite(mm):
            why = f"stable up to depth_max_mm = {self.depth_max_mm:.4g} mm at every speed"
            low = {"spindle_rpm": None, "spindle_rpm_reason": why, "depth_limit_mm": None,
                   "depth_limit_mm_reason": why}  # fmt: skip
        return {
            "method": self.method,
            "steps_per_period": self.steps_per_period,
            "depth_max_mm": self.depth_max_mm,
            "minimum": low,
            "rows": rows,
            "warnings": list(self.warnings),
        }


def stability_lobes(case: StabilityCase, method: str = "sd", steps: int | None = None) -> Lobes:
    """Depth limit per spindle speed of ``case`` by semi-discretization (``sd``, ``steps`` per
    tooth period over the cut, default the case's) or the zero-order approximation (``zoa``).
    ZOA results are checked against SD: flip lobes it misses are named in the warnings."""
    if method not in METHODS:
        raise AnalysisError(f"method {method!r}: expected one of {', '.join(METHODS)}")
    zmin = zoa_minimum(case)
    if not math.isfinite(zmin):
        raise AnalysisError(
            f"{case.name}: no chatter possible: the mean directional factor times the receptance "
            "has no negative real part (check the coefficients and modes)"
        )
    depth_max_m = (case.depth_max_mm or 1e3 * DEPTH_MAX_FACTOR * zmin) / 1e3
    steps = steps or case.steps_per_period
    sd = _sd(case, steps, zmin, depth_max_m)
    warnings = []
    if method == "zoa":
        depth, chatter = zoa_lobes(case)
        depth = np.where(depth <= depth_max_m, depth, np.inf)
        kind = tuple("hopf" if math.isfinite(a) else "" for a in depth)
        warnings += _zoa_misses(case, sd, depth)
        result = Lobes("zoa", case.rpm, depth * 1e3, chatter, kind, depth_max_m * 1e3, None,
                       warnings)  # fmt: skip
    else:
        result = sd
    return result


def _sd(case: StabilityCase, steps: int, zmin_m: float, depth_max_m: float) -> Lobes:
    d = discretise(case, steps)
    n = max(2, math.ceil(math.log(depth_max_m / (GRID_START * zmin_m)) / math.log(GRID_RATIO)))
    grid = np.geomspace(GRID_START * zmin_m, depth_max_m, n + 1)
    depth, mu = critical_depths(d, grid)
    flip = np.isfinite(depth) & (np.abs(mu.imag) <= 1e-9 * np.abs(mu)) & (mu.real < 0)
    kind = tuple("" if not math.isfinite(a) else "flip" if f else "hopf"
                 for a, f in zip(depth, flip))  # fmt: skip
    return Lobes("sd", case.rpm, depth * 1e3, _chatter_hz(case, d.tau_s, mu), kind,
                 depth_max_m * 1e3, steps)  # fmt: skip


def _chatter_hz(case: StabilityCase, tau_s: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """Of the frequencies a multiplier allows, (k +- arg(mu) / 2 pi) / tau, the one where the
    oriented receptance's real part is most negative (where the ZOA would put the chatter)."""
    phase = np.abs(np.angle(mu)) / (2 * math.pi)  # nan where no multiplier
    k = np.arange(int(math.ceil(3 * case.f_hz.max() * tau_s.max())) + 2)
    cand = np.concatenate([k[None] + phase[:, None], k[None] + 1 - phase[:, None]], 1)
    cand = cand / tau_s[:, None]  # (S, C) Hz
    idx = ["xy".index(x) for x in case.directions]
    a0 = case.mean_h()[np.ix_(idx, idx)]
    g = case.receptance(np.where(np.isfinite(cand), cand, 0.0))
    re = np.linalg.eigvals(a0 * g[..., None, :]).real.min(-1)
    re = np.where((cand > 0) & np.isfinite(cand), re, np.inf)
    best = cand[np.arange(cand.shape[0]), np.argmin(re, 1)]
    return np.where(np.isfinite(mu), best, np.nan)


def _zoa_misses(case: StabilityCase, sd: Lobes, zoa_m: np.ndarray) -> list[str]:
    """A warning where SD's flip lobes lie below the ZOA's limit."""
    zoa_mm = zoa_m * 1e3
    miss = np.array([k == "flip" for k in sd.kind]) & (sd.depth_limit_mm < FLIP_MARGIN * zoa_mm)
    if not miss.any():
        return []
    i = np.flatnonzero(miss)
    worst = i[np.argmin(sd.depth_limit_mm[i] / zoa_mm[i])]
    return [
        f"the zero-order approximation misses period-doubling (flip) lobes at {miss.sum()} of "
        f"{miss.size} speeds ({sd.spindle_rpm[i].min():.0f}-{sd.spindle_rpm[i].max():.0f} rpm; "
        f"{case.teeth} teeth, radial immersion {case.radial_immersion:g}): semi-discretization "
        f"gives {sd.depth_limit_mm[worst]:.3g} mm at {sd.spindle_rpm[worst]:.0f} rpm where ZOA "
        f"gives {zoa_mm[worst]:.3g} mm; use --method sd"
    ]


def plot_lobes(lobes: Lobes, path: str | Path, title: str = "") -> Path:
    """Depth limit over spindle speed (flip parts marked) as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(path)
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(lobes.spindle_rpm, lobes.depth_limit_mm, "k-", lw=1.2, label=lobes.method.upper())
    flip = np.array([k == "flip" for k in lobes.kind])
    if flip.any():
        ax.plot(lobes.spindle_rpm[flip], lobes.depth_limit_mm[flip], "r.", ms=4,
                label="flip (period doubling)")  # fmt: skip
    ax.fill_between(lobes.spindle_rpm, 0, np.minimum(lobes.depth_limit_mm, lobes.depth_max_mm),
                    color="tab:green", alpha=0.15, label="stable")  # fmt: skip
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("axial depth limit (mm)")
    ax.set_ylim(bottom=0)
    ax.set_title(title or f"stability lobes ({lobes.method})")
    ax.legend(loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    try:
        fig.savefig(out, dpi=100)
    except OSError as exc:
        raise AnalysisError(f"{out}: cannot write the plot: {exc}") from None
    finally:
        plt.close(fig)
    return out
