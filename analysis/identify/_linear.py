"""The linear least-squares fit of the force models with its statistics: estimates, standard
errors, t intervals, block-bootstrap intervals over whole runs (revolutions of one run are not
independent) and ratios of estimates with their propagated error. Private to
``analysis.identify``."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from analysis.errors import AnalysisError


@dataclass(frozen=True)
class LinearFit:
    """Least-squares estimates with standard errors and confidence intervals.

    ``values``/``std_errors``/``ci_low``/``ci_high`` shape (p,) in the order of ``names``;
    ``r_squared``; ``residual_rms`` (same unit as the data); ``dof`` degrees of freedom;
    ``covariance`` (p, p); ``condition_number`` of the design.
    """

    names: tuple[str, ...]
    values: np.ndarray
    std_errors: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    covariance: np.ndarray
    r_squared: float
    residual_rms: float
    dof: int
    confidence: float
    condition_number: float
    boot_low: np.ndarray | None = None
    boot_high: np.ndarray | None = None

    def as_dict(self) -> dict[str, dict[str, float]]:
        nan = np.full(len(self.names), math.nan)
        blo = nan if self.boot_low is None else self.boot_low
        bhi = nan if self.boot_high is None else self.boot_high
        return {
            n: {
                "value": float(v),
                "std_error": float(s),
                "ci_low": float(lo),
                "ci_high": float(hi),
                "boot_ci_low": float(bl),
                "boot_ci_high": float(bh),
            }
            for n, v, s, lo, hi, bl, bh in zip(
                self.names, self.values, self.std_errors, self.ci_low, self.ci_high, blo, bhi
            )
        }


@dataclass(frozen=True)
class RunBlock:
    """One run's share of a least-squares fit's normal equations: ``xtx`` (p, p), ``xty`` (p,),
    ``shift`` (p, c) how ``xty`` moves when the run's force level moves by (c,) N, and the
    run's ``revolution_means_n`` (revolutions, c) to resample."""

    xtx: np.ndarray
    xty: np.ndarray
    shift: np.ndarray
    revolution_means_n: np.ndarray

    @classmethod
    def of(cls, X: np.ndarray, y: np.ndarray, rev_means: np.ndarray) -> RunBlock:
        """From a run's regressors X (m, c, p) against its data y (m, c)."""
        X2 = X.reshape(-1, X.shape[-1])
        return cls(X2.T @ X2, X2.T @ y.reshape(-1), X.sum(axis=0).T, np.asarray(rev_means))


#: Bootstrap replicates for the intervals (the percentiles settle to ~0.3 % of the width).
N_BOOT = 400


def bootstrap_intervals(
    blocks: Sequence[RunBlock], derived: Callable[[np.ndarray], np.ndarray] | None = None,
    confidence: float = 0.95, n_boot: int = N_BOOT, seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Percentile bootstrap intervals (low, high) of the fitted parameters (or of
    ``derived(p)``): resample the runs, and within each drawn run its revolutions' mean forces
    (which moves that run's force level). Covers what differs from run to run and revolution to
    revolution in a real cut (material, depth, spindle), which the noise-only intervals miss.
    Replicates that cannot determine the parameters (too few distinct runs drawn) are skipped.
    A fixed ``seed``: the same data give the same intervals."""
    rng = np.random.default_rng(seed)
    n = len(blocks)
    rev_mean = [b.revolution_means_n.mean(axis=0) if len(b.revolution_means_n) else 0.0
                for b in blocks]  # fmt: skip
    out = []
    for _ in range(n_boot):
        A: np.ndarray | float = 0.0
        v: np.ndarray | float = 0.0
        for i in rng.integers(0, n, n):
            b = blocks[i]
            r = b.revolution_means_n
            delta = r[rng.integers(0, len(r), len(r))].mean(axis=0) - rev_mean[i] if len(r) else 0
            A = A + b.xtx
            v = v + b.xty + b.shift @ np.broadcast_to(delta, b.shift.shape[1:])
        if np.linalg.matrix_rank(A) < np.shape(A)[0]:
            continue
        p = np.linalg.solve(A, v)
        out.append(derived(p) if derived else p)
    if len(out) < n_boot // 4:
        nan = np.full(len(derived(blocks[0].xty) if derived else blocks[0].xty), math.nan)
        return nan, nan.copy()
    q = 50 * (1 - confidence)
    return np.percentile(out, q, axis=0), np.percentile(out, 100 - q, axis=0)


def linear_fit(
    X: np.ndarray, y: np.ndarray, names: Sequence[str], confidence: float = 0.95
) -> tuple[LinearFit, np.ndarray]:
    """Ordinary least squares y ~ X p with statistics; returns (fit, residuals)."""
    n, p = X.shape
    dof = n - p
    if dof <= 0:
        raise AnalysisError(f"{n} equations for {p} unknowns: need more data than unknowns")
    sol, _, rank, sv = linalg.lstsq(X, y)
    if rank < p:
        raise AnalysisError(
            f"the runs do not determine all {p} unknowns (rank {rank}): vary the conditions"
        )
    resid = y - X @ sol
    rss = float(resid @ resid)
    sigma2 = rss / dof
    xtx_inv = linalg.pinvh(X.T @ X)
    cov = sigma2 * xtx_inv
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    from scipy import stats  # on first use: importing scipy.stats costs ~0.3 s

    tq = stats.t.ppf(0.5 + confidence / 2, dof)
    tss = float(((y - y.mean()) ** 2).sum())
    r2 = 1.0 - rss / tss if tss > 0 else math.nan
    fit = LinearFit(
        tuple(names), sol, se, sol - tq * se, sol + tq * se, cov, r2,
        math.sqrt(rss / n), dof, confidence, float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf,
    )  # fmt: skip
    return fit, resid


def ratio_with_error(fit: LinearFit, num: int, den: int) -> tuple[float, float, float, float]:
    """a/b with its delta-method standard error and confidence interval (value, se, lo, hi)."""
    a, b = fit.values[num], fit.values[den]
    r = a / b
    g = np.zeros(len(fit.values))
    g[num], g[den] = 1 / b, -a / b**2
    se = float(math.sqrt(max(g @ fit.covariance @ g, 0.0)))
    from scipy import stats

    tq = stats.t.ppf(0.5 + fit.confidence / 2, fit.dof)
    return float(r), se, float(r - tq * se), float(r + tq * se)
