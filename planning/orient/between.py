"""Verification between CL points as the machine moves, and refinement until it holds.

The control interpolates every axis linearly between two blocks (X, Y, Z, tilt, C), so between
two CL points the tool tip leaves the chord and the tool axis sweeps what the rotary axes make of
it. Each move is sampled in machine-axis space (so that the tip moves at most ``step_mm`` and the
axis turns at most ``step_deg`` between samples), mapped back to the part by forward kinematics,
and checked:

* the tool tip's deviation from the intended path, the chord between the two CL tips;
* collision of the tool system with the part and the fixtures, by an independent mesh check:
  python-fcl with the part as a BVH of its triangles (trimesh-style mesh of the NURBS surfaces),
  the cutter as the convex solid of revolution shrunk by the gouge tolerance (a polygon drawn
  round its outline, so it is never smaller than the true shrunk cutter), the holder and the
  spindle nose as cylinders, the fixtures as boxes;
* overcut: how deep the part's NURBS surfaces reach into the (unshrunk) cutter, found exactly on
  the surfaces (:mod:`planning.orient.overcut`). The fcl cutter is shrunk by the mesh's chord sag
  as well, and on convex areas the triangles lie under the surface, so fcl alone let the straight
  moves between two CL points dig 0.01 mm into the mask where each point only touches it.

:func:`refine` inserts CC points (on the surface, half way in parameter; orientation interpolated
and re-planned if that collides) into every move that deviates by more than the tolerance,
collides, overcuts by more than ``Scene.gouge_limit_mm``, turns the axis by more than
``max_jump_deg`` or swings C by more than
``max_c_step_deg``, until every move passes (or a round limit, reported).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import fcl
import numpy as np
import trimesh

from analysis.config import MachineConfig
from planning.errors import PlanningError
from planning.orient._energy import Site
from planning.orient._search import _Context, _free, solve_point
from planning.orient.kinematics import AxisMoves, five_axis_kind, forward, hold_c, inverse
from planning.orient.overcut import OvercutCheck
from planning.orient.planner import CCPoints, axis_jumps_deg, cc_at
from planning.orient.smooth import angles_of
from planning.orient.tool import ToolSystem, cutter_position, tool_axis
from planning.surface import NurbsSurface

# Overcut allowed between CL points, as a share of the gouge tolerance: the rest covers the part
# of a move between its samples (0.25 mm apart: a 0.01 mm bump over a 0.85 mm move can peak
# 0.0004 mm above the nearest sample).
GOUGE_SHARE = 0.9
N_ROUND = 120  # polygon sides round the axis: a 6 mm radius is drawn 0.002 mm too large at most
_Cache = dict[int, tuple[np.ndarray, np.ndarray]]  # point -> orientations (k, 2) rad, free


def _rotation_to(axis: np.ndarray) -> np.ndarray:
    """A rotation matrix taking +Z to the unit ``axis``."""
    z = np.asarray(axis, float)
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], 1)


def _revolved_convex(profile: np.ndarray) -> fcl.Convex:
    """Convex solid of revolution about +Z through the (rho, z) outline points, circumscribed:
    every polygon round the axis has its sides tangent to the true circle."""
    ang = np.linspace(0, 2 * np.pi, N_ROUND, endpoint=False)
    scale = 1.0 / np.cos(np.pi / N_ROUND)
    pts = [
        np.stack([rho * scale * np.cos(ang), rho * scale * np.sin(ang), np.full(N_ROUND, z)], 1)
        for rho, z in profile
    ]
    hull = trimesh.convex.convex_hull(np.concatenate(pts))
    faces = np.concatenate([np.full((len(hull.faces), 1), 3), hull.faces], 1).ravel()
    return fcl.Convex(np.asarray(hull.vertices, float), len(hull.faces), faces)


def chord_sag_mm(surfaces: Sequence[NurbsSurface], spacing_mm: float) -> float:
    """Upper estimate of how far a mesh triangle lies off its surface: kappa_max h^2 / 8, h the
    triangle's diagonal, kappa_max the largest normal curvature on a 60 x 60 grid."""
    k = 0.0
    for s in surfaces:
        sp = s.evaluate(*s.grid(60, 60))
        for d in (sp.su, sp.sv, sp.su + sp.sv, sp.su - sp.sv):
            k = max(k, float(np.abs(NurbsSurface.normal_curvature(sp, d)).max()))
    return k * 2 * spacing_mm**2 / 8


