"""planning.orient.planner on the three seed 002 test models, checked independently of the energy.

The independent check here is a second implementation: points sampled on the tool system's
surfaces of revolution (cutter with its corner radius, holder, spindle nose, with their end faces)
are tested against the part's dense triangle mesh by exact point-to-triangle distance (Ericson's
closest-point-on-triangle, vectorised; trimesh's own closest_point needs rtree, which cutlab does
not depend on); a tool point that lies behind a triangle (against its normal, which faces the
tool) with its foot inside that triangle is a collision or gouge.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from planning.errors import PlanningError
from planning.orient import ToolSystem, load_orient, verify
from planning.orient.planner import axis_jumps_deg, plan_orientation, require_feasible

ROOT = Path(__file__).resolve().parent.parent
MODELS = ["impeller", "fan", "mask"]


def tool_surface_points(tool: ToolSystem, tip, u, ds_tip=0.1, ds_side=0.3, ds_body=0.6):
    """Points on the tool system's surfaces of revolution, (k, 3) mm (independent of its SD)."""
    R, r, L = tool.R_mm, tool.r_mm, tool.cutter_length_mm
    Rh, Lh, Rn, Ln = (
        tool.holder_radius_mm,
        tool.holder_length_mm,
        tool.nose_radius_mm,
        tool.nose_length_mm,
    )

    def line(a, b, ds):
        n = max(2, int(np.ceil(np.hypot(*(np.subtract(b, a))) / ds)) + 1)
        return np.linspace(a, b, n)

    # Finest where the cutter cuts (bottom and corner), coarser up the flank and the body.
    prof = [line((0, 0), (R - r, 0), ds_tip)]
    if r > 0:
        t = np.linspace(-np.pi / 2, 0, max(3, int(np.ceil(r * np.pi / 2 / ds_tip)) + 1))
        prof.append(np.stack([R - r + r * np.cos(t), r + r * np.sin(t)], 1))
    side = [line((R, r), (R, min(L, r + 3.0)), ds_tip), line((R, min(L, r + 3.0)), (R, L), ds_side)]
    z1, z2 = L + Lh, L + Lh + Ln
    body = [
        line((R, L), (Rh, L), ds_body),
        line((Rh, L), (Rh, z1), ds_body),
        line((Rh, z1), (Rn, z1), ds_body),
        line((Rn, z1), (Rn, z2), ds_body),
    ]
    e1 = np.cross(u, [1.0, 0, 0] if abs(u[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    out = []
    parts = [(p, ds_tip) for p in prof] + list(zip(side, (ds_tip, ds_side)))
    for pr, ds in parts + [(p, ds_body) for p in body]:
        for rho, z in pr:
            k = max(8, int(np.ceil(2 * np.pi * rho / ds)))
            th = np.linspace(0, 2 * np.pi, k, endpoint=False)
            ring = rho * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)
            out.append(tip + z * u + ring)
    return np.concatenate(out)


def closest_on_triangles(p, a, b, c):
    """Closest points on triangles (a, b, c) to points p, all (k, 3) (Ericson, RTCD 5.1.5)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 / (va + vb + vc)
        v, w = vb * denom, vc * denom
        out = a + ab * v[:, None] + ac * w[:, None]  # inside the face
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    conds = [
        (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
        b + (c - b) * t_bc[:, None],
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),
        a + ac * t_ac[:, None],
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),
        a + ab * t_ab[:, None],
        (d6 >= 0) & (d5 <= d6),
        c,
        (d3 >= 0) & (d4 <= d3),
        b,
        (d1 <= 0) & (d2 <= 0),
        a,
    ]
    for k in range(0, len(conds), 2):
        out = np.where(conds[k][:, None], conds[k + 1], out)
    interior = ~np.any(np.stack(conds[0::2]), axis=0)
    return out, interior


def chord_sag_mm(surfaces, spacing_mm):
    """Upper estimate of how far a mesh triangle lies off its surface: kappa_max h^2 / 8, with h
    the triangle diagonal and kappa_max the largest normal curvature met on the surface."""
    from planning.surface import NurbsSurface

    k = 0.0
    for s in surfaces:
        sp = s.evaluate(*s.grid(60, 60))
        for d in (sp.su, sp.sv, sp.su + sp.sv, sp.su - sp.sv):
            k = max(k, float(np.abs(NurbsSurface.normal_curvature(sp, d)).max()))
    return k * 2 * spacing_mm**2 / 8


def trimesh_collisions(surfaces, tool, tips, axes, tol_mm, spacing_mm=0.3):
    """Count placements with a tool surface point behind the part mesh by more than tol_mm plus
    the mesh's chord sag (a triangle of a concave surface lies above it, towards the tool)."""
    tol_mm = tol_mm + chord_sag_mm(surfaces, spacing_mm)
    verts, faces, off = [], [], 0
    for s in surfaces:
        v, f = s.triangulate(spacing_mm)
        verts.append(v)
        faces.append(f + off)
        off += len(v)
    V, Fc = np.concatenate(verts), np.concatenate(faces)
    fn = np.cross(V[Fc[:, 1]] - V[Fc[:, 0]], V[Fc[:, 2]] - V[Fc[:, 0]])
    fn /= np.linalg.norm(fn, axis=1)[:, None]
    # Faces around each vertex, padded; a point's candidates are the faces of its 4 nearest
    # vertices (the mesh is regular and fine, so the nearest face is among them).
    fv = Fc.ravel()
    fi = np.repeat(np.arange(len(Fc)), 3)
    order = np.argsort(fv, kind="stable")
    fv, fi = fv[order], fi[order]
    counts = np.bincount(fv, minlength=len(V))
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    inc_arr = np.repeat(fi[start][:, None], counts.max(), axis=1)  # padded with a real face
    inc_arr[fv, np.arange(len(fv)) - start[fv]] = fi
    tree = cKDTree(V)
    bad, worst = 0, 0.0
    for tip, u in zip(tips, axes):
        q = tool_surface_points(tool, tip, u)
        # Only tool points near the part can be behind it by a little; a deep collision still
        # shows here, where the tool's surface crosses the part's (depth 0..0.3 mm there).
        d1, _ = tree.query(q, k=1, distance_upper_bound=0.5)
        q = q[np.isfinite(d1)]
        d, nv = tree.query(q, k=4)
        if len(q) == 0:
            continue
        nv = np.where(nv < len(V), nv, nv[:, :1])
        cand = inc_arr[nv].reshape(len(q), -1)  # (k, 4 * width)
        qq = np.repeat(q, cand.shape[1], axis=0)
        cf = cand.ravel()
        c, interior = closest_on_triangles(qq, V[Fc[cf, 0]], V[Fc[cf, 1]], V[Fc[cf, 2]])
        dist = np.linalg.norm(qq - c, axis=1).reshape(len(q), -1)
        j = np.argmin(dist, axis=1)
        rows = np.arange(len(q))
        best_face = cand[rows, j]
        foot = c.reshape(len(q), -1, 3)[rows, j]
        inside = interior.reshape(len(q), -1)[rows, j]
        s = ((q - foot) * fn[best_face]).sum(1)
        depth = np.where(inside, -s, 0.0)
        worst = max(worst, float(depth.max()))
        bad += bool(np.any(depth > tol_mm))
    return bad, worst


# The mask (75 points, ~10 s of planning and checks) in CI's command (long): the impeller and the
# fan run the same planner and the same independent checks in the quick tier.
@pytest.fixture(scope="module", params=[
    m if m != "mask" else pytest.param(m, marks=pytest.mark.long) for m in MODELS])  # fmt: skip
def planned(request):
    cfg, tool_cfg, machine = load_orient(ROOT / "configs" / "orient" / f"{request.param}.toml")
    res = plan_orientation(cfg, tool_cfg)
    return request.param, cfg, tool_cfg, res


def test_every_point_has_a_valid_orientation(planned):
    name, cfg, tool_cfg, res = planned
    assert res.n_points == {"impeller": 40, "fan": 30, "mask": 75}[name]  # seed 002 Table 1
    assert res.feasible.all(), res.reasons
    a0, a1 = cfg.limits.alpha_deg
    b0, b1 = cfg.limits.beta_deg
    assert np.all((res.alpha_deg >= a0 - 1e-9) & (res.alpha_deg <= a1 + 1e-9))
    assert np.all((res.beta_deg >= b0 - 1e-9) & (res.beta_deg <= b1 + 1e-9))
    assert np.allclose(np.linalg.norm(res.axis, axis=1), 1.0, atol=1e-12)
    # Angle between axis and normal is what (alpha, beta) say.
    cosang = (res.axis * res.cc.normal).sum(1)
    assert np.allclose(cosang, np.cos(np.radians(res.alpha_deg)) * np.cos(np.radians(res.beta_deg)))
    assert np.all(res.gap_per_mm >= -1e-9)  # K - kappa >= 0: no local overcut
    assert np.all(res.energy == 0.0)  # eq 7: U = 0
    assert np.allclose(res.centre_mm - res.tip_mm, tool_cfg.corner_radius_mm * res.axis)
    jumps = axis_jumps_deg(res.axis, res.cc.line)
    assert res.max_jump_deg == pytest.approx(np.nanmax(jumps))


def test_zero_collisions_on_a_fresh_dense_mesh(planned):
    _, cfg, tool_cfg, res = planned
    surfaces = [s.build() for s in cfg.surfaces]
    tool = ToolSystem.from_endmill(tool_cfg)
    ver = verify(surfaces, tool, res.tip_mm, res.axis, 0.22, cfg.planner.gouge_tolerance_mm)
    assert ver.checked == res.n_points
    assert ver.collisions == 0, ver.worst


def test_zero_collisions_by_trimesh_point_to_triangle(planned):
    name, cfg, tool_cfg, res = planned
    surfaces = [s.build() for s in cfg.surfaces]
    tool = ToolSystem.from_endmill(tool_cfg)
    step = 6  # every 6th orientation here; all of them in the slow test below
    bad, worst = trimesh_collisions(
        surfaces, tool, res.tip_mm[::step], res.axis[::step], cfg.planner.gouge_tolerance_mm
    )
    assert bad == 0, f"{name}: deepest tool point behind the part {worst:.4f} mm"


@pytest.mark.slow
def test_zero_collisions_by_trimesh_all_points(planned):
    name, cfg, tool_cfg, res = planned
    surfaces = [s.build() for s in cfg.surfaces]
    tool = ToolSystem.from_endmill(tool_cfg)
    bad, worst = trimesh_collisions(
        surfaces, tool, res.tip_mm, res.axis, cfg.planner.gouge_tolerance_mm
    )
    assert bad == 0, f"{name}: deepest tool point behind the part {worst:.4f} mm"


def test_trimesh_check_does_catch_a_collision():
    """The independent check is not blind: a tool pushed 0.5 mm into the floor is caught."""
    cfg, tool_cfg, _ = load_orient(ROOT / "configs" / "orient" / "fan.toml")
    res = plan_orientation(
        cfg.model_copy(
            update={"paths": cfg.paths.model_copy(update={"lines": (0.5,), "points_per_line": 3})}
        ),
        tool_cfg,
    )
    surfaces = [s.build() for s in cfg.surfaces]
    tool = ToolSystem.from_endmill(tool_cfg)
    sunk = res.tip_mm - 0.5 * res.cc.normal
    bad, worst = trimesh_collisions(surfaces, tool, sunk, res.axis, cfg.planner.gouge_tolerance_mm)
    assert bad == 3 and worst == pytest.approx(0.5, abs=0.05)
    ver = verify(surfaces, tool, sunk, res.axis, 0.3, cfg.planner.gouge_tolerance_mm)
    assert ver.collisions == 3


def test_limits_without_a_collision_free_orientation_are_reported():
    cfg, tool_cfg, _ = load_orient(ROOT / "configs" / "orient" / "impeller.toml")
    tight = cfg.model_copy(
        update={
            "limits": cfg.limits.model_copy(
                update={"alpha_deg": (10.0, 10.0), "beta_deg": (60.0, 65.0)}
            ),
            "paths": cfg.paths.model_copy(update={"lines": (0.5,), "points_per_line": 2}),
        }
    )
    res = plan_orientation(tight, tool_cfg)
    assert not res.feasible.any()
    assert np.isnan(res.axis[~res.feasible]).all()  # nothing is output for those points
    assert (
        "no collision-free orientation within alpha 10..10 deg, beta 60..65 deg" in res.reasons[0]
    )
    assert "hits blade" in res.reasons[0]
    with pytest.raises(PlanningError, match=r"CC point 0 \(line 0, u = .*: no collision-free"):
        require_feasible(res)
