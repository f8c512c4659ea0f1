"""The whole `cutlab plan rough` job: plan a part by every method, write the chosen program for
the controller's dialect, check it on a Z-map, draw the pictures, and return the JSON-ready
result."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TypedDict

from analysis.config import MachineConfig, load_machine
from analysis.validation import JsonObject, JsonValue
from planning.errors import PlanningError
from planning.nc import Program
from planning.nc.output import DIALECTS, default_dialect, for_dialect
from planning.rough.check import check_program
from planning.rough.gcode import MoveSettings, PlanTotals, plan_motion, plan_program, plan_totals
from planning.rough.part import Part, load_part
from planning.rough.planner import METHODS, RoughPlan, RoughPlanner

# (planner, chosen plan, its Fanuc program) -> (plan, program, report): planning.limits
LimitStep = Callable[[RoughPlanner, RoughPlan, Program], tuple[RoughPlan, Program, JsonObject]]


class Comparison(TypedDict):
    """The cutting-path comparisons between methods, % (None: the reference path is 0)."""

    bisection_shorter_than_equal_pct: float | None
    bisection_shorter_than_lee_pct: float | None
    optimal_shorter_than_bisection_pct: float | None


class RoughResult(TypedDict):
    """What :func:`run_rough` returns (JSON-ready): the chosen plan's levels, every method's
    totals, the Z-map check, the written files and the limits' report."""

    part: str
    method: str
    dialect: str
    cusp_model: str
    cusp_mm: float
    max_depth_mm: float
    bottom_mm: float
    top_mm: float
    levels: list[JsonObject]
    totals: dict[str, PlanTotals]
    comparison: Comparison
    check: JsonObject | None
    program: str
    png: dict[str, str]
    violations: JsonValue
    limits: JsonObject | None


def shorter_pct(a: float, b: float) -> float | None:
    """How much shorter a is than b, % of b (None when b is 0)."""
    return round(100.0 * (1.0 - a / b), 2) if b else None


def comparison_pct(totals: Mapping[str, PlanTotals]) -> Comparison:
    """The cutting-path comparisons between methods, in % (seed 000's headline numbers)."""
    path = {m: t["cutting_path_mm"] for m, t in totals.items()}
    return {
        "bisection_shorter_than_equal_pct": shorter_pct(path["bisection"], path["equal"]),
        "bisection_shorter_than_lee_pct": shorter_pct(path["bisection"], path["lee"]),
        "optimal_shorter_than_bisection_pct": shorter_pct(path["optimal"], path["bisection"]),
    }


def run_rough(
    config: str | Path,
    output: Path,
    method: str = "bisection",
    cusp_model: str | None = None,
    check: bool = True,
    check_spacing_mm: float = 0.5,
    png: bool = True,
    progress: Callable[[str], None] | None = None,
    status: Callable[[str], None] | None = None,
    dialect: str | None = None,
    machine: str | Path | MachineConfig | None = None,
    limits: LimitStep | None = None,
) -> RoughResult:
    """Plan ``config`` (a part file or name) by all four methods, write ``method``'s program to
    ``output`` for the ``dialect`` controller (default: ``machine``'s, a machine config name,
    path or object; else Fanuc), cut it on a Z-map of ``check_spacing_mm`` (unless not
    ``check``), draw the pictures next to ``output`` (if ``png``) and return the JSON-ready
    result. ``progress`` gets one note per planning step, ``status`` one line per finished
    stage. ``limits`` (planning.limits.rough_limiter) checks the chosen program against the
    machine's and tool's limits, and may split levels or lower feeds: its report is the result's
    ``limits``, its violations the result's ``violations``."""
    if not check_spacing_mm > 0:
        raise PlanningError(f"--check-spacing = {check_spacing_mm}: must be > 0 (mm)")
    if method not in METHODS:
        raise PlanningError(f"method = {method!r}: expected one of {', '.join(METHODS)}")
    if dialect is not None and dialect not in DIALECTS:
        raise PlanningError(f"dialect = {dialect!r}: expected one of {', '.join(DIALECTS)}")
    if machine is not None and not isinstance(machine, MachineConfig):
        machine = load_machine(machine)
    dialect = dialect or default_dialect(machine)
    say = status or (lambda msg: None)
    output = Path(output)
    part = load_part(config)
    if cusp_model is not None:
        cfg = part.config
        rough = cfg.rough.model_copy(update={"cusp_model": cusp_model})
        part = Part(cfg.model_copy(update={"rough": rough}), part.path)
    t0 = time.perf_counter()
    planner = RoughPlanner(part, progress=progress)
    plans = planner.plan_all()
    say(f"planned 4 methods in {time.perf_counter() - t0:.1f} s")
    motions = {m: plan_motion(p, part) for m, p in plans.items()}
    totals = {m: plan_totals(p, part, motions[m]) for m, p in plans.items()}
    chosen = plans[method]
    fanuc = plan_program(chosen, part, motions[method])
    limit_report = None
    if limits is not None:
        chosen, fanuc, limit_report = limits(planner, chosen, fanuc)
        before, after = limit_report.get("before"), limit_report.get("violations")
        if isinstance(before, dict) and isinstance(after, list):
            say(f"limits: {before['violations']} violations before, {len(after)} after")
        else:
            say(f"limits not checked: {limit_report.get('why', '')}")
    program = for_dialect(fanuc, dialect, machine, source="fanuc")  # moves as fanuc does
    output.parent.mkdir(parents=True, exist_ok=True)
    program.write(output)
    say(f"wrote {output} ({len(program.lines)} lines, {dialect})")

    result = None
    if check:
        st = part.config.stock
        result = check_program(  # the Fanuc text: tool numbers even where GRBL has no M6
            fanuc.text(),
            planner.offset_surface,
            (st.x_min_mm, st.x_max_mm, st.y_min_mm, st.y_max_mm, st.z_min_mm, st.z_max_mm),
            {1: part.tool.radius_mm, 2: part.lee_tool.radius_mm},
            part.config.rough.cusp_mm,
            MoveSettings.of(part).safe_z_mm,
            spacing_mm=check_spacing_mm,
        )
    pngs: dict[str, str] = {}
    if png:
        from planning.rough.plot import plot_levels, plot_paths, plot_roughed

        stem = output.with_suffix("")
        pngs["levels"] = str(plot_levels(planner, plans, f"{stem}.levels.png"))
        pngs["paths"] = str(plot_paths(planner, chosen, f"{stem}.paths.png"))
        if result is not None:
            pngs["roughed"] = str(plot_roughed(result, method, f"{stem}.roughed.png"))
    return {
        "part": part.config.name,
        "method": method,
        "dialect": dialect,
        "cusp_model": part.config.rough.cusp_model,
        "cusp_mm": part.config.rough.cusp_mm,
        "max_depth_mm": planner.L,
        "bottom_mm": round(planner.bottom, 4),
        "top_mm": planner.top,
        "levels": [lv.row() for lv in chosen.levels],
        "totals": totals,
        "comparison": comparison_pct(totals),
        "check": None if result is None else result.summary(),
        "program": str(output),
        "png": pngs,
        "violations": [] if limit_report is None else limit_report["violations"],
        "limits": limit_report,
    }
