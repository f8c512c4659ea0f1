"""Collision-free 5-axis tool orientation by the potential-energy method (seed 002, Cho & Lee).

At every CC point of the given paths the advance angle alpha (about b) and tilt angle beta (about
f) are chosen to minimise the curvature gap K - kappa (eq 8, Szende's swept-surface curvature K
against the part's normal curvature kappa across the feed) subject to U = 0 (eq 7, no collision)
and K - kappa >= 0 (no local overcut), within the angle limits.

How the constraints are met (the paper used the ADS optimiser; here scipy):

1. Curvature: ``scipy.optimize.minimize`` (SLSQP) minimises R (K - kappa) + w |theta -
   theta_prev|^2 subject to K - kappa >= margin and the bounds, started from the previous CC
   point's answer. The second term is beyond the paper: its stated weakness is that the
   orientation can jump between neighbouring CC points; w = ``smoothness_weight``.
2. Collision: if U > 0 there, U is descended along its analytic gradient in (alpha, beta)
   (seed 002 section 3: "moving down the gradient reaches U = 0"). U is flat (zero) on the whole
   collision-free set, which gives a gradient optimiser nothing to hold on to as an equality
   constraint, so the final answer is the point nearest the curvature optimum on the segment
   between it and the collision-free start found by descent, by bisection on U = 0.
3. If descent stalls, a coarse scan of the limits looks for any collision-free orientation; if there
   is none, the point is reported infeasible with the reason (which tool part hits which
   surface), and no orientation is output for it.
4. Every answer is verified against the dense check mesh (:mod:`planning.orient_check`), a check
   independent of the energy; an answer that fails it is never output.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from analysis.config import EndMill
from planning._energy import Charges, Site, energy, place
from planning.errors import PlanningError
from planning.nurbs import NurbsSurface
from planning.orient_check import CheckMesh, check
from planning.orient_config import OrientConfig
from planning.orient_tool import ToolSystem, local_frame, szende_K, szende_K_grad

K_CAP_PER_MM = 1e3  # stands in for the flat end mill's infinite K at alpha = 0, beta != 0


@dataclass(frozen=True)
class CCPoints:
    """CC points in path order: parameters (m,), position/normal/frame (m, 3), kappa (m,) 1/mm,
    line (m,) index of the iso-parameter line each point belongs to."""

    u: np.ndarray
    v: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    feed: np.ndarray
    binormal: np.ndarray
    kappa_per_mm: np.ndarray
    line: np.ndarray


@dataclass(frozen=True)
class OrientResult:
    """Orientation per CC point (arrays shape (m,) or (m, 3)); NaN where infeasible.

    tip_mm is the tool tip (bottom centre on the axis), centre_mm the cutter centre (tip + r u),
    axis the unit tool axis; clearance_mm the check mesh's smallest signed distance to the tool
    (about 0 at the contact); energy the eq 7 value at the answer (0 when feasible).
    """

    cc: CCPoints
    alpha_deg: np.ndarray
    beta_deg: np.ndarray
    axis: np.ndarray
    tip_mm: np.ndarray
    centre_mm: np.ndarray
    K_per_mm: np.ndarray
    gap_per_mm: np.ndarray
    energy: np.ndarray
    clearance_mm: np.ndarray
    feasible: np.ndarray
    reasons: tuple[str, ...]
    seconds: np.ndarray
    evaluations: np.ndarray
    max_jump_deg: float
    max_jump_at: int

    @property
    def n_points(self) -> int:
        return len(self.alpha_deg)


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

    def U(self, site: Site, th, grad: bool = False):
        self.evals += 1
        return energy(
            self.tool, self.charges, site, th[0], th[1], self.tol_mm, self.clearance_mm, grad
        )

    def gate(self, site: Site, th):
        u, tip = place(self.tool, site, th[0], th[1])
        return check(self.mesh, self.tool, tip, u, self.tol_mm)


# ----------------------------------------------------------------------------------------------


def cc_points(surface: NurbsSurface, cfg: OrientConfig) -> CCPoints:
    """CC points on the iso-parameter lines of ``cfg.paths`` with frames and kappa."""
    ps = cfg.paths
    us, vs, line = [], [], []
    for i, frac in enumerate(ps.lines):
        u, v = surface.iso_path(ps.along, frac, ps.points_per_line, ps.span)
        if ps.zigzag and i % 2:
            u, v = u[::-1], v[::-1]
        us.append(u)
        vs.append(v)
        line.append(np.full(len(u), i))
    u, v = np.concatenate(us), np.concatenate(vs)
    sp = surface.evaluate(u, v)
    sign = np.concatenate(
        [
            np.full(ps.points_per_line, -1.0 if (ps.zigzag and i % 2) else 1.0)
            for i in range(len(ps.lines))
        ]
    )
    tangent = (sp.su if ps.along == "u" else sp.sv) * sign[:, None]
    b, f, n = local_frame(sp.normal, tangent)
    kappa = NurbsSurface.normal_curvature(sp, b)
    return CCPoints(u, v, sp.point, n, f, b, kappa, np.concatenate(line))


def build_context(cfg: OrientConfig, tool_cfg: EndMill, surfaces: list[NurbsSurface]) -> _Context:
    tool = ToolSystem.from_endmill(tool_cfg, cfg.tool)
    pl = cfg.planner
    pts, wts, sid = [], [], []
    for i, s in enumerate(surfaces):
        v, _ = s.triangulate(pl.charge_spacing_mm)
        pts.append(v)
        wts.append(np.full(len(v), pl.charge_spacing_mm**2))
        sid.append(np.full(len(v), i))
    charges = Charges.from_points(np.concatenate(pts), np.concatenate(wts), np.concatenate(sid))
    mesh = CheckMesh.build(surfaces, pl.check_spacing_mm)
    bounds = np.radians([cfg.limits.alpha_deg, cfg.limits.beta_deg])
    return _Context(
        tool,
        charges,
        mesh,
        bounds,
        0.5 * pl.gouge_tolerance_mm,  # half: the rest covers sampling between mesh vertices
        pl.clearance_mm,
        pl.smoothness_weight,
        pl.curvature_margin_per_mm,
    )


def plan_orientation(
    cfg: OrientConfig,
    tool_cfg: EndMill,
    progress: Callable[[int, int], None] | None = None,
) -> OrientResult:
    """Orientation at every CC point of ``cfg`` (see the module docstring)."""
    surfaces = [s.build() for s in cfg.surfaces]
    machined = surfaces[[s.role for s in cfg.surfaces].index("machined")]
    cc = cc_points(machined, cfg)
    ctx = build_context(cfg, tool_cfg, surfaces)
    return solve_all(ctx, cc, progress)


def solve_all(ctx: _Context, cc: CCPoints, progress=None) -> OrientResult:
    m = len(cc.u)
    th_out = np.full((m, 2), np.nan)
    U_out, clr, secs, nev = np.full(m, np.nan), np.full(m, np.nan), np.zeros(m), np.zeros(m, int)
    reasons: list[str] = []
    lo = ctx.bounds[:, 0]
    prev = np.array(
        [lo[0] + min(np.radians(3.0), np.ptp(ctx.bounds[0]) / 2), np.clip(0.0, *ctx.bounds[1])]
    )
    for i in range(m):
        t0 = time.perf_counter()
        e0 = ctx.evals
        site = Site(cc.point[i], cc.normal[i], cc.binormal[i], cc.feed[i])
        th, why, U, gate = solve_point(ctx, site, float(cc.kappa_per_mm[i]), prev)
        secs[i] = time.perf_counter() - t0
        nev[i] = ctx.evals - e0
        if th is None:
            reasons.append(
                f"CC point {i} (line {cc.line[i]}, u = {cc.u[i]:.4g}, v = {cc.v[i]:.4g}, "
                f"at {np.round(cc.point[i], 3).tolist()} mm): {why}"
            )
        else:
            th_out[i], U_out[i], clr[i] = th, U, gate.min_mm
            prev = th
        if progress:
            progress(i + 1, m)
    ok = ~np.isnan(th_out[:, 0])
    u = np.full((m, 3), np.nan)
    tip, centre = np.full((m, 3), np.nan), np.full((m, 3), np.nan)
    from planning.orient_tool import cutter_position, tool_axis

    if ok.any():
        u[ok] = tool_axis(th_out[ok, 0], th_out[ok, 1], cc.binormal[ok], cc.feed[ok], cc.normal[ok])
        tip[ok], centre[ok] = cutter_position(
            cc.point[ok], cc.normal[ok], u[ok], ctx.tool.R_mm, ctx.tool.r_mm
        )
    K = szende_K(th_out[:, 0], th_out[:, 1], ctx.tool.R_mm, ctx.tool.r_mm)
    jumps = axis_jumps_deg(u, cc.line)
    j = int(np.nanargmax(jumps)) if np.isfinite(jumps).any() else -1
    return OrientResult(
        cc,
        np.degrees(th_out[:, 0]),
        np.degrees(th_out[:, 1]),
        u,
        tip,
        centre,
        K,
        K - cc.kappa_per_mm,
        U_out,
        clr,
        ok,
        tuple(reasons),
        secs,
        nev,
        float(jumps[j]) if j >= 0 else float("nan"),
        j + 1 if j >= 0 else -1,
    )


def axis_jumps_deg(axis: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Angle (deg) between the tool axes of consecutive CC points on the same line, shape (m-1,);
    NaN across lines or where a point is infeasible."""
    c = np.clip((axis[1:] * axis[:-1]).sum(1), -1.0, 1.0)
    out = np.degrees(np.arccos(c))
    out[line[1:] != line[:-1]] = np.nan
    return out


