"""What ``cutlab plan check`` does, and the limit steps of ``plan feed`` and ``plan rough``.

* :func:`check_job`: a program's blocks against the limits (violations, per-block table, PNG).
* :func:`feed_limiter`: the feed cap per piece for the post-processor (the load rule works below
  it) and the check of what it writes; with ``fix``, blocks still over a limit get their feed
  lowered to the cap.
* :func:`rough_limiter`: the check of a roughing program; with ``fix``, a level whose depth
  breaks the stability limit, or a force, deflection, power or torque limit that splitting cures
  in less time than a lower feed, is split into equal sub-levels (same shoulder, top down), and
  the blocks still over a limit get their feed lowered. Levels elsewhere are untouched.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from analysis.config import EndMill, EndMillCoefficients, MachineConfig, get_material, load_machine
from analysis.forces import ENDMILL
from analysis.validation import JsonObject, JsonValue
from planning.errors import PlanningError
from planning.feed import cap_feeds, end_mill
from planning.limits.check import FEED_LIMITS, CheckResult, Pieces, check_motion
from planning.limits.model import Limits, limits_for
from planning.nc import Motion, Program, interpret, motion_stats
from planning.stock import Simulation, ZMap
from planning.stock.plans import bind_tools

if TYPE_CHECKING:
    from planning.rough import Part, RoughPlan, RoughPlanner
    from planning.rough.job import LimitStep

#: progress of a Z-map run: (pieces done, pieces in all)
Progress = Callable[[int, int], None]
#: per-piece feed cap of planning.feed.FeedPostOptions: (simulation, rpm per piece) -> mm/min
FeedCap = Callable[[Simulation, NDArray[np.float64]], NDArray[np.float64]]
#: the check of a written program: (program, start stock, machine) -> (program, report)
CheckStep = Callable[[Program, ZMap, MachineConfig | None], tuple[Program, JsonObject]]

SPLIT_SLACK = 1.1  # sub-levels: depth / (needed reduction x this)
ROUNDS = 4  # split-and-recheck rounds before the remaining blocks get lower feeds


def coefficients(material: str | None) -> EndMillCoefficients:
    """The material's end-mill coefficients (configs/materials.toml)."""
    if not material:
        raise PlanningError("--material is required: the force model needs its [endmill] table")
    coef: EndMillCoefficients | None = ENDMILL.coefficients(get_material(material))
    if coef is None:
        raise PlanningError(f"material '{material}' has no [endmill] coefficients")
    return coef


def _check(
    program: Program, machine: MachineConfig | None, tool: EndMill, coef: EndMillCoefficients,
    limits: Limits, stock: ZMap, spindle_rpm: float | None, progress: Progress | None = None,
    dialect: str | None = None,
) -> tuple[Motion, CheckResult]:  # fmt: skip
    """``dialect``: the program's (default the machine's; the rough planner writes Fanuc)."""
    motion = interpret(program, machine, file=program.file, cutter_comp="refuse",
                       probing="refuse", dialect=dialect)  # fmt: skip
    res = check_motion(motion, tool, coef, limits, stock.copy(), spindle_rpm=spindle_rpm,
                       file=program.file, progress=progress)  # fmt: skip
    return motion, res


def _time_s(motion: Motion, machine: MachineConfig | None) -> float:
    return float(motion_stats(motion, machine).time_s)


def _lower_feeds(
    program: Program, motion: Motion, machine: MachineConfig | None, res: CheckResult
) -> tuple[Program, list[JsonValue]]:
    """Blocks over a feed-driven limit run at their cap (floored to 1 mm/min, not below the
    machine's minimum feed); what was lowered."""
    bad = {v["block"] for v in res.violations if v["limit"] in FEED_LIMITS}
    if not bad:
        return program, []
    caps = res.block_caps()
    f_min = machine.feed_min_mm_min if machine is not None else 1.0
    new: dict[int, float] = {b: max(math.floor(caps[b]), f_min) for b in bad if b in caps}
    feeds = res.blocks.set_index("block")["feed_mm_min"]
    done: list[JsonValue]
    done = [{"block": b, "feed_before_mm_min": float(feeds[b]), "feed_after_mm_min": float(f)}
            for b, f in sorted(new.items())]  # fmt: skip
    return cap_feeds(program, motion, machine, new), done


