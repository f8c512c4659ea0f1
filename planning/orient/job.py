"""The whole `cutlab plan orient` job: plan the orientations, smooth them, refine the CL points
until the machine's moves between them are verified (planning.orient.between), re-check every
posted pose on a fresh mesh, post for the machine (inverse kinematics, singularity, G93 feeds
within the axis speeds, forward-kinematics check of every block), simulate the stock the program
leaves (planning.orient.stock5: gouge and leftover against the design surface), write CL data,
the NC program, the pictures and summary.json, and return the summary."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.config import EndMill, MachineConfig
from analysis.validation import JsonObject, JsonValue
from planning.errors import PlanningError
from planning.nc import Program, get_dialect
from planning.nc.output import default_dialect, for_dialect
from planning.orient._search import _Context
from planning.orient.between import Refined, Scene, refine
from planning.orient.check import Verification, verify
from planning.orient.config import OrientConfig, load_orient
from planning.orient.kinematics import (
    axis_speeds,
    check_forward,
    inverse_time_feeds,
    nc_program,
    write_cl_csv,
)
from planning.orient.planner import (
    CCPoints,
    OrientResult,
    assemble,
    axis_jumps_deg,
    build_context,
    cc_points,
    energy_map,
    require_feasible,
    solve_all,
)
from planning.orient.smooth import angles_of, smooth_result
from planning.orient.stock5 import NormalDexels, StockFigures, figures, save_maps, simulate
from planning.orient.tool import ToolSystem
from planning.surface import NurbsSurface

TIP_TOL_MM = 0.01  # tool tip off the chord between CL points, after refinement
MAX_JUMP_DEG = 5.0  # tool-axis change between neighbouring CL points
MAX_C_STEP_DEG = 30.0  # C per block
SINGULAR_CONE_DEG = 3.0  # C held within this angle of the C axis
STOCK_SPACING_MM = 0.25  # dexels of the stock simulation, apart on the design surface
STOCK_STEP_MM = 0.1  # tool samples along a move: a bull's 2 mm corner leaves 0.0006 mm between
STOCK_ALLOWANCE_MM = 1.0  # stock over the design surface before the program


def _jump_stats(axis: np.ndarray, cc: CCPoints) -> tuple[float, int, float]:
    """Largest axis change between neighbours (deg), the later point, largest per mm on the
    part (deg/mm)."""
    j = axis_jumps_deg(axis, cc.line)
    step = np.linalg.norm(np.diff(cc.point, axis=0), axis=1)
    k = int(np.nanargmax(j)) if np.isfinite(j).any() else -1
    per_mm = float(np.nanmax(j / np.maximum(step, 1e-9))) if k >= 0 else float("nan")
    return (float(j[k]) if k >= 0 else float("nan")), k + 1, per_mm


@dataclass(frozen=True)
class _Planned:
    """The planning step's result: the surfaces (and the machined one), the CC points, the
    planner's context, the raw and smoothed orientations and the time it took, s."""

    surfaces: list[NurbsSurface]
    machined: NurbsSurface
    cc: CCPoints
    ctx: _Context
    raw: OrientResult
    res: OrientResult
    plan_s: float


@dataclass(frozen=True)
class _Checked:
    """The refined CL points, their independent verification, the stock they leave and the
    step times, s."""

    tool: ToolSystem
    ref: Refined
    ver: Verification
    stock: NormalDexels
    cut: StockFigures
    verify_s: float
    stock_s: float


@dataclass(frozen=True)
class _Posted:
    """The posted program's figures: forward check (mm, rad), axis speeds, the posted angles
    (m, 2) rad and the files written."""

    fk_mm: float
    fk_rad: float
    speeds: dict[str, float]
    th_post: np.ndarray
    files: list[JsonValue]