# ----------------------------------------------------------------------------------------------


def _gap(ctx: _Context, kappa: float, th) -> float:
    K = float(szende_K(th[0], th[1], ctx.tool.R_mm, ctx.tool.r_mm))
    return min(K, K_CAP_PER_MM) - kappa


def _objective(ctx, kappa, prev):
    R = ctx.tool.R_mm

    def J(th):
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
        return grid[int(np.argmax(gap))]
    x0 = grid[int(np.argmin(np.where(free, Jg, np.inf)))]
    J = _objective(ctx, kappa, prev)
    r_mm = ctx.tool.r_mm

    def dJ(th):
        return R * szende_K_grad(th[0], th[1], R, r_mm) + 2 * w * (th - prev)

    cons = [
        {
            "type": "ineq",
            "fun": lambda th: _gap(ctx, kappa, th) - ctx.margin,
            "jac": lambda th: szende_K_grad(th[0], th[1], R, r_mm),
        }
    ]
    res = minimize(
        J,
        x0,
        jac=dJ,
        method="SLSQP",
        bounds=ctx.bounds,
        constraints=cons,
        options={"maxiter": 50, "ftol": 1e-12},
    )
    x = np.clip(res.x, ctx.bounds[:, 0], ctx.bounds[:, 1])
    if np.all(np.isfinite(x)) and _gap(ctx, kappa, x) >= ctx.margin and J(x) <= J(x0):
        return x
    return x0


