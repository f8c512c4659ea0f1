"""Operation plans (seed 001 3): one die as an ordered list of NC programs, each with its tool
and holder, machined on the same stock (:mod:`planning.stock.machining` cuts each), so that the
pencil or rest-roughing program meets what the roughing left; and the tools a program uses.

Plan file (TOML, :func:`load_plan`): the stock table above plus::

    [plan]
    machine = "ace-h63"            # name in configs/machines or a path (optional)
    [[operations]]
    name = "roughing"
    program = "rough.nc"           # relative to the plan file
    tool = "phi50-bull"            # name in configs/tools.toml (or --tools), for one tool
    # tools = { T1 = "phi10-flat", T2 = "phi5-drill" }   # instead: a program that changes tools
    rule = "rules/rough.toml"      # optional: the feed rule of this operation

A program is cut with the tool in the spindle: each consecutive run of segments with its own T
number (after M6) is simulated with the end mill mapped to it (:func:`bind_tools`); a program
whose T numbers are not all mapped, or that changes tools under a single ``tool``, is refused.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from analysis.config import EndMill, MachineConfig, get_tool, load_machine
from analysis.forces import ENDMILL
from analysis.validation import JsonObject, Model, read_toml, validate
from planning.errors import PlanningError
from planning.nc import Motion, segment_time_s
from planning.nc.arcs import segment_length_mm
from planning.stock.machining import (
    Simulation,
    check_motion,
    simulate_motion,
)
from planning.stock.starts import _stock_from_model, _StockModel
from planning.stock.zmap import Cutter, ZMap

#: T number -> (tool name, end mill) of every tool a program uses (0: the program has no M6)
ToolMap = dict[int, tuple[str, EndMill]]


def parse_tool_spec(text: str) -> str | dict[str, str]:
    """``NAME`` or ``T1=NAME,T2=NAME`` (the ``--tool`` of a program that changes tools)."""
    if "=" not in text:
        return text
    out = {}
    for item in text.split(","):
        key, _, name = item.partition("=")
        out[key.strip().upper()] = name.strip()
    return out


def bind_tools(
    motion: Motion, spec: str | Mapping[str, str], file: str = "<program>", what: str = "--tool"
) -> ToolMap:
    """The end mill of each T number the program loads (M6), from one tool name (a program that
    does not change tools) or a map ``{"T1": name, ...}``; refuse, naming the block, a tool change
    under one name or a T number the map lacks. Segments before the first M6 are cut with the
    first tool loaded."""
    used = list(dict.fromkeys(int(t) for t in motion.tool if t != 0))

    def block(t: int) -> str:
        i = int(np.argmax(motion.tool == t))
        return f"{file}:{int(motion.line[i])}: block {int(motion.block[i])}"

    if isinstance(spec, str):
        if len(used) > 1:
            a, b = used[:2]
            hint = (f"--tool T{a}=NAME,T{b}=NAME" if what.startswith("--")
                    else f'tools = {{ T{a} = "NAME", T{b} = "NAME" }}')  # fmt: skip
            raise PlanningError(
                f"{block(b)}: the program changes from T{a} to T{b} (M6), but {what} = {spec!r} "
                f"is one end mill: map each tool ({hint})"
            )
        return {used[0] if used else 0: (spec, end_mill(spec, what))}
    numbers = {}
    for key, name in spec.items():
        if not (key[:1] in "Tt" and key[1:].isdigit()) or not name:
            raise PlanningError(
                f"{file}: {what}: {key}={name!r}: expected T<number>=TOOL, e.g. T1=phi10-flat"
            )
        numbers[int(key[1:])] = name
    if not used:
        if len(numbers) != 1:
            raise PlanningError(f"{file}: the program loads no tool (no T M6): {what} needs one")
        used = list(numbers)
    for t in used:
        if t not in numbers:
            raise PlanningError(
                f"{block(t)}: T{t} (M6) is not in {what} ({', '.join(f'T{n}' for n in numbers)}):"
                f" map it to a tool, e.g. T{t}=NAME"
            )
    return {t: (numbers[t], end_mill(numbers[t], f"{what} T{t}")) for t in used}


def end_mill(name: str | None, what: str = "--tool") -> EndMill:
    """The end mill ``name`` of the tool catalogues (the Z-map models end mills only)."""
    from analysis.config import load_tools

    if not name:
        known = ", ".join(sorted(k for k, t in load_tools().items() if ENDMILL.describes(t)))
        raise PlanningError(f"{what} is required (an end mill of the tool catalogue): {known}")
    tool = get_tool(name)
    if not ENDMILL.describes(tool):
        raise PlanningError(f"{what} = {name!r} is a {tool.kind}: the Z-map models end mills only")
    return tool


@dataclass(frozen=True)
class Operation:
    """One program of a plan: its motion, its tools (with holders) and optional feed rule path."""

    name: str
    motion: Motion
    tools: ToolMap
    file: str = "<program>"
    rule_path: str | None = None

    @property
    def tool(self) -> EndMill:
        """The first tool the program loads."""
        return next(iter(self.tools.values()))[1]

    @property
    def tool_name(self) -> str:
        if len(self.tools) == 1:
            return next(iter(self.tools.values()))[0]
        return ",".join(f"T{t}={n}" for t, (n, _) in self.tools.items())

    def runs(self) -> list[tuple[int, int, int]]:
        """(first segment, end segment, T number) of each consecutive run of one tool; segments
        before the first M6 go with the first tool."""
        first = next(iter(self.tools))
        t = np.where(self.motion.tool == 0, first, self.motion.tool)
        if len(self.tools) == 1:
            t[:] = first  # one tool named: it cuts everything (bind_tools refused a change)
        cut = np.flatnonzero(np.diff(t)) + 1
        bounds = [0, *cut.tolist(), len(t)]
        return [(a, b, int(t[a])) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


@dataclass(frozen=True)
class OperationResult:
    operation: Operation
    simulation: Simulation
    time_s: float
    removed_mm3: float
    stock_volume_after_mm3: float
    #: per tool run: (T number, tool name, segments, removed mm^3, time s)
    tool_runs: tuple[tuple[int, str, int, float, float], ...] = ()


@dataclass
class OperationPlan:
    """Ordered programs machined on one stock (seed 001's operation plan).

    ``run`` lowers ``stock`` in place; keep ``stock.copy()`` if the start is needed again.
    """

    stock: ZMap
    operations: list[Operation]
    machine: MachineConfig | None = None

    def check(self) -> None:
        """Refuse the whole plan before anything is cut if one program cannot run."""
        for op in self.operations:
            widest = max((m for _, m in op.tools.values()), key=lambda m: m.diameter_mm)
            check_motion(op.motion, self.machine, self.stock, Cutter.from_tool(widest), op.file)

    def run(
        self,
        piece_mm: float = math.inf,
        check_holder: bool = True,
        progress: Callable[[str, int, int], None] | None = None,
    ) -> list[OperationResult]:
        self.check()
        out = []
        for op in self.operations:
            cb = None if progress is None else (lambda d, t, n=op.name: progress(n, d, t))
            time_s = segment_time_s(op.motion, self.machine)
            parts, runs = [], []
            for lo, hi, t in op.runs():  # each tool cuts its own blocks (seed 001 2.1)
                name, tool = op.tools[t]
                sim = simulate_motion(
                    self.stock, tool, op.motion[lo:hi], piece_mm=piece_mm,
                    check_holder=check_holder, progress=cb,
                )  # fmt: skip
                parts.append((lo, sim))
                runs.append((t, name, hi - lo, sim.removed_total_mm3, float(time_s[lo:hi].sum())))
            sim = join_simulations(op.motion, parts)
            out.append(
                OperationResult(
                    operation=op,
                    simulation=sim,
                    time_s=float(time_s.sum()),
                    removed_mm3=sim.removed_total_mm3,
                    stock_volume_after_mm3=self.stock.volume_mm3(),
                    tool_runs=tuple(runs),
                )
            )
        return out


def join_simulations(motion: Motion, parts: list[tuple[int, Simulation]]) -> Simulation:
    """One simulation of ``motion`` from those of its consecutive slices (first segment, sim)."""
    if len(parts) == 1:
        return parts[0][1]

    def cat(name: str, shift: int = 0) -> NDArray[Any]:  # each field's own dtype
        return np.concatenate([getattr(s, name) + (lo if shift else 0) for lo, s in parts])

    return Simulation(
        motion, cat("piece_segment", 1), cat("piece_start_mm"), cat("piece_end_mm"),
        cat("piece_removed_mm3"), cat("removed_mm3"), cat("piece_depth_mm"),
        tuple(c for _, s in parts for c in s.contacts), cat("rapid_cut_segments", 1),
        cat("piece_arcs") if all(s.piece_arcs is not None for _, s in parts) else None,
    )  # fmt: skip


def summary(result: OperationResult) -> JsonObject:
    """Plain-data summary of one operation's virtual machining (for JSON and tables)."""
    sim = result.simulation
    m = sim.motion
    length = segment_length_mm(m)
    return {
        "operation": result.operation.name,
        "file": result.operation.file,
        "tool": result.operation.tool_name,
        "segments": len(m),
        "feed_path_mm": float(length[m.is_feed].sum()),
        "cutting_path_mm": float(length[m.is_feed & (sim.removed_mm3 > 1e-9)].sum()),
        "removed_mm3": result.removed_mm3,
        "time_s": result.time_s,
        "stock_volume_after_mm3": result.stock_volume_after_mm3,
        "holder_contacts": [
            {"block": c.block, "line": c.line, "part": c.part, "overlap_mm": c.overlap_mm}
            for c in sim.contacts
        ],
        "rapid_cut_blocks": [int(m.block[i]) for i in sim.rapid_cut_segments],
        "tools": [
            {"T": t, "tool": name, "segments": n, "removed_mm3": v, "time_s": ts}
            for t, name, n, v, ts in result.tool_runs
        ],
    }


# ---------------------------------------------------------------------------------- files


class _OperationModel(Model):
    name: str = Field(min_length=1)
    program: str = Field(min_length=1, description="NC file, relative to the plan file")
    tool: str | None = Field(
        None, min_length=1, description="tool name in the tool catalogue: a one-tool program"
    )
    tools: dict[str, str] | None = Field(
        None, description="T number -> tool name, e.g. { T1 = \"phi10-flat\" }, for a program "
        "that changes tools (M6)"
    )  # fmt: skip

    @model_validator(mode="after")
    def _one_of(self) -> _OperationModel:
        if (self.tool is None) == (self.tools is None):
            raise ValueError("give tool = NAME (one tool) or tools = { T1 = NAME, ... }")
        return self

    rule: str | None = Field(None, description="feed rule file or rule-base name")


class _PlanHeader(Model):
    machine: str | None = None
    description: str = ""


class _PlanModel(Model):
    plan: _PlanHeader = _PlanHeader()
    stock: _StockModel
    operations: tuple[_OperationModel, ...] = Field(min_length=1)


def load_plan(
    path: str | Path, spacing_mm: float | None = None, strict: bool = True
) -> tuple[OperationPlan, list[str | None]]:
    """An operation plan from its TOML file; returns the plan and each operation's rule spec.

    Every program is read and interpreted now, so a bad program or tool is reported before
    anything is cut.
    """
    from planning.nc import interpret_file

    p = Path(path)
    data, raw = read_toml(p)
    model = validate(_PlanModel, data, str(p), raw)
    machine = load_machine(model.plan.machine) if model.plan.machine else None
    stock = _stock_from_model(model.stock, str(p), p.parent, spacing_mm)
    ops = []
    for i, o in enumerate(model.operations):
        prog = Path(o.program) if Path(o.program).is_absolute() else p.parent / o.program
        motion = interpret_file(
            prog, machine, strict=strict, cutter_comp="refuse", probing="refuse"
        )
        what = f"{p}: operations[{i}].{'tool' if o.tools is None else 'tools'}"
        # arg-type: _OperationModel's validator guarantees one of tool and tools is set
        tools = bind_tools(motion, o.tools or o.tool, str(prog), what)  # type: ignore[arg-type]
        ops.append(Operation(o.name, motion, tools, str(prog), o.rule))
    return OperationPlan(stock, ops, machine), [o.rule for o in model.operations]


__all__ = [
    "Operation",
    "OperationPlan",
    "OperationResult",
    "ToolMap",
    "bind_tools",
    "end_mill",
    "join_simulations",
    "load_plan",
    "parse_tool_spec",
    "summary",
]