@dataclass
class Scene:
    """fcl objects: the part (one BVH of all surfaces) and fixtures; the tool system's parts in
    their own frame (tip at the origin, axis +Z): (name, geometry, z offset of its frame)."""

    part: fcl.CollisionObject
    fixtures: list[tuple[str, fcl.CollisionObject]]
    tool: list[tuple[str, fcl.CollisionObject, float]]
    spacing_mm: float
    tolerance_mm: float
    overcut: OvercutCheck
    gouge_limit_mm: float
    # move's axes (bytes) -> (overcut mm, where)
    _cache: dict[bytes, tuple[float, str]] = field(default_factory=dict, repr=False)

    @classmethod
    def build(
        cls,
        surfaces: Sequence[NurbsSurface],
        tool: ToolSystem,
        spacing_mm: float,
        tol_mm: float,
        fixtures: Sequence[tuple[str, Sequence[float], Sequence[float]]] = (),
    ) -> Scene:
        """``fixtures``: (name, min corner, max corner) boxes in mm, workpiece frame. The cutter
        is shrunk by ``tol_mm`` plus the mesh's chord sag (:func:`chord_sag_mm`): a triangle of
        a concave surface lies that much above it, towards the tool; overcut (exact, on the
        surfaces) is allowed up to ``GOUGE_SHARE`` of ``tol_mm``."""
        limit_mm = GOUGE_SHARE * tol_mm
        tol_mm = tol_mm + chord_sag_mm(surfaces, spacing_mm)
        verts, faces, off = [], [], 0
        for s in surfaces:
            v, f = s.triangulate(spacing_mm)
            verts.append(v)
            faces.append(f + off)
            off += len(v)
        V, F = np.concatenate(verts), np.concatenate(faces)
        bvh = fcl.BVHModel()
        bvh.beginModel(len(V), len(F))
        bvh.addSubModel(V, F)
        bvh.endModel()
        part = fcl.CollisionObject(bvh, fcl.Transform())
        fix = []
        for name, lo_mm, hi_mm in fixtures:
            lo, hi = np.asarray(lo_mm, float), np.asarray(hi_mm, float)
            box = fcl.Box(*(hi - lo))
            fix.append((name, fcl.CollisionObject(box, fcl.Transform(0.5 * (lo + hi)))))
        # The cutter shrunk by the tolerance: ring radius R - r, corner radius r - tol (or a
        # flat bottom raised by tol), side R - tol.
        R, r, L = tool.R_mm, tool.r_mm, tool.cutter_length_mm
        rr = max(r - tol_mm, 0.0)
        k = 24  # circumscribed arc of 24 points: at most r * 0.0006 outside the true corner
        t = np.linspace(-np.pi / 2, 0, k)
        corner = np.stack([(R - r) + rr * np.cos(t), r + rr * np.sin(t)], 1)
        if r > 0:  # circumscribe the corner arc: scale its offsets from the arc centre
            c = np.array([R - r, r])
            corner = c + (corner - c) / np.cos(0.5 * (t[1] - t[0]))
        prof = np.vstack([[[0.0, tol_mm]], corner, [[R - tol_mm, L]], [[0.0, L]]])
        prof[:, 1] = np.maximum(prof[:, 1], tol_mm)
        parts = [("cutter", _revolved_convex(prof), 0.0)]
        for name, z0, z1, a in tool.parts()[1:]:
            parts.append((name, fcl.Cylinder(a, z1 - z0), 0.5 * (z0 + z1)))
        objs = [(n, fcl.CollisionObject(g, fcl.Transform()), dz) for n, g, dz in parts]
        over = OvercutCheck(surfaces, tool, spacing_mm)
        return cls(part, fix, objs, spacing_mm, tol_mm, over, limit_mm)

    def hit(self, tip: np.ndarray, axis: np.ndarray) -> str:
        """'' when the tool placed at ``tip`` along ``axis`` touches nothing, else what hits
        what (e.g. 'holder hits part')."""
        R = _rotation_to(axis)
        for name, obj, dz in self.tool:
            obj.setTransform(fcl.Transform(R, tip + dz * axis))
            for other, o2 in (("part", self.part), *self.fixtures):
                if fcl.collide(obj, o2, fcl.CollisionRequest(), fcl.CollisionResult()):
                    return f"{name} hits {other}"
        return ""


