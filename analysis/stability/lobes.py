"""Stability lobes of a case by either method, with the chatter frequency and the kind of
instability per speed, warnings where the zero-order approximation cannot follow, and the plot.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.errors import AnalysisError
from analysis.stability.case import StabilityCase
from analysis.stability.sd import critical_depths, critical_depths_near, discretise
from analysis.stability.zoa import zoa_lobes, zoa_minimum
from analysis.validation import JsonObject, JsonValue

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
#: a speed's SD limit counts as converged when doubling its steps per tooth period changes it
#: by at most this fraction (the error falls as steps^-4, so the finer value is far closer)
CONVERGED_REL = 0.01
#: the most steps per tooth period the doubling goes to (30 -> 60 -> 120 -> 240)
MAX_STEPS = 240


@dataclass(frozen=True)
class Lobes:
    """Per speed: ``depth_limit_mm`` (inf: stable up to ``depth_max_mm``), ``chatter_hz`` and
    ``kind`` ('hopf', 'flip' (period doubling) or '' when stable); with ``warnings``.
    ``steps_per_period`` is the count SD started from; per speed, ``steps`` is the count its
    limit comes from and ``convergence_rel`` how much the last doubling changed it (nan where
    not checked: a fixed count was asked for, or ZOA)."""

    method: str
    spindle_rpm: np.ndarray
    depth_limit_mm: np.ndarray
    chatter_hz: np.ndarray
    kind: tuple[str, ...]
    depth_max_mm: float
    steps_per_period: int | None
    warnings: list[str] = field(default_factory=list)
    steps: np.ndarray | None = None
    convergence_rel: np.ndarray | None = None

    def convergence(self) -> JsonObject:
        """The doubling check as JSON: tolerance, largest change seen, speeds not converged."""
        rel = self.convergence_rel
        if rel is None or not np.isfinite(rel).any():
            why = ("fixed steps per tooth period asked for" if self.method == "sd"
                   else "zero-order approximation (no discretisation)")  # fmt: skip
            return {"checked": False, "reason": why, "tolerance_pct": CONVERGED_REL * 100}
        ok = np.isfinite(rel)
        return {
            "checked": True,
            "tolerance_pct": CONVERGED_REL * 100,
            "max_change_pct": float(np.max(rel[ok]) * 100),
            "median_change_pct": float(np.median(rel[ok]) * 100),
            "max_steps": int(np.max(self.steps)) if self.steps is not None else None,
            "unconverged_speeds": int(np.sum(rel > CONVERGED_REL)),
        }

    def minimum(self) -> tuple[float, float]:
        """(speed rpm, depth mm) of the lowest limit."""
        i = int(np.argmin(self.depth_limit_mm))
        return float(self.spindle_rpm[i]), float(self.depth_limit_mm[i])

    def to_json(self) -> JsonObject:
        """JSON-able result: the rows, with null and a reason where no limit was found."""
        rows: list[JsonValue] = []
        steps = self.steps if self.steps is not None else np.full(self.spindle_rpm.size, -1)
        rel = (self.convergence_rel if self.convergence_rel is not None
               else np.full(self.spindle_rpm.size, np.nan))  # fmt: skip
        for n, a, f, k, m, r in zip(self.spindle_rpm, self.depth_limit_mm, self.chatter_hz,
                                    self.kind, steps, rel):  # fmt: skip
            row: JsonObject = {"spindle_rpm": float(n)}
            if self.method == "sd":
                row["steps"] = int(m) if m > 0 else None
                row["convergence_pct"] = float(r * 100) if math.isfinite(r) else None
            if math.isfinite(a):
                row |= {"depth_limit_mm": float(a), "chatter_hz": float(f), "kind": k}
            else:
                why = f"stable up to depth_max_mm = {self.depth_max_mm:.4g} mm"
                row |= {"depth_limit_mm": None, "depth_limit_mm_reason": why,
                        "chatter_hz": None, "chatter_hz_reason": why, "kind": None}  # fmt: skip
            rows.append(row)
        rpm, mm = self.minimum()
        low: JsonObject = {"spindle_rpm": rpm, "depth_limit_mm": mm}
        if not math.isfinite(mm):
            why = f"stable up to depth_max_mm = {self.depth_max_mm:.4g} mm at every speed"
            low = {"spindle_rpm": None, "spindle_rpm_reason": why, "depth_limit_mm": None,
                   "depth_limit_mm_reason": why}  # fmt: skip
        return {
            "method": self.method,
            "steps_per_period": self.steps_per_period,
            "depth_max_mm": self.depth_max_mm,
            "minimum": low,
            "convergence": self.convergence(),
            "rows": rows,
            "warnings": list(self.warnings),
        }


def stability_lobes(case: StabilityCase, method: str = "sd", steps: int | None = None) -> Lobes:
    """Depth limit per spindle speed of ``case`` by semi-discretization (``sd``) or the zero-order
    approximation (``zoa``). SD starts from the case's steps per tooth period and doubles them
    at each speed until the limit changes by at most :data:`CONVERGED_REL` (up to
    :data:`MAX_STEPS`; speeds still changing are named in the warnings); ``steps`` fixes the
    count instead (no check). ZOA results are checked against SD: flip lobes it misses are
    named in the warnings."""
    if method not in METHODS:
        raise AnalysisError(f"method {method!r}: expected one of {', '.join(METHODS)}")
    from threadpoolctl import threadpool_limits

    # One BLAS thread: the eigenvalues of many small matrices gain nothing from more, and
    # OpenBLAS's spinning threads on a busy 2-core machine made 8 eigvals of 124 x 124 take
    # 40 s instead of 0.09 s
    with threadpool_limits(1, user_api="blas"):
        return _lobes(case, method, steps)


def _lobes(case: StabilityCase, method: str, steps: int | None) -> Lobes:
    zmin = zoa_minimum(case)
    if not math.isfinite(zmin):
        raise AnalysisError(
            f"{case.name}: no chatter possible: the mean directional factor times the receptance "
            "has no negative real part (check the coefficients and modes)"
        )
    depth_max_m = (case.depth_max_mm or 1e3 * DEPTH_MAX_FACTOR * zmin) / 1e3
    if steps or method == "zoa":  # ZOA's flip check needs no converged SD
        sd = _sd(case, steps or case.steps_per_period, zmin, depth_max_m)
    else:
        sd = _sd_converged(case, case.steps_per_period, zmin, depth_max_m)
    warnings = list(sd.warnings)
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


def _sd_converged(case: StabilityCase, steps: int, zmin_m: float, depth_max_m: float) -> Lobes:
    """SD with the steps per tooth period doubled at each speed whose limit still moves by more
    than CONVERGED_REL (the 30-step default read 10-14 % high, the unsafe side, on the 2-DOF
    a/D 0.05 benchmark at 6700-6900 rpm; 60-120 steps converge there)."""
    # The check starts one halving below ``steps`` (8 times cheaper: the cost grows as the cube
    # of the steps): a speed whose limit moves by at most CONVERGED_REL from half the steps to
    # ``steps`` keeps the latter, the others double on.
    m = max(4, steps // 2)
    out = _sd(case, m, zmin_m, depth_max_m)
    depth, hz = out.depth_limit_mm.copy(), out.chatter_hz.copy()
    kind = list(out.kind)
    used = np.full(depth.size, m)
    rel = np.full(depth.size, np.nan)
    todo = np.arange(depth.size)
    while todo.size and (2 * m <= MAX_STEPS or m < steps):
        m = steps if m < steps else 2 * m
        fine = _sd(dataclasses.replace(case, rpm=case.rpm[todo]), m, zmin_m, depth_max_m,
                   depth[todo])  # fmt: skip
        a, b = depth[todo], fine.depth_limit_mm
        both_inf = np.isinf(a) & np.isinf(b)
        with np.errstate(invalid="ignore", divide="ignore"):
            change = np.where(both_inf, 0.0, np.abs(a - b) / np.minimum(a, b))
        change = np.where(np.isnan(change), np.inf, change)  # one side inf: not converged
        depth[todo], hz[todo], used[todo], rel[todo] = b, fine.chatter_hz, m, change
        for i, k in zip(todo, fine.kind):
            kind[i] = k
        todo = todo[change > CONVERGED_REL]
    warnings = []
    if todo.size:
        worst = todo[np.argmax(rel[todo])]
        warnings.append(
            f"the limit at {todo.size} of {depth.size} speeds still changes by more than "
            f"{CONVERGED_REL:.0%} at {MAX_STEPS} steps per tooth period (worst "
            f"{rel[worst]:.1%} at {case.rpm[worst]:.0f} rpm): treat those speeds as uncertain"
        )
    return Lobes("sd", case.rpm, depth, hz, tuple(kind), out.depth_max_mm, steps, warnings,
                 used, rel)  # fmt: skip


def _sd(case: StabilityCase, steps: int, zmin_m: float, depth_max_m: float,
        guess_mm: np.ndarray | None = None) -> Lobes:  # fmt: skip
    """SD lobes; with ``guess_mm`` (a coarser count's limits) finite limits are first sought
    in a bracket around the guess (5 evaluations instead of ~25 for the march), the rest
    marched for as without."""
    n = max(2, math.ceil(math.log(depth_max_m / (GRID_START * zmin_m)) / math.log(GRID_RATIO)))
    grid = np.geomspace(GRID_START * zmin_m, depth_max_m, n + 1)
    if guess_mm is None:
        depth, mu = critical_depths(discretise(case, steps), grid)
    else:
        depth = np.full(case.rpm.size, np.nan)
        mu = np.full(case.rpm.size, np.nan, complex)
        near = np.flatnonzero(np.isfinite(guess_mm))
        if near.size:
            sub = discretise(dataclasses.replace(case, rpm=case.rpm[near]), steps)
            depth[near], mu[near] = critical_depths_near(sub, guess_mm[near] / 1e3)
        far = np.flatnonzero(np.isnan(depth))
        if far.size:
            sub = discretise(dataclasses.replace(case, rpm=case.rpm[far]), steps)
            depth[far], mu[far] = critical_depths(sub, grid)
    flip = np.isfinite(depth) & (np.abs(mu.imag) <= 1e-9 * np.abs(mu)) & (mu.real < 0)
    kind = tuple("" if not math.isfinite(a) else "flip" if f else "hopf"
                 for a, f in zip(depth, flip))  # fmt: skip
    tau_s = 60.0 / (case.teeth * case.rpm)
    return Lobes("sd", case.rpm, depth * 1e3, _chatter_hz(case, tau_s, mu), kind,
                 depth_max_m * 1e3, steps, [], np.full(depth.size, steps),
                 np.full(depth.size, np.nan))  # fmt: skip


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


def plot_lobes(lobes: Lobes, path: str | Path, title: str = "",
               case: StabilityCase | None = None) -> Path:  # fmt: skip
    """Depth limit over spindle speed (flip parts marked) and, below it, the chatter frequency
    at the limit, as a PNG; with ``case`` the title names the teeth, radial immersion, milling
    mode and modes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(path)
    fig, (ax, axf) = plt.subplots(2, 1, figsize=(8, 6), sharex=True,
                                  gridspec_kw={"height_ratios": [3, 1.3]})  # fmt: skip
    ax.plot(lobes.spindle_rpm, lobes.depth_limit_mm, "k-", lw=1.2,
            label=f"limit ({lobes.method.upper()})")  # fmt: skip
    flip = np.array([k == "flip" for k in lobes.kind])
    if flip.any():
        ax.plot(lobes.spindle_rpm[flip], lobes.depth_limit_mm[flip], "r.", ms=4,
                label="flip (period doubling)")  # fmt: skip
    ax.fill_between(lobes.spindle_rpm, 0, np.minimum(lobes.depth_limit_mm, lobes.depth_max_mm),
                    color="tab:green", alpha=0.15, label="stable")  # fmt: skip
    if not np.isfinite(lobes.depth_limit_mm).all():
        ax.axhline(lobes.depth_max_mm, color="0.5", ls=":", lw=1,
                   label=f"search ceiling {lobes.depth_max_mm:.3g} mm")  # fmt: skip
    ax.set_ylabel("axial depth limit (mm)")
    ax.set_ylim(bottom=0)
    conv = lobes.convergence()
    sub = (f"converged within {conv['max_change_pct']:.2f} % (doubling)" if conv["checked"]
           else "convergence unchecked")  # fmt: skip
    if case is not None:
        modes = ", ".join(f"{d} {f:.0f} Hz \u03b6 {z:.3g}"
                          for d, f, z in zip(case.direction, case.f_hz, case.zeta))  # fmt: skip
        sub = (f"{case.teeth} teeth, a/D {case.radial_immersion:g}, {case.milling} milling; "
               f"modes {modes}; {sub}")  # fmt: skip
    ax.set_title(f"{title or 'stability lobes'} ({lobes.method})\n{sub}", fontsize=9)
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    axf.plot(lobes.spindle_rpm, lobes.chatter_hz, "b.", ms=3, label="chatter frequency")
    if case is not None:
        for f in case.f_hz:
            axf.axhline(f, color="0.4", ls="--", lw=0.8)
        axf.plot([], [], color="0.4", ls="--", lw=0.8, label="natural frequencies")
    axf.set_xlabel("spindle speed (rpm)")
    axf.set_ylabel("chatter (Hz)")
    axf.legend(loc="upper left", fontsize=8)
    axf.grid(alpha=0.3)
    fig.tight_layout()
    try:
        fig.savefig(out, dpi=100)
    except OSError as exc:
        raise AnalysisError(f"{out}: cannot write the plot: {exc}") from None
    finally:
        plt.close(fig)
    return out
