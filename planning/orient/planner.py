"""Collision-free 5-axis tool orientation by the potential-energy method (seed 002, Cho & Lee).

At every CC point of the given paths the advance angle alpha (about b) and tilt angle beta (about
f) are chosen to minimise the curvature gap K - kappa (eq 8, Szende's swept-surface curvature K
against the part's normal curvature kappa across the feed) subject to U = 0 (eq 7, no collision)
and K - kappa >= 0 (no local overcut), within the angle limits.

The paper used the ADS optimiser; here the search for one point (scipy's SLSQP for the
curvature, the paper's gradient descent on U, bisection and a compass search along the
collision-free set, and a final check on a dense mesh independent of the energy) lives in
:mod:`planning.orient._search`. Beyond the paper, a smoothness term w |theta - theta_prev|^2
(``smoothness_weight``) in the objective and a warm start from the neighbour's answer keep the axis
from jumping between neighbouring CC points -- the paper's own stated weakness -- and the largest
jump is reported. A point with no collision-free orientation in the limits gets no orientation
(NaN) and a reason; :func:`require_feasible` turns those into one PlanningError.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from analysis.config import EndMill
from planning.errors import PlanningError
from planning.orient._energy import Charges, Site
from planning.orient._search import _Context, curvature_optimum, descend, solve_point
from planning.orient.check import CheckMesh
from planning.orient.config import OrientConfig
from planning.orient.tool import (
    ToolSystem,
    cutter_position,
    local_frame,
    szende_K,
    tool_axis,
)
from planning.surface import NurbsSurface


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
    max_jump_deg is the largest angle between the axes of neighbouring CC points on a line (it
    includes the turn of the surface normal; max_jump_at is the later point's index);
    max_angle_jump_deg the largest change of (alpha, beta), hypot of both, between them.
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
    max_angle_jump_deg: float

    @property
    def n_points(self) -> int:
        return len(self.alpha_deg)


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
    sign = np.concatenate(
        [
            np.full(ps.points_per_line, -1.0 if (ps.zigzag and i % 2) else 1.0)
            for i in range(len(ps.lines))
        ]
    )
    return cc_at(surface, ps.along, u, v, sign, np.concatenate(line))


def cc_at(
    surface: NurbsSurface,
    along: str,
    u: npt.ArrayLike,
    v: npt.ArrayLike,
    sign: npt.ArrayLike,
    line: npt.ArrayLike,
) -> CCPoints:
    """CC points at parameters (u, v), the feed along +-``along`` (``sign`` per point)."""
    sp = surface.evaluate(np.asarray(u, float), np.asarray(v, float))
    tangent = (sp.su if along == "u" else sp.sv) * np.asarray(sign, float)[:, None]
    b, f, n = local_frame(sp.normal, tangent)
    kappa = NurbsSurface.normal_curvature(sp, b)
    return CCPoints(np.asarray(u, float), np.asarray(v, float), sp.point, n, f, b, kappa,
                    np.asarray(line))  # fmt: skip


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
    """Orientation at every CC point of ``cfg`` (see the module docstring); the smooth field
    of :mod:`planning.orient.smooth` is a step of its own (``smooth_result``)."""
    surfaces = [s.build() for s in cfg.surfaces]
    machined = surfaces[[s.role for s in cfg.surfaces].index("machined")]
    cc = cc_points(machined, cfg)
    ctx = build_context(cfg, tool_cfg, surfaces)
    return solve_all(ctx, cc, progress)


def solve_all(
    ctx: _Context, cc: CCPoints, progress: Callable[[int, int], None] | None = None
) -> OrientResult:
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
            assert gate is not None  # (solve_point gives the check with every answer)
            th_out[i], U_out[i], clr[i] = th, U, gate.min_mm
            prev = th
        if progress:
            progress(i + 1, m)
    return assemble(ctx, cc, th_out, U_out, clr, tuple(reasons), secs, nev)


def assemble(
    ctx: _Context,
    cc: CCPoints,
    th_out: np.ndarray,
    U_out: np.ndarray,
    clr: np.ndarray,
    reasons: tuple[str, ...],
    secs: np.ndarray,
    nev: np.ndarray,
) -> OrientResult:
    """The OrientResult of angles th_out (m, 2) rad (NaN rows: infeasible) at CC points cc."""
    m = len(cc.u)
    ok = ~np.isnan(th_out[:, 0])
    u = np.full((m, 3), np.nan)
    tip, centre = np.full((m, 3), np.nan), np.full((m, 3), np.nan)
    if ok.any():
        u[ok] = tool_axis(th_out[ok, 0], th_out[ok, 1], cc.binormal[ok], cc.feed[ok], cc.normal[ok])
        tip[ok], centre[ok] = cutter_position(
            cc.point[ok], cc.normal[ok], u[ok], ctx.tool.R_mm, ctx.tool.r_mm
        )
    K = szende_K(th_out[:, 0], th_out[:, 1], ctx.tool.R_mm, ctx.tool.r_mm)
    jumps = axis_jumps_deg(u, cc.line)
    j = int(np.nanargmax(jumps)) if np.isfinite(jumps).any() else -1
    dth = np.degrees(np.hypot(*np.diff(th_out, axis=0).T))
    dth[cc.line[1:] != cc.line[:-1]] = np.nan
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
        reasons,
        secs,
        nev,
        float(jumps[j]) if j >= 0 else float("nan"),
        j + 1 if j >= 0 else -1,
        float(np.nanmax(dth)) if np.isfinite(dth).any() else float("nan"),
    )


def axis_jumps_deg(axis: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Angle (deg) between the tool axes of consecutive CC points on the same line, shape (m-1,);
    NaN across lines or where a point is infeasible."""
    c = np.clip((axis[1:] * axis[:-1]).sum(1), -1.0, 1.0)
    out: npt.NDArray[np.float64] = np.degrees(np.arccos(c))
    out[line[1:] != line[:-1]] = np.nan
    return out


# ----------------------------------------------------------------------------------------------


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
    a = np.linspace(ctx.bounds[0, 0], ctx.bounds[0, 1], n_alpha)
    b = np.linspace(ctx.bounds[1, 0], ctx.bounds[1, 1], n_beta)
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