@dataclass(frozen=True)
class MoveCheck:
    """Per move i (CL point i to i + 1; NaN / '' across lines): the tip's largest deviation from
    the chord (mm), what collides ('' none), the largest overcut (mm, exact, on the surfaces) and
    where ('' none), the samples taken."""

    deviation_mm: np.ndarray
    hits: tuple[str, ...]
    samples: int
    overcut_mm: np.ndarray
    overcut_at: tuple[str, ...]

    @property
    def collisions(self) -> int:
        return sum(bool(h) for h in self.hits)


def check_moves(
    machine: MachineConfig,
    moves: AxisMoves,
    tips_mm: np.ndarray,
    line: np.ndarray,
    gauge_length_mm: float,
    scene: Scene,
    step_mm: float = 0.25,
    step_deg: float = 0.25,
) -> MoveCheck:
    """Sample every move of a line linearly in machine axes and check it (module docstring)."""
    P = moves.as_array()
    m = len(P)
    dev = np.full(max(m - 1, 0), np.nan)
    over = np.full(max(m - 1, 0), np.nan)
    hits, where = [""] * max(m - 1, 0), [""] * max(m - 1, 0)
    total = 0
    for i in range(m - 1):
        if line[i + 1] != line[i]:
            continue
        d = np.abs(P[i + 1] - P[i])
        n = int(max(2, np.ceil(max(np.linalg.norm(d[:3]) / step_mm, d[3:].max() / step_deg))))
        s = np.linspace(0.0, 1.0, n + 1)[1:-1, None]  # the CL points themselves: verify()
        Q = P[i] + s * (P[i + 1] - P[i])
        mv = AxisMoves(Q[:, 0], Q[:, 1], Q[:, 2], Q[:, 3], Q[:, 4], moves.kind)
        tips, axes = forward(moves.kind, machine, mv, gauge_length_mm)
        a, b = tips_mm[i], tips_mm[i + 1]
        ab = b - a
        t = np.clip((tips - a) @ ab / max(ab @ ab, 1e-300), 0.0, 1.0)
        dev[i] = float(np.linalg.norm(tips - (a + t[:, None] * ab), axis=1).max())
        total += len(s)
        for tip, u in zip(tips, axes):
            h = scene.hit(tip, u)
            if h:
                hits[i] = h
                break
        key = P[i : i + 2].tobytes()  # refinement re-checks unchanged moves: measured once
        if key not in scene._cache:
            got = [scene.overcut.depth(tip, u) for tip, u in zip(tips, axes)]
            k = int(np.argmax([g.depth_mm for g in got]))
            at = f"in {got[k].surface} at {np.round(got[k].point, 2).tolist()} mm"
            scene._cache[key] = (got[k].depth_mm, at if got[k].depth_mm > 0 else "")
        over[i], where[i] = scene._cache[key]
    return MoveCheck(dev, tuple(hits), total, over, tuple(where))


@dataclass(frozen=True)
class Refined:
    """The CL points after refinement: CC points, planned angles (m, 2) rad, posted axes and
    tips (after :func:`planning.orient.kinematics.hold_c`), machine moves, the last check,
    inserted count, rounds, and the reason refinement stopped short ('' when all passed)."""

    cc: CCPoints
    theta: np.ndarray
    axis: np.ndarray
    tip_mm: np.ndarray
    moves: AxisMoves
    check: MoveCheck
    inserted: int
    rounds: int
    unresolved: str


def posted(ctx: _Context, cc: CCPoints, theta: np.ndarray, machine: MachineConfig, cone_deg: float,
           start_c_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray, AxisMoves]:  # fmt: skip
    """Axes held near the singularity, tips for them, machine moves."""
    u = tool_axis(theta[:, 0], theta[:, 1], cc.binormal, cc.feed, cc.normal)
    u = hold_c(five_axis_kind(machine), u, cc.line, cone_deg)
    tip, _ = cutter_position(cc.point, cc.normal, u, ctx.tool.R_mm, ctx.tool.r_mm)
    moves = inverse(machine, tip, u, ctx.tool.gauge_length_mm, start_c_deg=start_c_deg,
                    line=cc.line)  # fmt: skip
    return u, tip, moves