def run_orient(
    config: str | Path,
    out_dir: Path,
    map_point: int | None = None,
    plot: bool = True,
    progress: Callable[[int, int], None] | None = None,
    status: Callable[[str], None] | None = None,
    dialect: str | None = None,
) -> JsonObject:
    """Plan the orientation config ``config``, check every orientation on a dense mesh, write
    cl.csv, program.nc, summary.json (and energy_map.png, orientation.png if ``plot``) to
    ``out_dir`` and return the summary. The energy map is drawn at ``map_point`` (default: the
    CC point that needed most energy evaluations). ``progress(done, total)`` counts CC points;
    ``status`` gets a line before the energy map and the reason when refinement stops short.
    ``dialect`` (fanuc, linuxcnc; default the machine's) is the controller the program is
    written for; grbl has no rotary axes and is refused. Nothing is written if a point fails."""
    config, out = Path(config), Path(out_dir)
    cfg, tool_cfg, machine = load_orient(config)
    dialect = _rotary_dialect(config, dialect or default_dialect(machine))
    planned = _plan(cfg, tool_cfg, progress)
    checked = _refine_and_check(cfg, tool_cfg, machine, planned, status)
    posted = _post(cfg, machine, planned, checked, dialect, out)
    idx = int(np.argmax(planned.res.evaluations)) if map_point is None else map_point
    if plot:
        posted.files.extend(_plots(cfg, tool_cfg, planned, checked, idx, out, status))
    summary: JsonObject = {
        "config": str(config),
        **_plan_figures(cfg, machine, planned, checked),
        **_check_figures(cfg, planned, checked, posted, dialect),
        "energy_map_point": idx,
        "files": posted.files,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2), encoding="utf-8")
    return summary


def _rotary_dialect(config: Path, dialect: str) -> str:
    """``dialect``, refused when its controller has no rotary axes."""
    if not get_dialect(dialect).post.full_words:  # no A/B/C words written there
        raise PlanningError(
            f"{config}: --dialect {dialect}: {get_dialect(dialect).title} has no rotary axes "
            "(A, B, C), so it cannot run a 5-axis program; use fanuc or linuxcnc"
        )
    return dialect


def _plan(
    cfg: OrientConfig, tool_cfg: EndMill, progress: Callable[[int, int], None] | None
) -> _Planned:
    """The orientation of every CC point (an error when one has none), smoothed."""
    surfaces = [s.build() for s in cfg.surfaces]
    machined = surfaces[[s.role for s in cfg.surfaces].index("machined")]
    t0 = time.perf_counter()
    cc = cc_points(machined, cfg)
    ctx = build_context(cfg, tool_cfg, surfaces)
    raw = solve_all(ctx, cc, progress)
    require_feasible(raw)
    res = smooth_result(ctx, raw)
    return _Planned(surfaces, machined, cc, ctx, raw, res, time.perf_counter() - t0)


def _refine_and_check(
    cfg: OrientConfig, tool_cfg: EndMill, machine: MachineConfig, planned: _Planned,
    status: Callable[[str], None] | None,
) -> _Checked:  # fmt: skip
    """CL points refined until the moves between them pass, every posted pose verified on a
    fresh mesh (an error naming the worst collision), the stock the moves leave simulated."""
    tool = ToolSystem.from_endmill(tool_cfg, cfg.tool)
    pl, res = cfg.planner, planned.res
    t1 = time.perf_counter()
    scene = Scene.build(planned.surfaces, tool, pl.check_spacing_mm, pl.gouge_tolerance_mm)
    theta = np.radians(np.stack([res.alpha_deg, res.beta_deg], 1))
    ref = refine(
        planned.ctx, planned.machined, cfg.paths.along, planned.cc, theta, machine, scene,
        TIP_TOL_MM, MAX_JUMP_DEG, MAX_C_STEP_DEG, SINGULAR_CONE_DEG,
    )  # fmt: skip
    verify_s = time.perf_counter() - t1
    if ref.unresolved and status is not None:
        status(f"refinement stopped short: {ref.unresolved}")
    ver = verify(
        planned.surfaces, tool, ref.tip_mm, ref.axis, pl.check_spacing_mm / 1.5,
        pl.gouge_tolerance_mm,
    )  # fmt: skip
    if ver.collisions:
        assert ver.worst is not None  # verify() names the worst of its collisions
        i, c = ver.worst
        raise PlanningError(
            f"{ver.collisions} orientations failed the independent check; worst CL point "
            f"{i}: {c.part} in {c.surface} by {-c.min_mm:.4f} mm"
        )
    t2 = time.perf_counter()
    ps = cfg.paths
    across = (min(ps.lines), max(ps.lines))
    u_frac, v_frac = (ps.span, across) if ps.along == "u" else (across, ps.span)
    stock = simulate(planned.machined, u_frac, v_frac, machine, ref.moves, ref.cc.line, tool,
                     STOCK_SPACING_MM, STOCK_STEP_MM, STOCK_ALLOWANCE_MM)  # fmt: skip
    cut = figures(stock, STOCK_ALLOWANCE_MM, STOCK_STEP_MM)
    return _Checked(tool, ref, ver, stock, cut, verify_s, time.perf_counter() - t2)


