"""Independent collision and gouge check of 5-axis orientations against a dense triangle mesh.

Separate from the energy on purpose: it takes the part surfaces as a dense triangle mesh
(``check_spacing_mm``, every vertex exactly on the NURBS surface) and measures the exact signed
distance of every mesh vertex within reach to the tool system's solid of revolution (cutter with
its corner radius, holder, spindle nose). An orientation passes when no vertex is deeper inside the
cutter than the gouge tolerance and none is inside the holder or the spindle nose.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from planning.orient.tool import ToolSystem, meridian
from planning.surface import NurbsSurface

PART_NAMES = ("cutter", "holder", "spindle nose")


@dataclass(frozen=True)
class CheckMesh:
    """Dense mesh of the part: vertices (m, 3) mm, faces (k, 3), surface index per vertex."""

    vertices: np.ndarray
    faces: np.ndarray
    surface: np.ndarray
    names: tuple[str, ...]
    tree: cKDTree

    @classmethod
    def build(cls, surfaces: Sequence[NurbsSurface], spacing_mm: float) -> CheckMesh:
        verts, faces, sid, off = [], [], [], 0
        for i, s in enumerate(surfaces):
            v, f = s.triangulate(spacing_mm)
            verts.append(v)
            faces.append(f + off)
            sid.append(np.full(len(v), i))
            off += len(v)
        V = np.concatenate(verts)
        return cls(
            V,
            np.concatenate(faces),
            np.concatenate(sid),
            tuple(s.name for s in surfaces),
            cKDTree(V),
        )


@dataclass(frozen=True)
class Clearance:
    """Result of checking one orientation.

    ok : no gouge deeper than the tolerance and nothing inside holder/nose
    min_mm : smallest signed distance of any mesh vertex to the tool system (< 0 inside), mm
    part, surface : names of the tool part and part surface at the worst vertex
    worst_point : (3,) mm
    """

    ok: bool
    min_mm: float
    part: str
    surface: str
    worst_point: np.ndarray


def check(
    mesh: CheckMesh, tool: ToolSystem, tip: np.ndarray, u: np.ndarray, tol_mm: float
) -> Clearance:
    """Exact vertex-to-tool signed distances for one placement (tip (3,), unit axis u (3,))."""
    z_st, r_st = tool.stations()
    centres = tip + z_st[:, None] * u
    hits = mesh.tree.query_ball_point(centres, r_st + 1.0, return_sorted=False)
    found = [np.asarray(h, dtype=np.intp) for h in hits if len(h)]
    if not found:
        return Clearance(True, np.inf, "", "", np.full(3, np.nan))
    idx = np.unique(np.concatenate(found))
    rho, z = meridian(mesh.vertices[idx], tip, u)
    sd, which = tool.signed_distance(rho, z)
    # Penetration beyond what is allowed, per part: cutter tolerance, holder/nose none.
    excess = np.where(which == 0, sd + tol_mm, sd)
    k = int(np.argmin(excess))
    j = idx[k]
    return Clearance(
        bool(excess[k] >= 0),
        float(sd[k]),
        PART_NAMES[int(which[k])],
        mesh.names[int(mesh.surface[j])],
        mesh.vertices[j],
    )


@dataclass(frozen=True)
class Verification:
    """Every output orientation checked on a fresh mesh: counts and the smallest clearance.

    collisions : number of orientations with a vertex inside holder/nose or deeper than the
    tolerance inside the cutter; worst : (index, Clearance) of the smallest excess, or None.
    """

    checked: int
    collisions: int
    spacing_mm: float
    tolerance_mm: float
    min_clearance_mm: np.ndarray
    worst: tuple[int, Clearance] | None


def verify(
    surfaces: Sequence[NurbsSurface],
    tool: ToolSystem,
    tip_mm: np.ndarray,
    axis: np.ndarray,
    spacing_mm: float,
    tol_mm: float,
) -> Verification:
    """Check each placement (tip (m, 3), axis (m, 3); NaN rows skipped) on a new mesh."""
    mesh = CheckMesh.build(surfaces, spacing_mm)
    mins = np.full(len(tip_mm), np.nan)
    bad, worst = 0, None
    for i, (t, u) in enumerate(zip(tip_mm, axis)):
        if not np.all(np.isfinite(t)):
            continue
        c = check(mesh, tool, t, u, tol_mm)
        mins[i] = c.min_mm
        bad += not c.ok
        if not c.ok and (worst is None or c.min_mm < worst[1].min_mm):
            worst = (i, c)
    n = int(np.isfinite(mins).sum())
    return Verification(n, bad, spacing_mm, tol_mm, mins, worst)