def refine(
    ctx: _Context,
    surface: NurbsSurface,
    along: str,
    cc: CCPoints,
    theta: np.ndarray,
    machine: MachineConfig,
    scene: Scene,
    tol_mm: float,
    max_jump_deg: float = 5.0,
    max_c_step_deg: float = 30.0,
    cone_deg: float = 3.0,
    max_rounds: int = 10,
    min_step_mm: float = 0.02,
) -> Refined:
    """Insert CC points until every move passes (see the module docstring); a move shorter than
    ``min_step_mm`` on the part that collides or turns the axis too far is not split further
    (that is the CC point's, not the move's). Deviation and C steps still are: near the C
    axis a short move on the part can swing C by degrees, and halving it quarters the tip's
    deviation."""
    theta = np.asarray(theta, float)
    inserted, unresolved = 0, ""
    for rounds in range(1, max_rounds + 1):
        u, tip, moves = posted(ctx, cc, theta, machine, cone_deg)
        chk = check_moves(machine, moves, tip, cc.line, ctx.tool.gauge_length_mm, scene)
        jump = axis_jumps_deg(u, cc.line)
        dc = np.abs(np.diff(moves.c_deg))
        gouge = chk.overcut_mm > scene.gouge_limit_mm
        bad = (chk.deviation_mm > tol_mm) | np.array([bool(h) for h in chk.hits], bool) | gouge
        bad |= (jump > max_jump_deg) | ((dc > max_c_step_deg) & (cc.line[1:] == cc.line[:-1]))
        bad &= cc.line[1:] == cc.line[:-1]
        short = np.linalg.norm(np.diff(cc.point, axis=0), axis=1) < min_step_mm
        short &= np.array([bool(h) for h in chk.hits], bool) | (jump > max_jump_deg) | gouge
        if (bad & short).any():
            bad &= short  # report the first move that cannot be split further
            break
        if not bad.any():
            return Refined(cc, theta, u, tip, moves, chk, inserted, rounds, "")
        if rounds == max_rounds:
            break
        # Pieces per bad move: the deviation falls with the square of the step, the turns with it.
        k = np.flatnonzero(bad)
        dev = np.nan_to_num(chk.deviation_mm[k])
        pieces = np.maximum.reduce(
            [
                np.ceil(np.sqrt(dev / tol_mm)),
                np.ceil(np.sqrt(np.nan_to_num(chk.overcut_mm[k]) / scene.gouge_limit_mm)),
                np.ceil(np.nan_to_num(jump[k]) / max_jump_deg),
                np.ceil(dc[k] / max_c_step_deg),
                np.full(len(k), 2.0),
            ]
        )
        cc, theta, added = _insert(
            ctx, surface, along, cc, theta, k, np.minimum(pieces, 16), max_jump_deg
        )
        inserted += added
        if not added:
            break
    f = int(np.flatnonzero(bad)[0])
    unresolved = (
        f"move {f} -> {f + 1} (line {cc.line[f]}): deviation {chk.deviation_mm[f]:.4f} mm, "
        f"axis turn {jump[f]:.2f} deg, C step {dc[f]:.2f} deg, {chk.hits[f] or 'no collision'}, "
        f"overcut {chk.overcut_mm[f]:.4f} mm {chk.overcut_at[f]}".rstrip()
        + f" after {rounds} rounds"
    )
    return Refined(cc, theta, u, tip, moves, chk, inserted, rounds, unresolved)