def feed_limiter(
    tool: EndMill, coef: EndMillCoefficients, limits: Limits, *, fix: bool,
    spindle_rpm: float | None = None,
) -> tuple[FeedCap | None, CheckStep]:  # fmt: skip
    """(the per-piece feed cap for :class:`planning.feed.FeedPostOptions` (None unless ``fix``),
    the step that checks the written program: ``(program, start stock, machine) -> (program,
    report)``)."""

    def cap(sim: Simulation, rpm: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.full(len(sim.piece_segment), np.inf)
        pieces = Pieces(tool, coef, limits, sim, rpm)
        out[pieces.cutting] = pieces.feed_cap_mm_min()
        return out

    def adjust(
        program: Program, stock: ZMap, machine: MachineConfig | None
    ) -> tuple[Program, JsonObject]:
        motion, res = _check(program, machine, tool, coef, limits, stock, spindle_rpm)
        found = len(res.violations)
        lowered: list[JsonValue] = []
        t0 = t1 = _time_s(motion, machine)
        if fix and res.violations:
            program, lowered = _lower_feeds(program, motion, machine, res)
            motion, res = _check(program, machine, tool, coef, limits, stock, spindle_rpm)
            t1 = _time_s(motion, machine)
        return program, {**res.summary(), "violations_found": found, "feeds_lowered": lowered,
                         "time_added_by_lowering_s": round(t1 - t0, 3)}  # fmt: skip

    return (cap if fix else None), adjust


def rough_limiter(
    *, fix: bool, machine: str | Path | MachineConfig | None = None, material: str | None = None,
    lobes: str | Path | None = None, spacing_mm: float = 1.0,
) -> LimitStep:  # fmt: skip
    """The limit step of ``plan rough``: ``(planner, plan, program) -> (plan, program, report)``
    (see the module's docstring), for the part's tool and material (``material`` overrides the
    part's ``cutting.material``) on ``machine``, on a Z-map of the stock box every
    ``spacing_mm``."""
    m = load_machine(machine) if isinstance(machine, (str, Path)) else machine

    def hook(
        planner: RoughPlanner, plan: RoughPlan, program: Program
    ) -> tuple[RoughPlan, Program, JsonObject]:
        part = planner.part
        mat = material or part.config.cutting.material
        if not mat:
            why = "no material: give cutting.material or --material"
            return plan, program, {"violations": [], "checked": False, "why": why,
                                   "verdict": "unchecked",
                                   "unchecked": [{"limit": "all", "reason": why}]}  # fmt: skip
        tool, coef = part.tool, coefficients(mat)
        limits = limits_for(tool, m, tool_name=part.config.tool.name, lobes=lobes)
        st = part.config.stock
        stock = ZMap.box(st.x_min_mm, st.x_max_mm, st.y_min_mm, st.y_max_mm, st.z_min_mm,
                         st.z_max_mm, spacing_mm)  # fmt: skip
        return _rough(planner, plan, program, tool, coef, limits, stock, m, fix)

    return hook


def _level_of_block(plan: RoughPlan, part: Part, motion: Motion) -> dict[int, int]:
    """Program block -> level index: the writer gives every feed segment its own block, in the
    order of the plan's motion (whose block field is the level)."""
    from planning.rough import plan_motion

    pm = plan_motion(plan, part)
    a, b = np.nonzero(pm.is_feed)[0], np.nonzero(motion.is_feed)[0]
    if len(a) != len(b):
        raise PlanningError("the rough program does not follow its plan (internal)")
    return dict(zip(motion.block[b].tolist(), pm.block[a].tolist()))


def _rough(
    planner: RoughPlanner, plan: RoughPlan, program: Program, tool: EndMill,
    coef: EndMillCoefficients, limits: Limits, stock: ZMap, machine: MachineConfig | None,
    fix: bool,
) -> tuple[RoughPlan, Program, JsonObject]:  # fmt: skip
    """The rough limit step proper (see :func:`rough_limiter`)."""
    from planning.rough import plan_program

    part = planner.part

    def totals(plan: RoughPlan, motion: Motion, res: CheckResult) -> dict[str, float]:
        return {"violations": len(res.violations), "levels": len(plan.levels),
                "cutting_path_mm": round(plan.path_mm, 2),
                "time_s": round(_time_s(motion, machine), 2)}  # fmt: skip

    motion, res = _check(program, machine, tool, coef, limits, stock, None, dialect="fanuc")
    before = totals(plan, motion, res)
    splits: list[JsonValue] = []
    lowered: list[JsonValue] = []
    uncured: dict[float, JsonValue] = {}  # level z -> why splitting cannot cure its chatter
    if fix and res.violations:
        dh = part.config.rough.dh_mm
        for _ in range(ROUNDS):
            need = _split_needs(res, _level_of_block(plan, part, motion), plan, dh, uncured)
            for lv_i in sorted(need, reverse=True):  # from the end: indices stay valid
                lv = plan.levels[lv_i]
                parts = min(need[lv_i], max(1, int(lv.height_mm / dh)))  # sub-levels >= dh
                if parts < 2:
                    need.pop(lv_i)
                    continue
                splits.append({"z_mm": round(lv.z_mm, 3), "height_mm": round(lv.height_mm, 3),
                               "parts": parts})  # fmt: skip
                plan = planner.split_level(plan, lv_i, parts)
            if not need:
                break
            program = plan_program(plan, part)
            motion, res = _check(program, machine, tool, coef, limits, stock, None, dialect="fanuc")
        program, lowered = _lower_feeds(program, motion, machine, res)
        if lowered:
            motion, res = _check(program, machine, tool, coef, limits, stock, None, dialect="fanuc")
    after = totals(plan, motion, res)
    report: JsonObject
    report = {**res.summary(), "before": dict(before), "after": dict(after), "levels_split": splits,
              "feeds_lowered": lowered, "not_split": list(uncured.values()),
              "time_lost_s": round(after["time_s"] - before["time_s"], 2),
              "path_added_mm": round(after["cutting_path_mm"] - before["cutting_path_mm"], 2)}
    return plan, program, report


def _split_needs(
    res: CheckResult, level_of: dict[int, int], plan: RoughPlan, dh_mm: float,
    uncured: dict[float, JsonValue],
) -> dict[int, int]:  # fmt: skip
    """Level index -> sub-levels it needs: a stability violation splits when sub-levels of at
    least the part's ``dh_mm`` get under the limit (else the level is named in ``uncured``: more
    passes that still chatter only multiply the path, and a lower feed does not cure chatter); a
    force-type one splits when that costs less time than the lower feed (k levels ~ k x the
    path, against feed / cap x the time)."""
    caps = res.block_caps()
    feeds = res.blocks.set_index("block")["feed_mm_min"]
    need: dict[int, int] = {}
    slow: dict[int, float] = {}
    stab: dict[int, tuple[int, float]] = {}  # level -> (sub-levels, least stable depth mm)
    for v in res.violations:
        lv = level_of.get(v["block"])
        if lv is None or v["limit"] == "chip":  # a chip limit is the feed's alone
            continue
        k = math.ceil(v["value"] / v["allowed"] * SPLIT_SLACK)
        if v["limit"] == "stability":
            k0, a0 = stab.get(lv, (1, math.inf))
            stab[lv] = (max(k0, k), min(a0, float(v["allowed"])))
            continue
        cap = caps.get(v["block"], math.inf)
        slow[lv] = max(slow.get(lv, 1.0), float(feeds[v["block"]]) / max(cap, 1e-9))
        if k < slow[lv]:
            need[lv] = max(need.get(lv, 1), k)
    for lv, (k, allowed) in stab.items():
        level = plan.levels[lv] if lv < len(plan.levels) else None
        if level is None or level.height_mm / k >= dh_mm:
            need[lv] = max(need.get(lv, 1), k)
            continue
        uncured[round(level.z_mm, 3)] = {
            "z_mm": round(level.z_mm, 3), "height_mm": round(level.height_mm, 3),
            "allowed_mm": round(allowed, 3), "sub_level_mm": round(level.height_mm / k, 3),
            "dh_mm": dh_mm,
        }  # fmt: skip
    return {lv: k for lv, k in need.items() if k >= 2 and lv < len(plan.levels)}


def _is_drilling(motion: Motion) -> bool:
    """Every feed move of a tool's section is along Z alone (hole cycles G81-G83, plunges)."""
    from planning.stock.machining import plunge_mask

    feed = motion.is_feed
    return bool(feed.any()) and bool(plunge_mask(motion.start[feed], motion.end[feed]).all())


def _lobes_for(
    lobes: str | Path | None, tools: dict[int, tuple[str, EndMill]], file: str
) -> dict[int, str | None]:
    """``--lobes FILE`` (a one-tool program) or ``T1=FILE,T2=FILE``: the table of each tool."""
    from planning.stock.plans import parse_tool_spec

    if lobes is None:
        return {t: None for t in tools}
    spec = parse_tool_spec(str(lobes))
    if isinstance(spec, str):
        if len(tools) > 1:
            raise PlanningError(
                f"{file}: --lobes = {lobes}: a lobes table is one tool's and the program loads "
                f"{', '.join(f'T{t}' for t in tools)}: give T<number>=FILE for each"
            )
        return {t: spec for t in tools}
    out: dict[int, str | None] = {t: None for t in tools}
    for key, path in spec.items():
        if not (key[:1] == "T" and key[1:].isdigit() and int(key[1:]) in tools):
            raise PlanningError(
                f"{file}: --lobes: {key}={path}: expected T<number>=FILE for a "
                f"tool the program loads ({', '.join(f'T{t}' for t in tools)})"
            )
        out[int(key[1:])] = path
    return out


def check_job(
    program_path: str | Path,
    *,
    tool_name: str | None,
    material: str | None,
    machine: str | Path = "ace-h63",
    stock_spec: str | None = None,
    spacing_mm: float | None = None,
    lobes: str | Path | None = None,
    force_limit_n: float | None = None,
    spindle_rpm: float | None = None,
    plot: str | Path | None = None,
    progress: Progress | None = None,
) -> tuple[list[CheckResult], JsonObject]:
    """``cutlab plan check``: every block of a program against the limits of its tool and
    machine, each tool's section (``tool_name`` ``T1=A,T2=B`` for a program that changes tools)
    with its own cutter and limits on the one stock; the per-block quantities to ``plot`` (PNG).
    A drilling section (Z-only feed moves) is machined but not checked (the end-mill force
    model does not hold for a drill): its limits are listed as unchecked. The verdict:
    "violations", else "unchecked" if any limit of any section could not be checked, else
    "within"."""
    from planning.feed.job import job_stock, refuse_no_removal
    from planning.limits.check import PIECE_MM, verdict
    from planning.nc import segment_time_s
    from planning.stock import simulate_motion
    from planning.stock.plans import Operation, parse_tool_spec

    file = str(program_path)
    m = load_machine(machine)
    if not tool_name:
        end_mill(tool_name)  # the error lists the end mills
    coef = coefficients(material)
    program = Program.read(program_path)
    motion = interpret(program, m, file=file, cutter_comp="refuse", probing="refuse")
    tools = bind_tools(motion, parse_tool_spec(tool_name), file)  # type: ignore[arg-type]
    radius = max(t.diameter_mm for _, t in tools.values()) / 2
    stock, stock_info = job_stock(motion, radius, stock_spec, spacing_mm, file)
    tables = _lobes_for(lobes, tools, file)
    time_s = segment_time_s(motion, m)
    results: list[CheckResult] = []
    sections: list[dict[str, Any]] = []
    first_limits = None
    for lo, hi, t in Operation("", motion, tools, file).runs():
        name, tool = tools[t]
        sub = motion[lo:hi]
        row: dict[str, Any] = {"tool_number": t, "tool": name, "segments": hi - lo,
                               "time_s": round(float(time_s[lo:hi].sum()), 3)}  # fmt: skip
        if _is_drilling(sub):
            sim = simulate_motion(stock, tool, sub, piece_mm=PIECE_MM, check_holder=False)
            unchecked: list[JsonValue]
            unchecked = [{"limit": "all", "reason": f"T{t} {name} only drills or plunges (Z-only "
                          "feed moves): the end-mill force model does not cover them"}]  # fmt: skip
            row |= {"removed_mm3": round(sim.removed_total_mm3, 3), "cutting_blocks": 0,
                    "violations": 0, "unchecked": unchecked, "verdict": "unchecked"}  # fmt: skip
            sections.append(row)
            continue
        limits = limits_for(tool, m, tool_name=name, lobes=tables[t],
                            force_limit_n=force_limit_n)  # fmt: skip
        before = stock.volume_mm3()
        res = check_motion(sub, tool, coef, limits, stock, spindle_rpm=spindle_rpm, file=file,
                           progress=progress)  # fmt: skip
        summ = res.summary()
        row |= {"removed_mm3": round(before - stock.volume_mm3(), 3),
                "cutting_blocks": summ["cutting_blocks"], "violations": len(res.violations),
                "unchecked": summ["unchecked"], "verdict": summ["verdict"],
                "worst": summ["worst"], "limits": summ["limits"]}  # fmt: skip
        first_limits = first_limits or summ["limits"]
        results.append(res)
        sections.append(row)
    removed = sum(r["removed_mm3"] for r in sections)
    refuse_no_removal(removed, stock_info, file)
    violations: list[JsonValue] = []
    unchecked = []
    for row, checked in _paired(sections, results):
        tag = f"T{row['tool_number']}" if len(tools) > 1 else None
        if checked is not None:
            violations += [v | ({"tool": tag} if tag else {}) for v in checked.violations]
        unchecked += [u | ({"tool": tag} if tag else {}) for u in row["unchecked"]]
    worst: dict[str, Any] = {}
    for row in sections:
        for k, w in row.get("worst", {}).items():
            if k not in worst or w["margin_pct"] < worst[k]["margin_pct"]:
                worst[k] = w | ({"tool": f"T{row['tool_number']}"} if len(tools) > 1 else {})
    out: JsonObject = {"program": file, "tool": tool_name, "material": material, "machine": m.name,
           "verdict": verdict(violations, unchecked), "violations": violations,
           "unchecked": unchecked, "limits": first_limits,
           "cutting_blocks": sum(r["cutting_blocks"] for r in sections), "worst": worst,
           "stock": stock_info, "removed_mm3": round(removed, 3),
           "time_s": round(float(time_s.sum()), 3), "tools": list(sections),
           "png": None}  # fmt: skip
    if plot:
        from planning.limits.plot import plot_check

        out["png"] = str(plot_check(results, plot, f"{Path(program_path).name}: limits per block"))
    return results, out


def _paired(
    sections: list[dict[str, Any]], results: list[CheckResult]
) -> Iterator[tuple[dict[str, Any], CheckResult | None]]:
    """Each section with its check (None for a drilling section), in program order."""
    it = iter(results)
    for row in sections:
        yield row, (next(it) if "limits" in row else None)
