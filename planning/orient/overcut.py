"""How deep the part's surfaces reach inside the cutter: exact, on the NURBS surfaces themselves.

A mesh check sees the surface only at its vertices (or its triangles, which lie under a convex
surface and over a concave one), so between them a gouge of about kappa h^2 / 8 goes unseen --
on the mask that hid 0.01 mm of overcut in the middle of moves. Here every surface is sampled on
a parameter grid about ``spacing_mm`` apart; the cutter's signed distance is taken at the grid
points within reach, and from every grid point that is a local minimum of it (and close enough
to the cutter that the surface between grid points could enter it) the minimum is followed on
the surface itself by a pattern search in (u, v) that quarters its step down to ``precision_mm``.
The deepest of those minima is the overcut.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from planning.orient.tool import ToolSystem, meridian
from planning.surface import NurbsSurface

# The pattern search's 5 x 5 stencil (in half steps), and a grid point's 8 neighbours.
_STENCIL = np.array([(i, j) for i in range(-2, 3) for j in range(-2, 3)], float) / 2
_NEIGHBOURS = [(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1) if (i, j) != (0, 0)]


@dataclass
class _Grid:
    surface: NurbsSurface
    u: np.ndarray  # (n_u,) parameters
    v: np.ndarray  # (n_v,)
    offset: int  # index of its first vertex in the stacked vertices


@dataclass(frozen=True)
class Overcut:
    """Result of one placement: depth of the part inside the cutter (mm, 0 when outside), the
    deepest point (3,) mm and the surface's name."""

    depth_mm: float
    point: np.ndarray
    surface: str


class OvercutCheck:
    """Exact overcut of placed cutters against NURBS surfaces (module docstring)."""

    def __init__(
        self,
        surfaces: Sequence[NurbsSurface],
        tool: ToolSystem,
        spacing_mm: float = 0.3,
        precision_mm: float = 1e-3,
    ) -> None:
        self.tool = tool
        self.grids: list[_Grid] = []
        verts, off = [], 0
        self.spacing_mm = float(spacing_mm)
        for s in surfaces:
            lu, lv = s.size_mm()
            n_u = max(2, int(np.ceil(lu / spacing_mm)) + 1)
            n_v = max(2, int(np.ceil(lv / spacing_mm)) + 1)
            u, v = np.linspace(*s.u_range, n_u), np.linspace(*s.v_range, n_v)
            U, V = np.meshgrid(u, v, indexing="ij")
            verts.append(s.points(U.ravel(), V.ravel()))
            self.grids.append(_Grid(s, u, v, off))
            off += n_u * n_v
        self.vertices = np.concatenate(verts)
        self.tree = cKDTree(self.vertices)
        # Each level of the search quarters its step; the depth's error is quadratic in it.
        self.levels = int(np.ceil(np.log(spacing_mm / precision_mm) / np.log(4)))
        # Between grid points the surface can come closer to the cutter than at them by about
        # (kappa_surface + 1/r) h^2 / 8 over a cell diagonal h; seeds must be that close.
        k = max(_max_curvature(s) for s in surfaces) + 1.0 / max(tool.r_mm, spacing_mm)
        self.seed_mm = k * 2 * spacing_mm**2 / 8 + 1e-3
        z = np.arange(0.0, tool.cutter_length_mm + tool.R_mm, 2 * tool.R_mm)
        self._z_st = np.minimum(z + tool.R_mm, tool.cutter_length_mm)
        self._r_st = np.hypot(tool.R_mm, tool.R_mm) + self.seed_mm

    def depth(self, tip: np.ndarray, axis: np.ndarray) -> Overcut:
        """The cutter at ``tip`` (3,) along the unit ``axis`` (3,): how deep the part is in it."""
        tip, axis = np.asarray(tip, float), np.asarray(axis, float)
        hits = self.tree.query_ball_point(tip + self._z_st[:, None] * axis, self._r_st)
        idx = np.unique(np.concatenate([np.asarray(h, np.intp) for h in hits]))
        none = Overcut(0.0, np.full(3, np.nan), "")
        if not len(idx):
            return none
        sd = np.full(len(self.vertices), np.inf)
        rho, z = meridian(self.vertices[idx], tip, axis)
        sd[idx] = self.tool.cutter_distance(rho, z)
        best = none
        for g in self.grids:
            seeds = self._seeds(g, sd)
            if not len(seeds):
                continue
            d, p = self._descend(g, seeds, tip, axis)
            if -d > best.depth_mm:
                best = Overcut(float(-d), p, g.surface.name)
        return best

    def _seeds(self, g: _Grid, sd: np.ndarray) -> np.ndarray:
        """(k, 2) grid indices of the local minima of sd on grid g closer than seed_mm."""
        n_u, n_v = len(g.u), len(g.v)
        S = sd[g.offset : g.offset + n_u * n_v].reshape(n_u, n_v)
        near = np.argwhere(S < self.seed_mm)
        if not len(near):
            return near
        pad = np.pad(S, 1, constant_values=np.inf)
        c = pad[near[:, 0] + 1, near[:, 1] + 1]
        keep = np.ones(len(near), bool)
        for i, j in _NEIGHBOURS:
            keep &= c <= pad[near[:, 0] + 1 + i, near[:, 1] + 1 + j]
        return near[keep]

    def _descend(
        self, g: _Grid, seeds: np.ndarray, tip: np.ndarray, axis: np.ndarray
    ) -> tuple[float, np.ndarray]:
        """Pattern search for the least cutter distance on the surface from each seed; returns
        the least distance and its point."""
        s = g.surface
        (u0, u1), (v0, v1) = s.u_range, s.v_range
        uv = np.stack([g.u[seeds[:, 0]], g.v[seeds[:, 1]]], 1)
        h = 0.75 * np.array([g.u[1] - g.u[0], g.v[1] - g.v[0]])  # reaches a cell
        lo, hi = np.array([u0, v0]), np.array([u1, v1])
        for _ in range(self.levels):
            cand = np.clip(uv[:, None, :] + _STENCIL[None] * h, lo, hi).reshape(-1, 2)
            rho, z = meridian(s.points(cand[:, 0], cand[:, 1]), tip, axis)
            d = self.tool.cutter_distance(rho, z).reshape(len(uv), len(_STENCIL))
            uv = cand.reshape(len(uv), len(_STENCIL), 2)[np.arange(len(uv)), d.argmin(1)]
            h = h / 4
        P = s.points(uv[:, 0], uv[:, 1])
        rho, z = meridian(P, tip, axis)
        d = self.tool.cutter_distance(rho, z)
        k = int(np.argmin(d))
        return float(d[k]), P[k]


def _max_curvature(s: NurbsSurface) -> float:
    """Largest normal curvature (1/mm) of ``s`` on a 60 x 60 grid, along u, v and diagonals."""
    sp = s.evaluate(*s.grid(60, 60))
    k = 0.0
    for d in (sp.su, sp.sv, sp.su + sp.sv, sp.su - sp.sv):
        k = max(k, float(np.abs(NurbsSurface.normal_curvature(sp, d)).max()))
    return k