def _insert(ctx: _Context, surface: NurbsSurface, along: str, cc: CCPoints, theta: np.ndarray,
            moves_idx: np.ndarray, pieces: np.ndarray,
            max_turn_deg: float = 5.0) -> tuple[CCPoints, np.ndarray, int]:  # fmt: skip
    """CC points splitting the moves ``moves_idx`` into ``pieces`` equal steps in parameter, on
    the surface with its normal there (:func:`cc_at`); the orientation is the blend of the
    neighbours' axes in the new frame, clipped to the limits. Where a blended orientation
    collides, the move's points are re-oriented together (:func:`_reorient`): re-planning each
    one alone picks either side of a collision island and the tool flips between them. Returns
    the new cc, theta and how many were inserted."""
    reps = np.asarray(pieces, int) - 1
    i = np.repeat(np.asarray(moves_idx), reps)
    w = np.concatenate([np.arange(1, n + 1) / (n + 1) for n in reps])
    um, vm = cc.u[i] + w * (cc.u[i + 1] - cc.u[i]), cc.v[i] + w * (cc.v[i + 1] - cc.v[i])
    par = cc.u if along == "u" else cc.v
    sign = np.where(par[i + 1] >= par[i], 1.0, -1.0)
    new = cc_at(surface, along, um, vm, sign, cc.line[i])
    u0 = tool_axis(theta[:, 0], theta[:, 1], cc.binormal, cc.feed, cc.normal)
    mean = (1 - w[:, None]) * u0[i] + w[:, None] * u0[i + 1]
    mean /= np.linalg.norm(mean, axis=1)[:, None]
    th_new = np.clip(angles_of(mean, new.binormal, new.feed, new.normal), *ctx.bounds.T)
    pos = np.concatenate([np.arange(len(theta)), i + w])
    order = np.argsort(pos, kind="stable")
    cc2 = CCPoints(
        *(
            np.concatenate([getattr(cc, f), getattr(new, f)])[order]
            for f in CCPoints.__dataclass_fields__
        )
    )
    th2 = np.concatenate([theta, th_new])[order]
    rank = np.empty(len(order), int)
    rank[order] = np.arange(len(order))
    is_new = np.arange(len(order)) >= len(theta)
    ok = np.ones(len(order), bool)
    ok[rank[is_new]] = False
    cache: _Cache = {}
    for k in np.asarray(moves_idx):
        s, e = int(rank[k]), int(rank[k + 1])
        if all(_placed_ok(ctx, cc2, th2[j], j) for j in range(s + 1, e)):
            ok[s + 1 : e] = True
            continue
        got = _reorient(ctx, cc2, th2, s, e, max_turn_deg, cache)
        if got is not None:
            a, b, th_ab = got
            th2[a : b + 1] = th_ab
            ok[a : b + 1] = True
    # What the joint re-orientation could not place: each point alone, as the planner would.
    for j in np.flatnonzero(~ok):
        site = _site(cc2, int(j))
        th, _, _, _ = solve_point(ctx, site, float(cc2.kappa_per_mm[j]), th2[j])
        if th is not None:
            th2[j], ok[j] = th, True
    keep = ok | ~is_new[order]
    added = int((keep & is_new[order]).sum())
    if not added:
        return cc, theta, 0
    cc3 = CCPoints(*(getattr(cc2, f)[keep] for f in CCPoints.__dataclass_fields__))
    return cc3, th2[keep], added


def _site(cc: CCPoints, j: int) -> Site:
    return Site(cc.point[j], cc.normal[j], cc.binormal[j], cc.feed[j])


def _placed_ok(ctx: _Context, cc: CCPoints, th: np.ndarray, j: int) -> bool:
    site = _site(cc, j)
    return _free(ctx, site, float(cc.kappa_per_mm[j]), th) and ctx.gate(site, th).ok