def _post(
    cfg: OrientConfig, machine: MachineConfig, planned: _Planned, checked: _Checked,
    dialect: str, out: Path,
) -> _Posted:  # fmt: skip
    """Forward-check the moves, set G93 feeds, write cl.csv and program.nc (for ``dialect``)."""
    ref, pl = checked.ref, cfg.planner
    moves = ref.moves
    fk_mm, fk_rad = check_forward(
        machine, moves, ref.tip_mm, ref.axis, checked.tool.gauge_length_mm
    )
    inv_f, _ = inverse_time_feeds(machine, moves, ref.tip_mm, pl.feed_mm_min)
    speeds = axis_speeds(machine, moves, inv_f, ref.cc.line)
    # The CL data of the posted points: angles of the posted (held) axes in their frames.
    th_post = angles_of(ref.axis, ref.cc.binormal, ref.cc.feed, ref.cc.normal)
    m_post = len(th_post)
    final = assemble(
        planned.ctx, ref.cc, th_post, np.zeros(m_post), checked.ver.min_clearance_mm, (),
        np.zeros(m_post), np.zeros(m_post, int),
    )  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    write_cl_csv(out / "cl.csv", final)
    fanuc = nc_program(
        moves, ref.cc.line, pl.feed_mm_min, pl.spindle_rpm, title=cfg.name, inverse_f=inv_f
    )
    program = for_dialect(Program.parse(fanuc, str(out / "program.nc")), dialect, machine,
                          source="fanuc")  # fmt: skip
    program.write(out / "program.nc")
    files: list[JsonValue] = [str(out / "cl.csv"), str(out / "program.nc")]
    return _Posted(fk_mm, fk_rad, speeds, th_post, files)


def _plots(
    cfg: OrientConfig, tool_cfg: EndMill, planned: _Planned, checked: _Checked, idx: int,
    out: Path, status: Callable[[str], None] | None,
) -> list[JsonValue]:  # fmt: skip
    """The energy map at CC point ``idx``, the orientations and the stock maps: their paths."""
    from planning.orient.plot import plot_axes, plot_energy_map

    if status is not None:
        status(f"energy map at CC point {idx} ...")
    emap = energy_map(cfg, tool_cfg, idx, planned.res)
    plot_energy_map(emap, out / "energy_map.png", cfg.name)
    plot_axes(planned.surfaces, planned.res, out / "orientation.png", cfg.name)
    save_maps(checked.stock, cfg.planner.gouge_tolerance_mm, out / "stock_maps.png", cfg.name)
    return [str(out / n) for n in ("energy_map.png", "orientation.png", "stock_maps.png")]


