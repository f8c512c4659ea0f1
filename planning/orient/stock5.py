"""Material removal of a posted 5-axis program, and gouge and leftover maps of the design surface.

The stock is a field of dexels along the design surface's normals (the "mow the grass" model of
5-axis NC verification, Jerard and Drysdale): one straight segment per point of a grid on the
machined surface, spaced ``spacing_mm`` (the resolution) in arc length, from ``below_mm`` under
the surface (how deep a gouge can be seen) to ``allowance_mm`` above it (the stock left by the
previous operation). Every move of the program is sampled as the control interpolates it (all
axes linearly between blocks, mapped back to the part by forward kinematics, the tip moving at
most ``step_mm`` and the axis turning at most ``step_deg`` between samples), and each sample of
the cutter cuts every dexel within reach down to where the dexel enters the cutter. What is left
of a dexel, its top's height over the design surface, is the map: negative is a gouge (material
cut below the design surface), positive is leftover (scallops, and untouched stock between the
paths). Along the normals the heights are exact, so a scallop is its height, not a distance.
Between two samples of the tool a corner of radius r leaves step^2 / (8 r) (0.0006 mm for a
2 mm corner at 0.1 mm steps), a sharp flat-end heel up to step * tan(lead) (0.027 mm at 15 deg):
for flat end mills the maps' figures carry that sampling error, both ways.

The cutter (flat, ball or bull, from the tool system) is convex: it is the set of points within
its corner radius r of the half-infinite cylinder of radius R - r above height r. Its signed
distance along a dexel is therefore a convex function of the position on the dexel, and where
the dexel enters the cutter is found by bisection (after a golden-section search for the
closest point when both dexel ends are outside), vectorised over all dexel-sample pairs with
numpy. Only the cutter cuts (holder and spindle nose are verified not to touch by
:mod:`planning.orient.between`); link moves between lines are not simulated.

Why not OpenCAMLib: its Python package (``pip install opencamlib``, 2023.1.11) offers
drop-cutter, push-cutter and waterline for a cutter along Z -- CL point generation for 3-axis
milling -- and no material-removal model; its octree cutting simulation is not in the package,
and nothing in it takes a tilted tool axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from analysis.config import MachineConfig
from planning.orient.kinematics import AxisMoves, forward
from planning.orient.tool import ToolSystem
from planning.surface import NurbsSurface

GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


@dataclass
class NormalDexels:
    """Dexels along the design surface normals: base points and unit normals (n_u, n_v, 3) on
    the surface, the top of what is left (n_u, n_v) mm along the normal (< 0 a gouge), the
    bottom (the deepest gouge that can be seen) mm, and the grid spacing (mm of arc length)."""

    point: np.ndarray
    normal: np.ndarray
    top_mm: np.ndarray
    bottom_mm: float
    spacing_mm: float

    @classmethod
    def on_surface(
        cls,
        surface: NurbsSurface,
        u_frac: tuple[float, float],
        v_frac: tuple[float, float],
        spacing_mm: float,
        allowance_mm: float = 1.0,
        below_mm: float = 0.5,
    ) -> NormalDexels:
        """Dexels on the part of ``surface`` between the fractions ``u_frac``, ``v_frac`` of its
        parameter ranges, about ``spacing_mm`` apart, stock ``allowance_mm`` thick."""
        lu, lv = surface.size_mm()
        n_u = max(2, int(np.ceil(lu * (u_frac[1] - u_frac[0]) / spacing_mm)) + 1)
        n_v = max(2, int(np.ceil(lv * (v_frac[1] - v_frac[0]) / spacing_mm)) + 1)
        (u0, u1), (v0, v1) = surface.u_range, surface.v_range
        uu = u0 + (u1 - u0) * np.linspace(*u_frac, n_u)
        vv = v0 + (v1 - v0) * np.linspace(*v_frac, n_v)
        U, V = np.meshgrid(uu, vv, indexing="ij")
        sp = surface.evaluate(U.ravel(), V.ravel())
        shape = (n_u, n_v)
        return cls(
            sp.point.reshape(*shape, 3),
            sp.normal.reshape(*shape, 3),
            np.full(shape, float(allowance_mm)),
            -float(below_mm),
            float(spacing_mm),
        )

    def cut(self, tips: np.ndarray, axes: np.ndarray, R_mm: float, r_mm: float,
            length_mm: float, chunk: int = 64) -> None:  # fmt: skip
        """Remove the cutter (radius R, corner radius r, flute length) placed at each tip (k, 3)
        along each unit axis (k, 3)."""
        q = self.point.reshape(-1, 3)
        nrm = self.normal.reshape(-1, 3)
        top = self.top_mm.reshape(-1)
        tree = cKDTree(q)
        reach = max(float(top.max()), -self.bottom_mm)
        # Spheres covering the cutter, grown by how far a dexel reaches from its base point.
        n_st = max(1, int(np.ceil(length_mm / (2 * R_mm))))
        h = length_mm / n_st
        z_st = h * (np.arange(n_st) + 0.5)
        r_st = np.hypot(R_mm, h / 2) + reach
        for s in range(0, len(tips), chunk):
            T, A = tips[s : s + chunk], axes[s : s + chunk]
            centres = (T[:, None, :] + z_st[None, :, None] * A[:, None, :]).reshape(-1, 3)
            hits = tree.query_ball_point(centres, r_st, return_sorted=False)
            poses: list[np.ndarray] = []
            idxs: list[np.ndarray] = []
            for k in range(len(T)):
                near = set().union(*hits[k * n_st : (k + 1) * n_st])
                if near:
                    idxs.append(np.fromiter(near, np.intp))
                    poses.append(np.full(len(idxs[-1]), k))
            if not idxs:
                continue
            idx, pose = np.concatenate(idxs), np.concatenate(poses)
            t_in = _entry(q[idx], nrm[idx], self.bottom_mm, top[idx], T[pose], A[pose], R_mm,
                          r_mm)  # fmt: skip
            np.minimum.at(top, idx, t_in)


def _entry(
    q: np.ndarray, n: np.ndarray, lo: float, hi: np.ndarray, tip: np.ndarray, axis: np.ndarray,
    R: float, r: float, iters: int = 36,
) -> np.ndarray:  # fmt: skip
    """Where each dexel q + t n, t in [lo, hi], first enters the cutter (hi where it does not):
    the cutter's signed distance along the dexel is convex in t (module docstring)."""
    d0 = q - tip
    coef = np.stack([(d0 * axis).sum(1), (n * axis).sum(1), (d0 * d0).sum(1), (d0 * n).sum(1)])
    core = R - r

    def f(t: np.ndarray, sel: np.ndarray) -> np.ndarray:
        z0, nz, dd, dn = coef[:, sel]
        z = z0 + t * nz
        rho = np.sqrt(np.maximum(dd + 2 * t * dn + t * t - z * z, 0.0))
        out: np.ndarray = np.hypot(np.maximum(rho - core, 0.0), np.maximum(r - z, 0.0)) - r
        return out

    every = np.arange(len(q))
    lo_t = np.full(len(q), float(lo))
    hi = np.asarray(hi, float)
    f_lo, f_hi = f(lo_t, every), f(hi, every)
    out = np.where(f_lo <= 0, lo_t, hi)
    first_in = hi.copy()  # a point inside the cutter for the dexels that enter it
    # Both ends outside: the closest point (golden section) decides whether the dexel passes
    # through the cutter; f is 1-Lipschitz, which rules most pairs out without a search.
    mid = np.flatnonzero((f_lo > 0) & (f_hi > 0) & (f_lo + f_hi <= hi - lo_t))
    a, b = lo_t[mid], hi[mid]
    for _ in range(iters):
        c1, c2 = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
        left = f(c1, mid) <= f(c2, mid)
        a, b = np.where(left, a, c1), np.where(left, c2, b)
    t_min = 0.5 * (a + b)
    through = f(t_min, mid) <= 0
    first_in[mid[through]] = t_min[through]
    # Bisection between lo (outside) and the point inside.
    cross = np.union1d(np.flatnonzero((f_lo > 0) & (f_hi <= 0)), mid[through])
    a, b = lo_t[cross], first_in[cross]
    for _ in range(iters):
        c = 0.5 * (a + b)
        inside = f(c, cross) <= 0
        a, b = np.where(inside, a, c), np.where(inside, c, b)
    out[cross] = b
    return out


