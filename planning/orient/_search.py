"""Search for one CC point's orientation (seed 002 sections 3-4); used by planning.orient.planner.

The steps, cheapest first (each counted in ``_Context.evals`` energy evaluations):

1. Curvature optimum: the best point of a vectorised grid of R (K - kappa) + w |theta -
   theta_prev|^2 subject to K - kappa >= margin, polished by ``scipy.optimize.minimize`` (SLSQP,
   analytic gradient of K). If U = 0 there and the check mesh agrees, that is the answer.
2. A collision-free start: the neighbour's answer, or a small step back from it; else the grid
   orientations in order of the objective (best-first, up to 40); else seed 002's own way out,
   descent along -grad U (eq 7) from the optimum; else the whole grid.
3. From that start towards the optimum, bisection on U = 0 (U is flat, zero, on the free set,
   which gives a gradient optimiser nothing to hold on to as an equality constraint), then a
   compass search that walks along the free set while the objective drops.
4. The answer must pass the dense check mesh (:mod:`planning.orient.check`); if nothing does, the
   point is infeasible and the reason names the tool part and the surface it hits.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from planning.orient._energy import Charges, Site, energy, place
from planning.orient.check import CheckMesh, Clearance, check
from planning.orient.tool import ToolSystem, szende_K, szende_K_grad

K_CAP_PER_MM = 1e3  # stands in for the flat end mill's infinite K at alpha = 0, beta != 0


@dataclass
class _Context:
    tool: ToolSystem
    charges: Charges
    mesh: CheckMesh
    bounds: np.ndarray  # (2, 2) rad: [[a0, a1], [b0, b1]]
    tol_mm: float
    clearance_mm: float
    weight: float
    margin: float
    evals: int = 0

    def U(self, site: Site, th: np.ndarray, grad: bool = False) -> tuple[float, np.ndarray]:
        self.evals += 1
        return energy(
            self.tool, self.charges, site, th[0], th[1], self.tol_mm, self.clearance_mm, grad
        )

    def gate(self, site: Site, th: np.ndarray) -> Clearance:
        u, tip = place(self.tool, site, th[0], th[1])
        return check(self.mesh, self.tool, tip, u, self.tol_mm)


# ----------------------------------------------------------------------------------------------


def _gap(ctx: _Context, kappa: float, th: np.ndarray) -> float:
    K = float(szende_K(th[0], th[1], ctx.tool.R_mm, ctx.tool.r_mm))
    return min(K, K_CAP_PER_MM) - kappa


def _objective(
    ctx: _Context, kappa: float, prev: np.ndarray
) -> Callable[[np.ndarray], float]:
    R = ctx.tool.R_mm

    def J(th: np.ndarray) -> float:
        d = th - prev
        return R * _gap(ctx, kappa, th) + ctx.weight * float(d @ d)

    return J


def curvature_optimum(ctx: _Context, kappa: float, prev: np.ndarray) -> np.ndarray:
    """argmin of R (K - kappa) + w |theta - prev|^2 s.t. K - kappa >= margin.

    The best point of a vectorised 31 x 61 grid of the limits (K is closed-form, so this costs
    about 0.1 ms and cannot be trapped) is polished with SLSQP; the polish is kept only if it
    meets the constraint and improves the objective.
    """
    R, w = ctx.tool.R_mm, ctx.weight
    grid = _grid(ctx, 31, 61)
    K = np.minimum(szende_K(grid[:, 0], grid[:, 1], R, ctx.tool.r_mm), K_CAP_PER_MM)
    gap = K - kappa
    Jg = R * gap + w * ((grid - prev) ** 2).sum(1)
    free = gap >= ctx.margin
    if not free.any():
        # Nothing meets K - kappa >= margin (a concave radius tighter than the cutter can
        # follow): return the largest gap; the caller reports it if the check then fails.
        top: np.ndarray = grid[int(np.argmax(gap))]
        return top
    x0: np.ndarray = grid[int(np.argmin(np.where(free, Jg, np.inf)))]
    J = _objective(ctx, kappa, prev)
    r_mm = ctx.tool.r_mm

    def dJ(th: np.ndarray) -> np.ndarray:
        out: np.ndarray = R * szende_K_grad(th[0], th[1], R, r_mm) + 2 * w * (th - prev)
        return out

    cons = [
        {
            "type": "ineq",
            "fun": lambda th: _gap(ctx, kappa, th) - ctx.margin,
            "jac": lambda th: szende_K_grad(th[0], th[1], R, r_mm),
        }
    ]
    # scipy-stubs' overloads want a 1-d float64 array type for the objective's argument, which
    # numpy's np.ndarray annotations here do not spell: the call is checked by the tests
    res = minimize(  # type: ignore[call-overload]
        J,
        x0,
        jac=dJ,
        method="SLSQP",
        bounds=ctx.bounds,
        constraints=cons,
        options={"maxiter": 50, "ftol": 1e-12},
    )
    x: np.ndarray = np.clip(res.x, ctx.bounds[:, 0], ctx.bounds[:, 1])
    if np.all(np.isfinite(x)) and _gap(ctx, kappa, x) >= ctx.margin and J(x) <= J(x0):
        return x
    return x0


def _grid(ctx: _Context, na: int, nb: int) -> np.ndarray:
    a = np.linspace(float(ctx.bounds[0, 0]), float(ctx.bounds[0, 1]), na)
    b = np.linspace(float(ctx.bounds[1, 0]), float(ctx.bounds[1, 1]), nb)
    A, B = np.meshgrid(a, b, indexing="ij")
    return np.stack([A.ravel(), B.ravel()], 1)


def descend(
    ctx: _Context, site: Site, th: np.ndarray, iters: int = 12,
    path: list[np.ndarray] | None = None,
) -> tuple[np.ndarray, float]:  # fmt: skip
    """Seed 002's collision escape: move down grad U in (alpha, beta) until U = 0.

    U of eq 7 is a sum of 1/d over the charges inside the tool, so it changes in steps as charges
    leave; each iteration therefore tries steps of 0.5 .. 16 deg along -grad U and keeps the
    lowest U. Returns (theta, U); appends each accepted theta to ``path`` if given.
    """
    lo, hi = ctx.bounds[:, 0], ctx.bounds[:, 1]
    U, g = ctx.U(site, th, grad=True)
    steps = np.radians([0.5, 1.0, 2.0, 4.0, 8.0, 16.0])
    for _ in range(iters):
        gn = np.linalg.norm(g)
        if U == 0.0 or gn == 0:
            break
        best: tuple[np.ndarray, float] | None = None
        for s in steps:
            cand = np.clip(th - s * g / gn, lo, hi)
            Uc, _ = ctx.U(site, cand)
            if Uc < U and (best is None or Uc < best[1]):
                best = (cand, Uc)
            if Uc == 0.0:
                break
        if best is None:
            break
        th = best[0]
        if path is not None:
            path.append(th)
        U, g = ctx.U(site, th, grad=True)
    return th, U


def solve_point(
    ctx: _Context, site: Site, kappa: float, prev: np.ndarray
) -> tuple[np.ndarray | None, str, float, Clearance | None]:
    """(theta (2,) rad or None, reason, U, Clearance) for one CC point."""
    th_c = curvature_optimum(ctx, kappa, prev)
    if _free(ctx, site, kappa, th_c):
        gate = ctx.gate(site, th_c)
        if gate.ok:
            return th_c, "", 0.0, gate
    # A collision-free start: the neighbour's answer, else the grid best-first, else descent.
    p = np.clip(prev, ctx.bounds[:, 0], ctx.bounds[:, 1])
    th_f: np.ndarray | None = p if _free(ctx, site, kappa, p) else None
    if th_f is None:
        # The neighbour's answer sits on the edge of its free set; step back from the optimum.
        away = p - th_c
        if np.linalg.norm(away) > 1e-9:
            away /= np.linalg.norm(away)
            for d in np.radians([0.5, 1.5, 4.0]):
                cand = np.clip(p + d * away, ctx.bounds[:, 0], ctx.bounds[:, 1])
                if _free(ctx, site, kappa, cand):
                    th_f = cand
                    break
    if th_f is None:
        th_f = _best_first(ctx, site, kappa, prev, budget=40)
    if th_f is None:
        # Seed 002's way out: down the energy gradient from the curvature optimum.
        th_d, U_d = descend(ctx, site, th_c)
        if U_d == 0.0 and _gap(ctx, kappa, th_d) >= ctx.margin:
            th_f = th_d
    if th_f is None:
        th_f = _best_first(ctx, site, kappa, prev, budget=None)
    if th_f is None:
        return None, _why_infeasible(ctx, site), np.nan, None
    th = _towards(ctx, site, kappa, th_f, th_c)
    th = _polish(ctx, site, kappa, prev, th)
    for cand in (th, th_f):
        gate = ctx.gate(site, cand)
        if gate.ok:
            return cand, "", 0.0, gate
    th_f = _best_first(ctx, site, kappa, prev, budget=None)
    if th_f is not None:
        return th_f, "", 0.0, ctx.gate(site, th_f)
    return None, _why_infeasible(ctx, site), np.nan, None


def _towards(ctx: _Context, site: Site, kappa: float, th_f: np.ndarray, th_c: np.ndarray,
             steps: int = 6) -> np.ndarray:  # fmt: skip
    """Furthest point from the collision-free th_f towards th_c still free (bisection on U = 0)."""
    good, bad = 0.0, 1.0
    for _ in range(steps):
        t = 0.5 * (good + bad)
        if _free(ctx, site, kappa, th_f + t * (th_c - th_f)):
            good = t
        else:
            bad = t
    out: np.ndarray = th_f + good * (th_c - th_f)
    return out


_COMPASS = np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]])


def _polish(ctx: _Context, site: Site, kappa: float, prev: np.ndarray, th: np.ndarray,
            budget: int = 16) -> np.ndarray:  # fmt: skip
    """Compass search on the objective inside U = 0: from th, try steps of 4, 2, 1, 0.5 deg
    along +-alpha, +-beta and the diagonals, best predicted first, taking the first that lowers
    the objective and stays free.

    The collision-free set is often a band (seed 002 Fig. 8); this walks along it towards
    better curvature matching at a cost of at most ``budget`` energy evaluations.
    """
    J = _objective(ctx, kappa, prev)
    lo, hi = ctx.bounds[:, 0], ctx.bounds[:, 1]
    best = J(th)
    step = np.radians(4.0)
    used = 0
    while step >= np.radians(0.5) and used < budget:
        points = [np.clip(th + d, lo, hi) for d in step * _COMPASS]
        cands = sorted((J(c), i, c) for i, c in enumerate(points) if J(c) < best - 1e-12)
        moved = False
        for jc, _, c in cands:
            if used >= budget:
                break
            used += 1
            if _free(ctx, site, kappa, c):
                th, best, moved = c, jc, True
                break
        if not moved:
            step /= 2
    return th


def _free(ctx: _Context, site: Site, kappa: float, th: np.ndarray) -> bool:
    return _gap(ctx, kappa, th) >= ctx.margin and ctx.U(site, th)[0] == 0.0


def _best_first(
    ctx: _Context, site: Site, kappa: float, prev: np.ndarray, budget: int | None,
    below: float = np.inf, gate: bool = True,
) -> np.ndarray | None:  # fmt: skip
    """The grid orientation of least objective with U = 0 (and passing the check if ``gate``).

    The 16 x 37 grid of the limits is sorted by the closed-form objective (cheap) and U is
    evaluated in that order, at most ``budget`` times (all when None), only below ``below``.
    """
    grid = _grid(ctx, 16, 37)
    R = ctx.tool.R_mm
    gap = np.minimum(szende_K(grid[:, 0], grid[:, 1], R, ctx.tool.r_mm), K_CAP_PER_MM) - kappa
    J = R * gap + ctx.weight * ((grid - prev) ** 2).sum(1)
    ok = (gap >= ctx.margin) & (J < below)
    order = np.argsort(np.where(ok, J, np.inf))[: int(ok.sum())]
    for k in order if budget is None else order[:budget]:
        if ctx.U(site, grid[k])[0] == 0.0 and (not gate or ctx.gate(site, grid[k]).ok):
            hit: np.ndarray = grid[k]
            return hit
    return None


def _why_infeasible(ctx: _Context, site: Site) -> str:
    """Name what collides at the least-energy orientation of a coarse grid."""
    grid = _grid(ctx, 11, 31)
    Us = np.array([ctx.U(site, g)[0] for g in grid])
    k = int(np.argmin(Us))
    gate = ctx.gate(site, grid[k])
    a0, a1 = np.degrees(ctx.bounds[0])
    b0, b1 = np.degrees(ctx.bounds[1])
    what = (
        f"{gate.part} hits {gate.surface} by {-gate.min_mm:.3g} mm"
        if not gate.ok
        else "every collision-free orientation has K - kappa below the margin (overcut)"
    )
    return (
        f"no collision-free orientation within alpha {a0:g}..{a1:g} deg, beta {b0:g}..{b1:g} deg; "
        f"least energy at alpha {np.degrees(grid[k][0]):.1f} deg, beta "
        f"{np.degrees(grid[k][1]):.1f} deg: U = {Us[k]:.3g}, {what}"
    )