def _plan_figures(
    cfg: OrientConfig, machine: MachineConfig, planned: _Planned, checked: _Checked
) -> JsonObject:
    """The summary's planning part: the planned and smoothed orientations, their jumps."""
    res, ref = planned.res, checked.ref
    jumps_ok = np.isfinite(res.max_jump_deg)
    before = _jump_stats(planned.raw.axis, planned.cc)
    smoothed = _jump_stats(res.axis, planned.cc)
    after = _jump_stats(ref.axis, ref.cc)
    return {
        "name": cfg.name,
        "tool": cfg.tool,
        "machine": machine.name,
        "kinematics": ref.moves.kind,
        "cc_points": res.n_points,
        "feasible": int(res.feasible.sum()),
        "plan_s": round(planned.plan_s, 4),
        "mean_point_ms": round(float(res.seconds.mean() * 1e3), 3),
        "energy_evaluations": int(res.evaluations.sum()),
        "alpha_deg_range": [float(res.alpha_deg.min()), float(res.alpha_deg.max())],
        "beta_deg_range": [float(res.beta_deg.min()), float(res.beta_deg.max())],
        "max_gap_per_mm": float(np.max(res.gap_per_mm)),
        "max_axis_jump_deg": after[0],
        "max_axis_jump_at": after[1],
        "max_axis_jump_per_mm_deg": after[2],
        "max_axis_jump_cc_deg": {"planned": before[0], "smoothed": smoothed[0]},
        "max_axis_jump_cc_per_mm_deg": {"planned": before[2], "smoothed": smoothed[2]},
        "max_angle_jump_deg": float(res.max_angle_jump_deg) if jumps_ok else None,
    }


def _check_figures(
    cfg: OrientConfig, planned: _Planned, checked: _Checked, posted: _Posted, dialect: str
) -> JsonObject:
    """The summary's checking part: refinement, verification, posting and stock."""
    ref, ver, cut, moves = checked.ref, checked.ver, checked.cut, checked.ref.moves
    post_deg = np.degrees(posted.th_post[:, 0])
    a_lim = np.asarray(cfg.limits.alpha_deg)
    return {
        "cl_points": len(ref.theta),
        "inserted_points": ref.inserted,
        "between_samples": ref.check.samples,
        "between_collisions": ref.check.collisions,
        "tip_deviation_mm": float(np.nanmax(ref.check.deviation_mm, initial=0.0)),
        "between_overcut_mm": float(np.nanmax(ref.check.overcut_mm, initial=0.0)),
        "refine_unresolved": ref.unresolved,
        "verify_s": round(checked.verify_s, 3),
        "posted_alpha_deg_range": [float(post_deg.min()), float(post_deg.max())],
        "posted_within_limits": bool(
            np.all(post_deg >= a_lim[0] - 1e-6) and np.all(post_deg <= a_lim[1] + 1e-6)
        ),
        "check_spacing_mm": ver.spacing_mm,
        "checked": ver.checked,
        "collisions": ver.collisions,
        "min_clearance_mm": float(np.nanmin(ver.min_clearance_mm)),
        "forward_check_mm": posted.fk_mm,
        "forward_check_rad": posted.fk_rad,
        "dialect": dialect,
        "a_deg_range": [float(moves.a_deg.min()), float(moves.a_deg.max())],
        "c_deg_range": [float(moves.c_deg.min()), float(moves.c_deg.max())],
        **posted.speeds,
        "gouge_max_mm": cut.gouge_max_mm,
        "leftover_max_mm": cut.leftover_max_mm,
        "stock_uncut_fraction": cut.uncut_fraction,
        "stock_resolution_mm": cut.spacing_mm,
        "stock_step_mm": cut.step_mm,
        "stock_allowance_mm": STOCK_ALLOWANCE_MM,
        "stock_s": round(checked.stock_s, 3),
    }


def summary_lines(summary: JsonObject) -> list[str]:
    """``cutlab plan orient``'s text: :func:`run_orient`'s summary as quantity / value rows
    (ranges as "lo .. hi", 4 significant digits), then the files written."""
    from analysis.output import table_lines

    def shown(v: JsonValue) -> JsonValue:
        return f"{v[0]:.4g} .. {v[1]:.4g}" if isinstance(v, list) and len(v) == 2 else v

    files = summary["files"]
    assert isinstance(files, list)
    rows = [{"quantity": k, "value": shown(v)} for k, v in summary.items() if k != "files"]
    return [*table_lines(rows), *(str(f) for f in files)]
