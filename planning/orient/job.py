"""The whole `cutlab plan orient` job: plan the orientations, re-check them on a fresh mesh,
write CL data, the NC program, the pictures and summary.json, and return the summary."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from planning.errors import PlanningError
from planning.orient.check import verify
from planning.orient.config import load_orient
from planning.orient.kinematics import inverse, nc_program, write_cl_csv
from planning.orient.planner import energy_map, plan_orientation, require_feasible
from planning.orient.tool import ToolSystem


def run_orient(
    config: str | Path,
    out_dir: Path,
    map_point: int | None = None,
    plot: bool = True,
    progress: Callable[[int, int], None] | None = None,
    status: Callable[[str], None] | None = None,
) -> dict:
    """Plan the orientation config ``config``, check every orientation on a dense mesh, write
    cl.csv, program.nc, summary.json (and energy_map.png, orientation.png if ``plot``) to
    ``out_dir`` and return the summary. The energy map is drawn at ``map_point`` (default: the
    CC point that needed most energy evaluations). ``progress(done, total)`` counts CC points;
    ``status`` gets a line before the energy map. Nothing is written if a point fails."""
    config, out = Path(config), Path(out_dir)
    cfg, tool_cfg, machine = load_orient(config)
    t0 = time.perf_counter()
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
    out.mkdir(parents=True, exist_ok=True)
    write_cl_csv(out / "cl.csv", res)
    (out / "program.nc").write_text(
        nc_program(
            moves, res.cc.line, pl.feed_mm_min, pl.spindle_rpm, title=cfg.name, tips_mm=res.tip_mm
        ),  # fmt: skip
        encoding="utf-8",
    )
    files = [str(out / "cl.csv"), str(out / "program.nc")]
    idx = int(np.argmax(res.evaluations)) if map_point is None else map_point
    if plot:
        from planning.orient.plot import plot_axes, plot_energy_map

        if status is not None:
            status(f"energy map at CC point {idx} ...")
        emap = energy_map(cfg, tool_cfg, idx, res)
        plot_energy_map(emap, out / "energy_map.png", cfg.name)
        plot_axes(surfaces, res, out / "orientation.png", cfg.name)
        files += [str(out / "energy_map.png"), str(out / "orientation.png")]
    jumps_ok = np.isfinite(res.max_jump_deg)
    summary = {
        "config": str(config),
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
    return summary
