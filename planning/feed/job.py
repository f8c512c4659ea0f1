"""What ``cutlab plan feed`` and ``cutlab plan simulate`` do (seed 001), from files to written
files and plain data.

* :func:`feed_program` (``cutlab plan feed IN.nc --rules RULE [--machine M] [--tool T]
  [--stock S] [--dialect D] -o OUT.nc``) computes each block's cutting load on a Z-map, picks
  feeds from the rule (a rule file, or a rule-base name / id), splits blocks where the load
  changes, clamps to the machine, and writes OUT.nc with only F words and splits changed, for the
  ``dialect`` controller (default the machine's: :func:`planning.nc.output.for_dialect`), plus a
  report (CSV, PNGs) next to it.
* :func:`simulate_job` (``cutlab plan simulate IN.nc|PLAN.toml [--tool T | T1=A,T2=B] [--stock S]
  --png stock.png``): virtual machining alone (removed volume, time, holder contacts, final
  stock PNG). A plan file runs several programs, each with its tool, on the same stock.

Every input problem (missing tool, a rule with gaps, a program outside the stock or the machine's
travel, an arc the machine cannot cut) is reported before any file is written.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TypedDict, Unpack

import numpy as np

from analysis.config import EndMill, MachineConfig, get_material, load_machine
from analysis.rules import FeedRule, RuleBase, load_rule
from analysis.validation import JsonObject, JsonValue
from planning.errors import PlanningError
from planning.feed.post import post_process
from planning.feed.report import FeedReportPaths, write_report
from planning.feed.result import FeedCap, FeedPostOptions, FeedPostResult, Section
from planning.nc import Motion, Program, interpret
from planning.nc.output import DIALECTS, default_dialect, for_dialect
from planning.stock import ZMap, load_stock, save_stock_png
from planning.stock.plans import (
    Operation,
    OperationPlan,
    OperationResult,
    ToolMap,
    bind_tools,
    end_mill,
    load_plan,
    parse_tool_spec,
    summary,
)

Progress = Callable[[int, int], None]  # (pieces done, pieces in all)
# (adjusted program, starting stock, machine) -> (program, report): planning.limits
LimitStep = Callable[[Program, ZMap, MachineConfig], tuple[Program, JsonObject]]


class FeedOptions(TypedDict, total=False):
    """The keywords of :func:`feed_post_options`."""

    min_piece_mm: float
    split: bool
    check_holder: bool
    force_limit_n: float | None
    material: str | None
    spindle_rpm: float | None
    feed_cap: FeedCap | None


#: the derived stock's top: Z0 (work zero on the stock top, the usual convention) when every
#: level the program cuts (a Z-constant feed move) is below it, else this far above the highest
STOCK_ALLOWANCE_MM = 1.0


def job_stock(
    motion: Motion, radius_mm: float, stock_spec: str | None, spacing_mm: float | None,
    file: str = "<program>",
) -> tuple[ZMap, JsonObject]:  # fmt: skip
    """The starting stock and where it came from (printed and in JSON): ``stock_spec`` (see
    :func:`load_stock`), else a box over the program's feed moves: their XY extent plus the
    widest cutter's ``radius_mm``, bottom 1 mm below the deepest, top at Z0, or
    :data:`STOCK_ALLOWANCE_MM` above the highest level cut when that is at or above Z0."""
    if stock_spec:
        return load_stock(stock_spec, spacing_mm), {"source": "--stock", "spec": stock_spec}
    from planning.nc import bounding_box

    feed = motion.is_feed
    if not feed.any():
        raise PlanningError(f"{file}: the program has no feed moves: give the stock (--stock)")
    lo, hi = bounding_box(motion[feed])
    level = feed & (np.abs(motion.start[:, 2] - motion.end[:, 2]) < 1e-9)
    top = 0.0
    if level.any() and float(motion.end[level, 2].max()) >= 0.0:
        top = float(motion.end[level, 2].max()) + STOCK_ALLOWANCE_MM
    bottom = min(float(lo[2]) - 1.0, -1.0)
    r = radius_mm
    box = (float(lo[0]) - r, float(hi[0]) + r, float(lo[1]) - r, float(hi[1]) + r, bottom, top)
    spec = "box:" + ",".join(f"{v:.6g}" for v in box)
    info: JsonObject
    info = {"source": "derived", "spec": spec, "allowance_mm": STOCK_ALLOWANCE_MM,
            "how": "the feed moves' XY extent plus the cutter radius; top at Z0, or "
                   f"{STOCK_ALLOWANCE_MM:g} mm above the highest level cut if that is not below "
                   "Z0; bottom 1 mm below the deepest feed move (give --stock for the real "
                   "one)"}  # fmt: skip
    return load_stock(spec, spacing_mm), info


def refuse_no_removal(removed_mm3: float, stock: JsonObject, file: str) -> None:
    """A program that removes nothing from its stock is an error naming the stock: its times
    and loads would say nothing of the part (every feed raised to the rule's maximum)."""
    if removed_mm3 <= 1e-6:
        raise PlanningError(
            f"{file}: the program removes nothing from its stock {stock['spec']} "
            f"({'--stock' if stock['source'] == '--stock' else 'derived'}): give the stock it "
            "cuts (--stock box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP)"
        )


@dataclass(frozen=True)
class Job:
    """One program ready to machine: its machine, end mill, text, motion and starting stock."""

    machine: MachineConfig
    tools: ToolMap  # T number -> (name, end mill) of each tool the program loads
    program: Program
    motion: Motion
    stock: ZMap
    stock_info: JsonObject = field(default_factory=dict)  # where the stock came from

    @property
    def tool(self) -> EndMill:
        """The first end mill the program loads (each tool's run: :func:`tool_sections`)."""
        return next(iter(self.tools.values()))[1]


def load_job(
    program_path: str | Path,
    machine: str | Path,
    tool_name: str | None,
    stock_spec: str | None = None,
    spacing_mm: float | None = None,
) -> Job:
    """Read and interpret a program (cutter compensation refused) for ``machine`` and the end
    mill ``tool_name`` (or ``T1=NAME,T2=NAME``: one per tool the program loads); the stock from
    ``stock_spec`` (see :func:`load_stock`), else derived (:func:`job_stock`)."""
    m = load_machine(machine)
    if not tool_name:
        end_mill(tool_name)  # the error lists the end mills
    program = Program.read(program_path)
    motion = interpret(program, m, file=str(program_path), cutter_comp="refuse", probing="refuse")
    tools = bind_tools(motion, parse_tool_spec(tool_name), str(program_path))  # type: ignore[arg-type]
    radius = max(t.diameter_mm for _, t in tools.values()) / 2
    stock, info = job_stock(motion, radius, stock_spec, spacing_mm, str(program_path))
    return Job(m, tools, program, motion, stock, info)


def resolve_rule(spec: str, db: str | Path | None = None) -> FeedRule:
    """A feed rule from a file (an existing path, or any ``.toml``), else by rule name or group
    id in the rule base ``db`` (default from configs/lab.toml; it must exist)."""
    p = Path(spec)
    if p.exists() or p.suffix == ".toml":
        return load_rule(p)
    with RuleBase(db, create=False) as base:
        return base.find(spec).rule


def feed_post_options(
    *,
    min_piece_mm: float = 5.0,
    split: bool = True,
    check_holder: bool = True,
    force_limit_n: float | None = None,
    material: str | None = None,
    spindle_rpm: float | None = None,
    feed_cap: FeedCap | None = None,
) -> FeedPostOptions:
    """The post-processor's options; a force limit needs a ``material`` (configs/materials.toml)
    with end-mill force coefficients."""
    if force_limit_n is not None and not material:
        raise PlanningError("--force-limit needs --material (its [endmill] coefficients)")
    coef = None
    if material:
        coef = get_material(material).endmill
        if coef is None:
            raise PlanningError(f"material '{material}' has no [endmill] coefficients")
    return FeedPostOptions(
        min_piece_mm=min_piece_mm,
        split=split,
        check_holder=check_holder,
        force_limit_n=force_limit_n,
        coefficients=coef,
        spindle_rpm=spindle_rpm,
        feed_cap=feed_cap,
    )


def feed_program(
    program_path: str | Path,
    rule_spec: str | None,
    output: str | Path,
    *,
    db: str | Path | None = None,
    machine: str | Path = "ace-h63",
    tool_name: str | None = None,
    stock_spec: str | None = None,
    spacing_mm: float | None = None,
    report_dir: str | Path | None = None,
    progress: Progress | None = None,
    warn: Callable[[str], None] | None = None,
    dialect: str | None = None,
    limit_step: LimitStep | None = None,
    rules_material: str | None = None,
    **options: Unpack[FeedOptions],
) -> tuple[FeedPostResult, JsonObject]:
    """``cutlab plan feed``: feeds of a program set by the rule's predicted cutting load,
    written to ``output`` for the ``dialect`` controller (default: the machine's; the program is
    read in the machine's) with its report (``report_dir``, default ``output``'s folder).

    ``rule_spec`` None: each tool's rule is looked up in the rule base ``db`` by tool and
    ``rules_material`` (:func:`lookup_rules`; the summary's ``rule_lookup`` says what was found).
    ``options`` go to :func:`feed_post_options`; ``warn`` hears a rule derived with another
    tool. ``limit_step`` (planning.limits.feed_limiter) checks the adjusted program against the
    machine's and tool's limits before it is written, and may lower feeds further; its report is
    the summary's ``limits``, its violations the summary's ``violations``. Returns the result
    (its program in the machine's dialect) and its summary (with the written paths and the
    dialect) as plain data.
    """
    if dialect is not None and dialect not in DIALECTS:
        raise PlanningError(f"dialect = {dialect!r}: expected one of {', '.join(DIALECTS)}")
    material = rules_material or options.get("material")
    job, rules, lookup, rule_spec = _job_and_rules(
        program_path, rule_spec, db, material, machine, tool_name, stock_spec, spacing_mm
    )
    sections, rule = _rule_sections(job, rules, rule_spec, str(program_path), warn)
    opts = feed_post_options(**options)
    start = job.stock.copy() if limit_step is not None else job.stock
    result = post_process(
        job.program, job.motion, sections[0].tool, rule, job.stock, job.machine, opts,
        progress=progress, sections=sections,
    )  # fmt: skip
    refuse_no_removal(result.simulation.removed_total_mm3, job.stock_info, str(program_path))
    limits = None
    if limit_step is not None:
        program, limits = limit_step(result.program, start, job.machine)
        result = replace(result, program=program)
    dialect = dialect or default_dialect(job.machine)
    report = _write_outputs(result, job.machine, dialect, Path(output), report_dir)
    summ = result.summary()
    summ.update(
        {"output": str(output), "dialect": dialect,
         "report": {k: str(v) for k, v in report.items()}}
    )  # fmt: skip
    summ["stock"] = job.stock_info
    summ["tools"] = tool_figures(result)
    if lookup is not None:
        summ["rule_lookup"] = lookup
    _add_verdict(summ, limits)
    slower = _slower(result.time_before_s, result.time_after_s)  # as in the summary
    summ["slower_than_input"] = slower
    if slower and warn is not None:
        warn(f"warning: {slower}")
    return result, summ


def _job_and_rules(
    program_path: str | Path, rule_spec: str | None, db: str | Path | None,
    material: str | None, machine: str | Path, tool_name: str | None,
    stock_spec: str | None, spacing_mm: float | None,
) -> tuple[Job, FeedRule | dict[str, FeedRule], list[JsonValue] | None, str]:  # fmt: skip
    """The job and its rules (``--rules``, else looked up by tool and ``material``), the
    look-up's notes (None with ``--rules``) and the rules' spec as said in errors."""
    if rule_spec is None:
        if not material:
            raise PlanningError("no --rules: give --material, each tool's rule is looked up in "
                                "the rule base by tool and material")  # fmt: skip
        job = load_job(program_path, machine, tool_name, stock_spec, spacing_mm)
        found, lookup = lookup_rules(job, material, db, str(program_path))
        spec = ",".join(f"{k}={v.name}" for k, v in found.items()) or "(rule base)"
        return job, found, lookup, spec
    rules = resolve_rules(rule_spec, db)  # a missing rule file is named before the program
    job = load_job(program_path, machine, tool_name, stock_spec, spacing_mm)
    return job, rules, None, rule_spec


def _rule_sections(
    job: Job, rules: FeedRule | dict[str, FeedRule], rule_spec: str, file: str,
    warn: Callable[[str], None] | None,
) -> tuple[list[Section], FeedRule]:  # fmt: skip
    """Each tool's run with its rule, and the first rule (an error when no tool has one); a
    rule derived with another tool is warned of."""
    sections = tool_sections(job, rules, rule_spec, file)
    rule = next((sc.rule for sc in sections if sc.rule is not None), None)
    if rule is None:
        raise PlanningError(f"{file}: --rules = {rule_spec}: no tool of the program has "
                            "a rule: nothing to adjust")  # fmt: skip
    for sc in sections:
        if sc.rule is not None and sc.rule.tool and sc.rule.tool != sc.tool_name and warn:
            warn(
                f"warning: rule '{sc.rule.name}' was derived with tool '{sc.rule.tool}', not "
                f"'{sc.tool_name}': its loads (relative to that tool's size) do not carry over"
            )
    return sections, rule


def _write_outputs(
    result: FeedPostResult, machine: MachineConfig, dialect: str, out: Path,
    report_dir: str | Path | None,
) -> FeedReportPaths:  # fmt: skip
    """The adjusted program written for ``dialect`` to ``out`` and its report beside it (or
    in ``report_dir``): the report's paths."""
    written = for_dialect(result.program, dialect, machine)  # the F edits and splits kept
    out.parent.mkdir(parents=True, exist_ok=True)
    written.write(out)
    return write_report(result, report_dir or out.parent, out.stem)


def _add_verdict(summ: JsonObject, limits: JsonObject | None) -> None:
    """The limits' verdict, violations and unchecked limits into the summary ("unchecked"
    without a limit step)."""
    if limits is not None:
        summ.update(verdict=limits["verdict"], violations=limits["violations"],
                    unchecked=limits["unchecked"], limits=limits)  # fmt: skip
    else:
        why = "no --material: the limits need its force coefficients"
        summ.update(verdict="unchecked", violations=[], unchecked=[{"limit": "all", "reason": why}])


def _drilling(motion: Motion) -> bool:
    """Every feed move is along Z alone (hole cycles G81-G83, plunges)."""
    from planning.stock.machining import plunge_mask

    feed = motion.is_feed
    return bool(feed.any()) and bool(plunge_mask(motion.start[feed], motion.end[feed]).all())


def lookup_rules(
    job: Job, material: str, db: str | Path | None, file: str
) -> tuple[dict[str, FeedRule], list[JsonValue]]:
    """Each tool's rule from the rule base by tool and material (``--rules`` not given): the
    rules found (``{"T1": rule}``) and, per tool, what was found or why none (a drilling run, a
    tool the base lacks: the tool keeps its feeds)."""
    op = Operation(Path(file).stem, job.motion, job.tools, file)
    runs = op.runs()
    found: dict[str, FeedRule] = {}
    notes: list[JsonValue] = []
    with RuleBase(db, create=False) as base:
        for t, (name, tool) in job.tools.items():
            row: JsonObject = {"tool_number": t, "tool": name, "rule": None}
            mine = [(lo, hi) for lo, hi, n in runs if n == t]
            if mine and all(_drilling(job.motion[lo:hi]) for lo, hi in mine):
                row["reason"] = "only drills (Z-only feed moves): feeds kept"
            elif (m := base.for_tool(name, material, tool.diameter_mm,
                                     tool.flute_length_mm)) is None:  # fmt: skip
                row["reason"] = (f"the rule base has no rule for {name} in {material}: "
                                 "feeds kept")  # fmt: skip
            else:
                found[f"T{t}"] = m.group.rule
                row.update(rule=m.group.rule_name, group=m.group.id, exact=m.exact)
                if not m.exact:
                    row["reason"] = (f"no rule derived with {name}: group {m.group.id}'s, of the "
                                     "same diameter and flute length")  # fmt: skip
            notes.append(row)
    return found, notes


def resolve_rules(rule_spec: str, db: str | Path | None) -> FeedRule | dict[str, FeedRule]:
    """``--rules``: one rule (file or rule-base name / id), or ``T1=RULE,T2=RULE``."""
    if "=" in rule_spec and not Path(rule_spec).exists():
        spec = parse_tool_spec(rule_spec)
        assert isinstance(spec, dict)  # "=" in it
        return {k: resolve_rule(v, db) for k, v in spec.items()}
    return resolve_rule(rule_spec, db)


def tool_sections(
    job: Job, spec: FeedRule | dict[str, FeedRule], rule_spec: str, file: str
) -> list[Section]:
    """Each tool's run of the program with its rule: ``spec`` is one rule (a one-tool program)
    or ``{"T1": rule, ...}``; a tool the map leaves out keeps its feeds (listed). A rule for a
    drilling run (Z-only feed moves) is refused: the load model is a milling cutter's."""
    op = Operation(Path(file).stem, job.motion, job.tools, file)
    runs = op.runs()
    if isinstance(spec, FeedRule):
        if len(job.tools) > 1:
            each = ",".join(f"T{n}=RULE" for n in job.tools)
            raise PlanningError(
                f"{file}: the program changes tools ({', '.join(f'T{n}' for n in job.tools)}) "
                f"and --rules = {rule_spec!r} is one rule: give each tool's ({each}; a tool left "
                "out keeps its feeds)"
            )
        spec = {f"T{t}": spec for t in job.tools}
    rules: dict[int, FeedRule] = {}
    for key, val in spec.items():
        if not (key[:1] == "T" and key[1:].isdigit() and int(key[1:]) in job.tools):
            raise PlanningError(
                f"{file}: --rules: {key}={val.name!r}: expected T<number>=RULE for a tool the "
                f"program loads ({', '.join(f'T{t}' for t in job.tools)})"
            )
        rules[int(key[1:])] = val
    out = []
    for lo, hi, t in runs:
        name, tool = job.tools[t]
        rule = rules.get(t)
        if rule is not None and len(job.tools) > 1 and _drilling(job.motion[lo:hi]):
            raise PlanningError(
                f"{file}: --rules T{t}={rule.name}: T{t} ({name}) only drills (Z-only feed "
                "moves): the load rule is a milling cutter's; leave T{t} out (feeds kept)"
            )
        out.append(Section(lo, hi, tool, rule, t, name))
    return out


def tool_figures(result: FeedPostResult) -> list[JsonValue]:
    """Per tool run: its rule (None: feeds kept), removed volume, and the time of its blocks
    with feed moves before and after, s (rapid-only blocks do not change)."""
    sim, bt = result.simulation, result.blocks
    out: list[JsonValue] = []
    for sc in result.sections:
        blocks = np.unique(result.motion_before.block[sc.lo : sc.hi])
        k = np.isin(bt.block, blocks)
        before = float(bt.time_before_s[k].sum())
        after = float(bt.time_after_s[k].sum())
        out.append({"tool_number": sc.tool_number, "tool": sc.tool_name,
                    "rule": sc.rule.name if sc.rule is not None else None,
                    "removed_mm3": round(float(sim.removed_mm3[sc.lo : sc.hi].sum()), 3),
                    "feed_time_before_s": round(before, 3), "feed_time_after_s": round(after, 3),
                    "feed_blocks": int(k.sum())})  # fmt: skip
    return out


#: a result slower than its input by more than this is said so (a rule for another tool or
#: material, or feeds in the wrong unit, can make it several times slower)
SLOWER_WARN_PCT = 3.0


def _slower(before: float, after: float) -> str | None:
    if not before > 0 or after <= before * (1 + SLOWER_WARN_PCT / 100):
        return None
    return (
        f"the adjusted program is slower than its input: {before:.1f} s -> {after:.1f} s "
        f"({after / before:.2f}x): the rule's feeds for these loads are below the program's "
        "(check the rule, its tool and the program's feeds)"
    )


def _number(v: JsonValue) -> float:
    assert isinstance(v, int | float)  # a summary's numbers
    return v


def simulate_job(
    program_path: str | Path,
    *,
    machine: str | Path = "ace-h63",
    tool_name: str | None = None,
    stock_spec: str | None = None,
    spacing_mm: float | None = None,
    check_holder: bool = True,
    png: str | Path | None = None,
    progress: Progress | None = None,
) -> tuple[list[OperationResult], JsonObject]:
    """``cutlab plan simulate``: virtual machining of an operation plan (a ``.toml``: its own
    stock, machine and tools) or of one program with ``tool_name`` on its stock; the final
    stock's picture to ``png``. Returns the operations' results and the summary as plain data.
    """
    if Path(program_path).suffix.lower() == ".toml":
        plan, _ = load_plan(program_path, spacing_mm)
        stock_info: JsonObject = {"source": "operation plan", "spec": str(program_path)}
    else:
        job = load_job(program_path, machine, tool_name, stock_spec, spacing_mm)
        op = Operation(Path(program_path).stem, job.motion, job.tools, str(program_path))
        plan = OperationPlan(job.stock, [op], job.machine)
        stock_info = job.stock_info
    start_volume = plan.stock.volume_mm3()
    cb = None if progress is None else (lambda name, done, total: progress(done, total))
    results = plan.run(check_holder=check_holder, progress=cb)
    rows = [summary(r) for r in results]
    if png:
        title = f"stock after {', '.join(str(r['operation']) for r in rows)}"
        save_stock_png(plan.stock, png, title)
    out: JsonObject = {
        "operations": list(rows),
        "stock_volume_before_mm3": start_volume,
        "stock_volume_after_mm3": plan.stock.volume_mm3(),
        "removed_mm3": sum(_number(r["removed_mm3"]) for r in rows),
        "time_s": sum(_number(r["time_s"]) for r in rows),
        "png": str(png) if png else None,
        "stock": stock_info,
    }
    return results, out