def _grid(ctx: _Context, na: int, nb: int) -> np.ndarray:
    a = np.linspace(*ctx.bounds[0], na)
    b = np.linspace(*ctx.bounds[1], nb)
    A, B = np.meshgrid(a, b, indexing="ij")
    return np.stack([A.ravel(), B.ravel()], 1)


def descend(ctx: _Context, site: Site, th: np.ndarray, iters: int = 12, path=None):
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
        best = None
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


def solve_point(ctx: _Context, site: Site, kappa: float, prev: np.ndarray):
    """(theta (2,) rad or None, reason, U, Clearance) for one CC point."""
    th_c = curvature_optimum(ctx, kappa, prev)
    if _free(ctx, site, kappa, th_c):
        gate = ctx.gate(site, th_c)
        if gate.ok:
            return th_c, "", 0.0, gate
    # A collision-free start: the neighbour's answer, else the grid best-first, else descent.
    p = np.clip(prev, ctx.bounds[:, 0], ctx.bounds[:, 1])
    th_f = p if _free(ctx, site, kappa, p) else None
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


def _towards(ctx: _Context, site: Site, kappa: float, th_f, th_c, steps: int = 6):
    """Furthest point from the collision-free th_f towards th_c still free (bisection on U = 0)."""
    good, bad = 0.0, 1.0
    for _ in range(steps):
        t = 0.5 * (good + bad)
        if _free(ctx, site, kappa, th_f + t * (th_c - th_f)):
            good = t
        else:
            bad = t
    return th_f + good * (th_c - th_f)