def _nodes(ctx: _Context, cc: CCPoints, j: int, theta: np.ndarray, s: int, e: int,
           cache: _Cache) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Candidate orientations (k, 2) rad at point j and which are free of the energy's collision
    and of local overcut (cached per point): the current one, the planner's answer from there,
    the axes of the move's ends s and e held in j's frame (for a short move the best path is
    often one of these), and a grid of the advance limits by the tilt within 35 deg of the
    current one (2.5 deg steps)."""
    if j not in cache:
        site, kap = _site(cc, j), float(cc.kappa_per_mm[j])
        a0, a1 = ctx.bounds[0]
        a = np.linspace(a0, a1, max(2, int(np.ceil((a1 - a0) / np.radians(2.5))) + 1))
        w = np.radians(35.0)
        b = np.arange(-w, w + 1e-9, np.radians(2.5)) + theta[j, 1]
        b = b[(b >= ctx.bounds[1, 0]) & (b <= ctx.bounds[1, 1])]
        A, B = np.meshgrid(a, b, indexing="ij")
        ends = tool_axis(theta[[s, e], 0], theta[[s, e], 1], cc.binormal[[s, e]],
                         cc.feed[[s, e]], cc.normal[[s, e]])  # fmt: skip
        held = np.clip(angles_of(ends, cc.binormal[j], cc.feed[j], cc.normal[j]), *ctx.bounds.T)
        cands = [theta[j][None], held, np.stack([A.ravel(), B.ravel()], 1)]
        got, _, _, _ = solve_point(ctx, site, kap, theta[j])
        if got is not None:
            cands.insert(1, got[None])
        th = np.vstack(cands)
        cache[j] = (th, np.array([_free(ctx, site, kap, t) for t in th]))
    return cache[j]


def _reorient(ctx: _Context, cc: CCPoints, theta: np.ndarray, s: int, e: int,
              max_turn_deg: float, cache: _Cache) -> tuple[int, int, np.ndarray] | None:
    """Orientations for points s..e of one line, chosen together: a shortest path (dynamic
    programming) through each point's collision-free grid orientations, the cost the sum of
    squared axis turns between neighbours (plus a little for leaving the current orientation),
    no turn above twice ``max_turn_deg`` (the next round inserts points into what is left above
    it), the end points held. The collision-free set at a point can be two islands within the
    lead/tilt limits (on the mask's cheek the upright tool collides and only a tilt either way
    is free); then only a path that keeps to one island from far enough back exists, so while
    there is none the stretch grows (twice as far each time, to the whole line, whose ends are
    then free too). Every chosen orientation is gated on the dense check mesh; one that fails
    is struck out and the path searched again. Returns (first, last, theta (k, 2)) or None."""
    line = cc.line[s]
    on = np.flatnonzero(cc.line == line)
    lo_i, hi_i = int(on[0]), int(on[-1])
    grow = 1
    while True:
        a, b = max(s - (grow - 1), lo_i), min(e + (grow - 1), hi_i)
        got = _shortest(ctx, cc, theta, a, b, (s, e), a > lo_i, b < hi_i, max_turn_deg, cache)
        if got is not None:
            return a, b, got
        if a == lo_i and b == hi_i:
            return None
        grow *= 2


def _shortest(ctx: _Context, cc: CCPoints, theta: np.ndarray, a: int, b: int, move: tuple[int, int],
              hold_a: bool, hold_b: bool, max_turn_deg: float,
              cache: _Cache) -> np.ndarray | None:  # fmt: skip
    nodes, free = [], []
    for j in range(a, b + 1):
        if (j == a and hold_a) or (j == b and hold_b):
            nodes.append(theta[j][None])
            free.append(np.ones(1, bool))
        else:
            th, fr = _nodes(ctx, cc, j, theta, *move, cache)
            nodes.append(th)
            free.append(fr.copy())
    lim = np.radians(2 * max_turn_deg)
    pref = 0.05  # weight of leaving the current orientation, against the turns
    for _ in range(8):
        axes = [
            tool_axis(t[:, 0], t[:, 1], cc.binormal[j], cc.feed[j], cc.normal[j])
            for j, t in zip(range(a, b + 1), nodes)
        ]
        here = [
            np.arccos(np.clip(x @ x[0], -1, 1)) ** 2 * pref
            if not ((j == a and hold_a) or (j == b and hold_b))
            else np.zeros(1)
            for j, x in zip(range(a, b + 1), axes)
        ]
        cost = np.where(free[0], here[0], np.inf)
        back = []
        for k in range(1, len(nodes)):
            turn = np.arccos(np.clip(axes[k - 1] @ axes[k].T, -1.0, 1.0))
            step = np.where(turn <= lim, turn**2, np.inf) + cost[:, None]
            arg = np.argmin(step, axis=0)
            cost = step[arg, np.arange(len(arg))] + np.where(free[k], here[k], np.inf)
            back.append(arg)
        if not np.isfinite(cost).any():
            return None
        pick = [int(np.argmin(cost))]
        for arg in reversed(back):
            pick.append(int(arg[pick[-1]]))
        pick.reverse()
        th = np.array([nodes[k][p] for k, p in enumerate(pick)])
        failed = False
        for k, j in enumerate(range(a, b + 1)):
            held = (j == a and hold_a) or (j == b and hold_b)
            if not held and not ctx.gate(_site(cc, j), th[k]).ok:
                free[k][pick[k]] = False
                failed = True
        if not failed:
            return th
    return None


def require_refined(ref: Refined) -> None:
    """PlanningError when refinement could not make every move pass."""
    if ref.unresolved:
        raise PlanningError(f"between CL points: {ref.unresolved}")
