"""PNG pictures of roughing plans (matplotlib, Agg): levels, paths, the roughed shape."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import LineString

from planning.rough.check import CheckResult, SurfaceHeights
from planning.rough.planner import RoughPlan, RoughPlanner

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _plt() -> ModuleType:
    """pyplot on the Agg backend (files only, no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(plt: ModuleType, fig: Figure, path: str | Path) -> Path:
    """Lay out, write and close ``fig``; the PNG path."""
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out


def plot_levels(planner: RoughPlanner, plans: dict[str, RoughPlan], path: str | Path) -> Path:
    """Side view through the crest: the offset surface and, per method, each level's cut.

    Each level is drawn as a bar at its height over the x-range it clears on the section line
    (the level's region A(lo) - C(z) cut by the line y = y_crest), labelled by cutting order.
    """
    plt = _plt()
    cz = planner.cusps
    y0 = float(cz.xyz[-1, 1])  # through the highest sample
    x_lo, x_hi, _, _ = planner.stock_xy
    xs = np.linspace(x_lo, x_hi, 400)
    heights = SurfaceHeights(planner.offset_surface, per_patch=8)
    zs = heights.height(xs, np.full_like(xs, y0))
    line = LineString([(x_lo - 1, y0), (x_hi + 1, y0)])
    fig, axes = plt.subplots(len(plans), 1, figsize=(9, 2.6 * len(plans)), sharex=True, dpi=100)
    axes = np.atleast_1d(axes)
    for ax, (name, plan) in zip(axes, plans.items()):
        ax.fill_between(xs, planner.part.config.stock.z_min_mm, zs, color="0.8", lw=0)
        ax.plot(xs, zs, "k-", lw=1, label="offset surface")
        ax.axhline(planner.top, color="0.5", ls=":", lw=1)
        cmap = plt.get_cmap("viridis")
        for lv in plan.levels:
            geom = planner.geom if lv.tool == 1 else planner.geom2
            reg = geom.region(lv.z_mm, lv.lo_mm)
            cut = reg.intersection(line)
            c = cmap(lv.order / max(len(plan.levels), 1))
            for g in getattr(cut, "geoms", [cut]):
                if g.is_empty or not isinstance(g, LineString):
                    continue
                gx = np.asarray(g.coords)[:, 0]
                ax.fill_between([gx.min(), gx.max()], lv.z_mm, lv.hi_mm, color=c, alpha=0.35, lw=0)
                ax.plot([gx.min(), gx.max()], [lv.z_mm, lv.z_mm], color=c, lw=2)
                ax.text(gx.mean(), lv.z_mm + 0.3, str(lv.order), fontsize=7, ha="center")
        ax.set_title(
            f"{name}: {len(plan.levels)} levels, cutting path {plan.path_mm:.0f} mm, "
            f"max cusp {plan.max_cusp_mm:.2f} mm",
            fontsize=9,
        )
        ax.set_ylabel("z (mm)")
        ax.set_ylim(planner.bottom - 3, planner.top + 2)
    axes[-1].set_xlabel(f"x (mm), section y = {y0:.1f} mm")
    return _save(plt, fig, path)


def plot_paths(planner: RoughPlanner, plan: RoughPlan, path: str | Path) -> Path:
    """Top view of every pass, coloured by level height, with the level contours."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 7), dpi=100)
    x0, x1, y0, y1 = planner.stock_xy
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], "k-", lw=1)
    zmin, zmax = planner.bottom, planner.top
    cmap = plt.get_cmap("viridis")
    norm = plt.Normalize(zmin, zmax)
    for lv in plan.levels:
        c = cmap(norm(lv.z_mm))
        geom = planner.geom if lv.tool == 1 else planner.geom2
        b = shapely.get_coordinates(geom.closed(lv.z_mm).boundary)
        if len(b):
            ax.plot(b[:, 0], b[:, 1], ".", ms=0.3, color="0.4")
        for p in lv.paths.passes:
            ax.plot(p.xy_mm[:, 0], p.xy_mm[:, 1], "-", color=c, lw=0.8)
            ax.plot(*p.xy_mm[0], "o", color=c, ms=2)
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=norm)
    fig.colorbar(sm, ax=ax, label="level z (mm)")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(
        f"{plan.method}: passes (dots: starts; climb, outside in), {plan.path_mm:.0f} mm",
        fontsize=9,
    )
    return _save(plt, fig, path)


def plot_roughed(check: CheckResult, title: str, path: str | Path) -> Path:
    """The Z-map after the program, and the material left above the offset surface."""
    plt = _plt()
    zm = check.zmap
    ext = zm.extent_mm
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), dpi=100)
    im0 = axes[0].imshow(zm.heights_mm, origin="lower", extent=ext, cmap="viridis")
    fig.colorbar(im0, ax=axes[0], label="height (mm)")
    axes[0].set_title(f"{title}: roughed shape (Z-map {zm.spacing_mm} mm)", fontsize=9)
    im1 = axes[1].imshow(
        check.left_mm, origin="lower", extent=ext, cmap="magma", vmin=0,
        vmax=max(check.cusp_limit_mm, float(check.left_mm.max())),
    )  # fmt: skip
    fig.colorbar(im1, ax=axes[1], label="left above offset surface (mm, normal)")
    axes[1].plot(*check.worst_xy_mm, "c+", ms=12)
    axes[1].set_title(
        f"max left {check.max_left_mm:.3f} mm (limit {check.cusp_limit_mm}), "
        f"gouge {check.max_gouge_mm:.3f} mm",
        fontsize=9,
    )
    for ax in axes:
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
    return _save(plt, fig, path)