def sample_program(
    machine: MachineConfig,
    moves: AxisMoves,
    line: np.ndarray,
    gauge_length_mm: float,
    step_mm: float,
    step_deg: float = 0.25,
) -> tuple[np.ndarray, np.ndarray]:
    """Tips and axes (k, 3) of the tool along every move within a line, as the control
    interpolates the axes, at most ``step_mm`` / ``step_deg`` apart (both CL points included)."""
    P = moves.as_array()
    tips, axes = [], []
    for i in range(len(P) - 1):
        if line[i + 1] != line[i]:
            continue
        d = np.abs(P[i + 1] - P[i])
        n = int(max(1, np.ceil(max(np.linalg.norm(d[:3]) / step_mm, d[3:].max() / step_deg))))
        s = np.linspace(0.0, 1.0, n + 1)[:, None]
        Q = P[i] + s * (P[i + 1] - P[i])
        mv = AxisMoves(Q[:, 0], Q[:, 1], Q[:, 2], Q[:, 3], Q[:, 4], moves.kind)
        t, a = forward(moves.kind, machine, mv, gauge_length_mm)
        tips.append(t)
        axes.append(a)
    if not tips:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return np.concatenate(tips), np.concatenate(axes)


@dataclass(frozen=True)
class StockFigures:
    """The maps' figures (mm): deepest gouge (0 when none), highest leftover, the share of the
    map still at the stock allowance (never touched), the resolution."""

    gouge_max_mm: float
    leftover_max_mm: float
    uncut_fraction: float
    spacing_mm: float
    step_mm: float


