"""Does the data support edge (ploughing) coefficients? The linear edge-force model against a
power law (Kienzle size effect) on the runs' mean forces against the feed per tooth.

Both models explain a run's mean force per unit chip width, component by component, with two
parameters: linear q = K h + P (P the edge or ploughing force) and power law q = C h^m (m = 1 - m_c
< 1: specific force growing as the chip thins). Over a narrow range of feeds a power law looks like
a straight line with a positive intercept, so a linear fit of size-effect data reports an edge
force that is not there (seed 003's face mill on Kienzle data: R^2 0.9998, P_R 83 % off). The two
separate only by curvature across feeds: with the same number of parameters, Akaike's criterion
from the residual sums, delta_aic = n ln(RSS_linear / RSS_power), says which the data supports
(> 6: the power law, < -6: the linear model; otherwise neither). The residual pattern is reported
too: the t value of a quadratic term added to the linear fit (curvature), per component.

Fewer than 3 distinct feeds per tooth cannot separate them at all. When the data cannot separate
them, or supports the size effect, the edge coefficients are not identified: the result says so
and which cuts would separate them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypedDict

import numpy as np
from scipy import optimize

__all__ = ["AIC_MARGIN", "Adequacy", "AdequacyDict", "compare_models", "runs_adequacy"]

if TYPE_CHECKING:
    from analysis.identify._common import RunAverage

#: |delta AIC| above which one model is supported (Burnham & Anderson: > 6 strong).
AIC_MARGIN = 6.0


class AdequacyDict(TypedDict):
    """:meth:`Adequacy.as_dict`: its fields by name, in their order."""

    verdict: str
    edge_identified: bool
    reason: str
    suggestion: str
    delta_aic: float
    exponent: float
    curvature_t: float
    feeds_mm: tuple[float, ...]


@dataclass(frozen=True)
class Adequacy:
    """``verdict`` 'edge' (linear model with edge/ploughing terms), 'size_effect' or
    'undecided'; ``edge_identified`` only for 'edge'; ``reason`` and ``suggestion`` one line each;
    ``delta_aic`` (> 0 favours the power law), ``exponent`` the power law's fitted m (1 - m_c),
    ``curvature_t`` the largest |t| of a quadratic term, ``feeds_mm`` the distinct feeds."""

    verdict: str
    edge_identified: bool
    reason: str
    suggestion: str = ""
    delta_aic: float = math.nan
    exponent: float = math.nan
    curvature_t: float = math.nan
    feeds_mm: tuple[float, ...] = ()

    def as_dict(self) -> AdequacyDict:
        return AdequacyDict(
            verdict=self.verdict, edge_identified=self.edge_identified, reason=self.reason,
            suggestion=self.suggestion, delta_aic=self.delta_aic, exponent=self.exponent,
            curvature_t=self.curvature_t, feeds_mm=self.feeds_mm,
        )  # fmt: skip

    def line(self) -> str:
        """The text-output line: the verdict, and what to do when the edge is not identified."""
        if self.edge_identified:
            return f"model adequacy: the linear edge-force model is supported ({self.reason})"
        return (f"model adequacy: edge/ploughing coefficients NOT identified: {self.reason}; "
                f"{self.suggestion}")  # fmt: skip


def _suggest(feeds: np.ndarray) -> str:
    lo, hi = float(feeds.min()), float(feeds.max())
    return (
        f"add cuts at fz below {_round(lo / 2)} and above {_round(hi * 1.5)} mm/tooth (at least "
        "3 feeds per tooth spanning a factor of 5 or more) to separate edge forces from a size "
        "effect"
    )


def _round(x: float) -> str:
    return f"{float(f'{x:.2g}'):g}"


def _power_fit(h: np.ndarray, q: np.ndarray) -> tuple[float, np.ndarray]:
    """(exponent, residuals) of q = C h^m by least squares (started from the log-log line)."""
    m0, c0 = np.polyfit(np.log(h), np.log(np.abs(q)), 1)
    sign = np.sign(q.mean())
    try:
        (c, m), _ = optimize.curve_fit(lambda x, c, m: c * x**m, h, q,
                                       p0=(sign * math.exp(c0), m0), maxfev=2000)  # fmt: skip
    except (RuntimeError, optimize.OptimizeWarning):
        c, m = sign * math.exp(c0), m0
    return float(m), q - c * h**m


def compare_models(
    fz_mm: Sequence[float], width_mm: Sequence[float], force_n: np.ndarray
) -> Adequacy:
    """Linear edge-force model against a power law on runs' mean forces (runs, c) N, chip width
    ``width_mm`` (runs,) and feed per tooth ``fz_mm`` (runs,); runs of one cutting geometry."""
    h = np.asarray(fz_mm, float)
    q = np.asarray(force_n, float).reshape(len(h), -1) / np.asarray(width_mm, float)[:, None]
    feeds = np.unique(np.round(h, 9))
    if len(feeds) < 3:
        return Adequacy(
            "undecided", False,
            f"the runs are at {len(feeds)} feed(s) per tooth "
            f"({', '.join(f'{f:g}' for f in feeds)} mm): a size effect (force ~ h^m) and an edge "
            "force (K h + P) fit them equally",
            _suggest(feeds), feeds_mm=tuple(float(f) for f in feeds),
        )  # fmt: skip
    # Components that carry the cut (consistent sign, >= 5 % of the largest), each scaled by
    # its size so that they weigh alike.
    size = np.abs(q.mean(axis=0))
    comps = [j for j in range(q.shape[1])
             if size[j] >= 0.05 * size.max() and (np.all(q[:, j] > 0) or np.all(q[:, j] < 0))]
    rss_lin = rss_pow = 0.0
    exps, curv = [], []
    for j in comps:
        y = q[:, j] / size[j]
        rss_lin += float(((y - np.polyval(np.polyfit(h, y, 1), h)) ** 2).sum())
        m, r = _power_fit(h, y)
        rss_pow += float((r**2).sum())
        exps.append(m)
        if len(feeds) >= 4:
            X = np.column_stack([np.ones_like(h), h, h**2])
            coef, res, *_ = np.linalg.lstsq(X, y, rcond=None)
            dof = len(h) - 3
            s2 = float(((y - X @ coef) ** 2).sum()) / max(dof, 1)
            cov = s2 * np.linalg.inv(X.T @ X)
            curv.append(abs(coef[2]) / math.sqrt(cov[2, 2]) if cov[2, 2] > 0 else math.inf)
    n = len(h) * len(comps)
    tiny = 1e-12 * n
    delta = n * math.log((rss_lin + tiny) / (rss_pow + tiny))
    exponent = float(np.mean(exps)) if exps else math.nan
    curvature = float(max(curv)) if curv else math.nan
    feeds_mm = tuple(float(f) for f in feeds)
    span = f"{len(feeds)} feeds {feeds.min():g}..{feeds.max():g} mm/tooth"
    if delta > AIC_MARGIN:
        return Adequacy(
            "size_effect", False,
            f"over {span} the mean forces follow a size effect (force ~ h^{exponent:.2f}, "
            f"AIC {delta:.1f} better than the linear model): the edge terms would only absorb it",
            "fit a size-effect (Kienzle) model, or " + _suggest(feeds), delta, exponent,
            curvature, feeds_mm,
        )  # fmt: skip
    if delta < -AIC_MARGIN:
        return Adequacy(
            "edge", True,
            f"over {span} the linear model fits better than a size effect by AIC {-delta:.1f}",
            "", delta, exponent, curvature, feeds_mm,
        )  # fmt: skip
    return Adequacy(
        "undecided", False,
        f"over {span} the linear and size-effect models fit alike (delta AIC {delta:.1f})",
        _suggest(feeds), delta, exponent, curvature, feeds_mm,
    )  # fmt: skip


def runs_adequacy(averages: Sequence[RunAverage]) -> Adequacy:
    """:func:`compare_models` on reduced runs (RunAverage): the runs of the cutting geometry
    (mode, radial width, spindle speed) with the most feeds; chip width = the axial depth."""
    groups: dict[tuple[str, float | None, float, float], list[RunAverage]] = {}
    for a in averages:
        c = a.conditions
        key = (c.mode, round(c.width_mm, 6) if math.isfinite(c.width_mm) else None,
               round(abs(c.spindle_rpm), 3), round(c.center_offset_mm, 6))  # fmt: skip
        groups.setdefault(key, []).append(a)
    runs = max(groups.values(), key=lambda g: len({round(a.conditions.fz_mm, 9) for a in g}))
    return compare_models(
        [a.conditions.fz_mm for a in runs], [a.conditions.depth_mm for a in runs],
        np.array([a.mean_n for a in runs]),
    )  # fmt: skip