_COMPASS = np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]])


def _polish(ctx: _Context, site: Site, kappa: float, prev, th, budget: int = 16):
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
        cands = [np.clip(th + d, lo, hi) for d in step * _COMPASS]
        cands = sorted((J(c), i, c) for i, c in enumerate(cands) if J(c) < best - 1e-12)
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


def _free(ctx: _Context, site: Site, kappa: float, th) -> bool:
    return _gap(ctx, kappa, th) >= ctx.margin and ctx.U(site, th)[0] == 0.0


def _best_first(ctx, site, kappa, prev, budget, below=np.inf, gate=True):
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
            return grid[k]
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


def require_feasible(res: OrientResult) -> None:
    """Raise PlanningError listing every infeasible CC point (nothing colliding is output)."""
    if not res.feasible.all():
        bad = res.reasons
        more = f"\n... and {len(bad) - 10} more" if len(bad) > 10 else ""
        raise PlanningError(
            f"{len(bad)} of {res.n_points} CC points have no collision-free orientation:\n"
            + "\n".join(bad[:10])
            + more
        )


@dataclass(frozen=True)
class EnergyMap:
    """U over the (alpha, beta) limits at one CC point (seed 002 Fig. 8).

    alpha_deg (na,), beta_deg (nb,), energy (na, nb); descent (k, 2) deg: the path of the
    gradient descent from the curvature optimum; chosen (2,) deg: the planner's answer.
    """

    index: int
    alpha_deg: np.ndarray
    beta_deg: np.ndarray
    energy: np.ndarray
    descent_deg: np.ndarray
    chosen_deg: np.ndarray


def energy_map(
    cfg: OrientConfig,
    tool_cfg: EndMill,
    index: int,
    result: OrientResult | None = None,
    n_alpha: int = 31,
    n_beta: int = 91,
) -> EnergyMap:
    """Evaluate eq 7 on an n_alpha x n_beta grid of the limits at CC point ``index``."""
    surfaces = [s.build() for s in cfg.surfaces]
    machined = surfaces[[s.role for s in cfg.surfaces].index("machined")]
    cc = cc_points(machined, cfg)
    if not 0 <= index < len(cc.u):
        raise PlanningError(f"energy map point {index} is outside 0..{len(cc.u) - 1}")
    ctx = build_context(cfg, tool_cfg, surfaces)
    site = Site(cc.point[index], cc.normal[index], cc.binormal[index], cc.feed[index])
    a = np.linspace(*ctx.bounds[0], n_alpha)
    b = np.linspace(*ctx.bounds[1], n_beta)
    E = np.array([[ctx.U(site, np.array([x, y]))[0] for y in b] for x in a])
    th_c = curvature_optimum(ctx, float(cc.kappa_per_mm[index]), np.array([a[0], 0.0]))
    path = [th_c]
    descend(ctx, site, th_c, path=path)
    chosen = (
        np.array([result.alpha_deg[index], result.beta_deg[index]])
        if result is not None
        else np.full(2, np.nan)
    )
    return EnergyMap(index, np.degrees(a), np.degrees(b), E, np.degrees(np.asarray(path)), chosen)