def figures(dexels: NormalDexels, allowance_mm: float, step_mm: float) -> StockFigures:
    top = dexels.top_mm
    return StockFigures(
        float(max(0.0, -top.min())),
        float(max(0.0, top.max())),
        float(np.mean(top >= allowance_mm - 1e-9)),
        dexels.spacing_mm,
        step_mm,
    )


def save_maps(dexels: NormalDexels, tol_mm: float, path: str | Path, title: str) -> Path:
    """Gouge (depth below the design surface) and leftover (height above it) side by side over
    the surface's arc lengths; the gouge scale marks the tolerance."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    P = dexels.point
    su = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P[:, P.shape[1] // 2], axis=0),
                                                         axis=1))])  # fmt: skip
    sv = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P[P.shape[0] // 2], axis=0),
                                                         axis=1))])  # fmt: skip
    top = dexels.top_mm
    gouge = np.maximum(-top, 0.0)
    left = np.maximum(top, 0.0)
    # a gouge panel only when a dexel is beyond the tolerance: a few um within it drew a blank
    # panel; those are marked on the leftover map instead
    gouged = bool(gouge.max() > tol_mm)
    # the panels take the surface's own proportions (a fixed 12 x 5 figure left white space)
    aspect = float(np.clip(su[-1] / max(sv[-1], 1e-9), 0.25, 4.0))
    n = 2 if gouged else 1
    fig, axs = plt.subplots(1, n, figsize=(5.2 * n + 1.2, 5.2 * aspect + 1.2), dpi=110,
                            squeeze=False)  # fmt: skip
    panels = list(axs[0])
    if gouged:
        vmax = max(float(gouge.max()), 2 * tol_mm)
        m0 = panels[0].pcolormesh(sv, su, gouge * 1e3, cmap="Reds", vmin=0, vmax=vmax * 1e3,
                               shading="auto")  # fmt: skip
        cb = fig.colorbar(m0, ax=panels[0], label="gouge below design surface (um)")
        cb.ax.axhline(tol_mm * 1e3, color="k", lw=1.5)
        over = int(np.sum(gouge > tol_mm))
        panels[0].set_title(f"gouge: max {gouge.max() * 1e3:.1f} um, {over} dexels beyond the "
                         f"tolerance {tol_mm * 1e3:g} um", fontsize=9)  # fmt: skip
    m1 = panels[-1].pcolormesh(sv, su, left, cmap="viridis", shading="auto")
    fig.colorbar(m1, ax=panels[-1], label="leftover above design surface (mm)")
    no_gouge = ""
    if not gouged:
        iu, iv = np.nonzero(gouge > 0)
        if iu.size:
            panels[-1].plot(sv[iv], su[iu], "r.", ms=2, label=f"gouge within tolerance ({iu.size})")
            panels[-1].legend(fontsize=7, loc="upper right")
        no_gouge = (f"\ngouge: max {gouge.max() * 1e3:.1f} um at {iu.size} dexels, all within "
                    f"the tolerance {tol_mm * 1e3:g} um")  # fmt: skip
    panels[-1].set_title(f"leftover: max {left.max():.3f} mm{no_gouge}", fontsize=9)
    for ax in panels:
        ax.set_xlabel("along v (mm of arc)")
        ax.set_ylabel("along u (mm of arc)")
        ax.set_aspect("equal")
    fig.suptitle(f"{title}: stock after the program, dexels {dexels.spacing_mm:g} mm apart",
                 fontsize=10)  # fmt: skip
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out


def simulate(
    surface: NurbsSurface,
    u_frac: tuple[float, float],
    v_frac: tuple[float, float],
    machine: MachineConfig,
    moves: AxisMoves,
    line: np.ndarray,
    tool: ToolSystem,
    spacing_mm: float,
    step_mm: float,
    allowance_mm: float = 1.0,
) -> NormalDexels:
    """The dexels of ``surface`` (the parameter fractions ``u_frac``, ``v_frac``) after the
    program ``moves`` with the cutter of ``tool`` (a :class:`planning.orient.ToolSystem`)."""
    dex = NormalDexels.on_surface(surface, u_frac, v_frac, spacing_mm, allowance_mm)
    tips, axes = sample_program(machine, moves, line, tool.gauge_length_mm, step_mm)
    dex.cut(tips, axes, tool.R_mm, tool.r_mm, tool.cutter_length_mm)
    return dex
