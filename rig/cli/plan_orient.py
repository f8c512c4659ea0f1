"""`cutlab plan orient CONFIG -o OUT [--json]`: collision-free 5-axis tool orientation (seed 002).

Writes to the folder OUT: ``cl.csv`` (CL data: tip, cutter centre, axis, angles per CC point),
``program.nc`` (G-code for the config's 5-axis machine by inverse kinematics),
``energy_map.png`` (the eq 7 energy over (alpha, beta) at one CC point, as seed 002 Fig. 8),
``orientation.png`` (the surfaces with the chosen tool axes, as Figs. 9-11) and
``summary.json``. Every output orientation is re-checked on a fresh dense mesh before anything
is written; a CC point without a collision-free orientation stops the command with its reason.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``orient`` to the ``plan`` group."""
    p = sub.add_parser(
        "orient",
        help="collision-free 5-axis tool orientation (potential energy, seed 002)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "config", type=Path, help="orientation config, e.g. configs/orient/impeller.toml"
    )
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument(
        "--map-point",
        type=int,
        default=None,
        help="CC point for the energy map (default: the one that needed most energy evaluations)",
    )
    p.add_argument(
        "--no-plot", action="store_true", help="skip both PNGs (energy map and orientation)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np
    from tqdm import tqdm

    from planning.errors import PlanningError
    from planning.orient import (
        ToolSystem,
        energy_map,
        inverse,
        load_orient,
        nc_program,
        plan_orientation,
        require_feasible,
        verify,
        write_cl_csv,
    )
    from rig.cli._common import print_json, print_table, status

    cfg, tool_cfg, machine = load_orient(args.config)
    t0 = time.perf_counter()
    with tqdm(
        total=None, desc="orient", unit="pt", file=sys.stderr, leave=False, disable=None
    ) as bar:

        def progress(i: int, n: int) -> None:
            bar.total = n
            bar.update(1)

        res = plan_orientation(cfg, tool_cfg, progress)
    plan_s = time.perf_counter() - t0
    require_feasible(res)
    surfaces = [s.build() for s in cfg.surfaces]
    tool = ToolSystem.from_endmill(tool_cfg, cfg.tool)
    pl = cfg.planner
    ver = verify(
        surfaces, tool, res.tip_mm, res.axis, pl.check_spacing_mm / 1.5, pl.gouge_tolerance_mm
    )
    if ver.collisions:
        i, c = ver.worst
        raise PlanningError(
            f"{ver.collisions} orientations failed the independent check; worst CC point "
            f"{i}: {c.part} in {c.surface} by {-c.min_mm:.4f} mm"
        )
    moves = inverse(machine, res.tip_mm, res.axis, tool.gauge_length_mm)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    write_cl_csv(out / "cl.csv", res)
    (out / "program.nc").write_text(
        nc_program(
            moves, res.cc.line, pl.feed_mm_min, pl.spindle_rpm, title=cfg.name, tips_mm=res.tip_mm
        ),  # fmt: skip
        encoding="utf-8",
    )
    files = [str(out / "cl.csv"), str(out / "program.nc")]
    idx = int(np.argmax(res.evaluations)) if args.map_point is None else args.map_point
    if not args.no_plot:
        status(f"energy map at CC point {idx} ...")
        emap = energy_map(cfg, tool_cfg, idx, res)
        _plot_map(emap, out / "energy_map.png", cfg.name)
        _plot_axes(surfaces, res, out / "orientation.png", cfg.name)
        files += [str(out / "energy_map.png"), str(out / "orientation.png")]
    jumps_ok = np.isfinite(res.max_jump_deg)
    summary = {
        "config": str(args.config),
        "name": cfg.name,
        "tool": cfg.tool,
        "machine": machine.name,
        "kinematics": moves.kind,
        "cc_points": res.n_points,
        "feasible": int(res.feasible.sum()),
        "plan_s": round(plan_s, 4),
        "mean_point_ms": round(float(res.seconds.mean() * 1e3), 3),
        "energy_evaluations": int(res.evaluations.sum()),
        "alpha_deg_range": [float(res.alpha_deg.min()), float(res.alpha_deg.max())],
        "beta_deg_range": [float(res.beta_deg.min()), float(res.beta_deg.max())],
        "max_gap_per_mm": float(np.max(res.gap_per_mm)),
        "max_axis_jump_deg": float(res.max_jump_deg) if jumps_ok else None,
        "max_axis_jump_at": res.max_jump_at,
        "max_angle_jump_deg": float(res.max_angle_jump_deg) if jumps_ok else None,
        "check_spacing_mm": ver.spacing_mm,
        "checked": ver.checked,
        "collisions": ver.collisions,
        "min_clearance_mm": float(np.nanmin(ver.min_clearance_mm)),
        "a_deg_range": [float(moves.a_deg.min()), float(moves.a_deg.max())],
        "c_deg_range": [float(moves.c_deg.min()), float(moves.c_deg.max())],
        "energy_map_point": idx,
        "files": files,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2), encoding="utf-8")
    if args.json:
        print_json(summary)
    else:

        def show(v):  # ranges as "lo .. hi" with 4 significant digits, not raw float lists
            return f"{v[0]:.4g} .. {v[1]:.4g}" if isinstance(v, list) and len(v) == 2 else v

        print_table([{"quantity": k, "value": show(v)} for k, v in summary.items() if k != "files"])
        for f in files:
            print(f)
    return 0


def _plot_map(emap, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

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


def _plot_axes(surfaces, res, path: Path, title: str) -> None:
    """Surfaces as wireframes with the tool axis drawn from each tip (seed 002 Figs. 9-11)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

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
