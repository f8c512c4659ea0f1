"""The pictures of `cutlab plan orient`: the energy map at one CC point (seed 002 Fig. 8) and
the surfaces with the chosen tool axes (Figs. 9-11). matplotlib is imported on first use."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from planning.orient.planner import EnergyMap, OrientResult
    from planning.surface import NurbsSurface


def _plt() -> ModuleType:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_energy_map(emap: EnergyMap, path: Path, title: str) -> Path:
    """The eq 7 energy over (alpha, beta) with the descent and the chosen angles, as a PNG."""
    import numpy as np

    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    B, A = np.meshgrid(emap.beta_deg, emap.alpha_deg)
    E = np.log10(1.0 + emap.energy)
    pc = ax.pcolormesh(B, A, E, shading="auto", cmap="viridis")
    ax.contour(B, A, (emap.energy > 0).astype(float), levels=[0.5], colors="w", linewidths=0.8)
    fig.colorbar(pc, ax=ax, label="log10(1 + U)   (U: eq 7, mm)")
    d = emap.descent_deg
    ax.plot(d[:, 1], d[:, 0], "r.-", label="descent from the curvature optimum")
    if np.all(np.isfinite(emap.chosen_deg)):
        ax.plot(emap.chosen_deg[1], emap.chosen_deg[0], "w*", ms=12, label="chosen")
    ax.set_xlabel("tilt angle beta (deg)")
    ax.set_ylabel("advance angle alpha (deg)")
    ax.set_title(f"{title}: potential energy at CC point {emap.index} (U = 0: collision-free)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def plot_axes(surfaces: Sequence[NurbsSurface], res: OrientResult, path: Path, title: str) -> Path:
    """Surfaces as wireframes with the tool axis drawn from each tip (seed 002 Figs. 9-11)."""
    import numpy as np

    plt = _plt()
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    for s in surfaces:
        n = 24
        P = s.points(*s.grid(n, n)).reshape(n, n, 3)
        ax.plot_wireframe(P[..., 0], P[..., 1], P[..., 2], color="0.6", linewidth=0.4)
    ok = res.feasible
    tip, u = res.tip_mm[ok], res.axis[ok]
    length = 0.25 * float(np.ptp(res.cc.point, axis=0).max())
    for t, a in zip(tip, u):
        ax.plot(*np.stack([t, t + length * a]).T, color="tab:red", linewidth=0.9)
    ax.scatter(*res.cc.point[ok].T, s=4, color="k")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.set_title(f"{title}: tool axes at {int(ok.sum())} CC points")
    ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
