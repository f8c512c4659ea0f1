"""What the `cutlab plan` commands ask (:class:`FeedRequest`, :class:`SimulateRequest`: one model
each, read by the API and the CLI alike, the options being their fields:
rig.cli.options.model_rows) and the jobs that answer them (:func:`feed_job`,
:func:`simulate_request`; the work: :mod:`planning.feed.job`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from planning.nc import DIALECTS

if TYPE_CHECKING:
    from analysis.validation import JsonObject
    from planning.feed import FeedPostResult
    from planning.feed.job import Progress
    from planning.limits.check import CheckResult
    from planning.limits.text import RoughAnswer
    from planning.stock.plans import OperationResult

_CONFIG = ConfigDict(extra="forbid", frozen=True)
# fmt: off
_TOOL = ("end mill of the tool catalogue, or T1=NAME,T2=NAME for a program that changes tools "
         "(needed for a program; plans name theirs)")


# the machine, the tool, the stock: the fields feed and simulate share
Machine = Annotated[str, Field(description="machine config name or path")]
Tool = Annotated[str | None, Field(description=_TOOL)]
Stock = Annotated[str | None, Field(description="box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP | mesh (.stl) "
                  "| stock TOML (default: derived from the program's feed moves, printed)")]
Spacing = Annotated[float | None, Field(gt=0, le=100, json_schema_extra={"unit": "mm"},
                    description="Z-map grid spacing, mm (default 0.25)")]
NoHolderCheck = Annotated[bool, Field(description="skip holder/stock checks")]
Lobes = Annotated[Path | None, Field(description="stability lobes CSV (spindle_rpm,depth_limit_mm; "
                  "`cutlab analyze stability -o`), default: the tool's modes if any")]
Dialect = Annotated[str | None, Field(json_schema_extra={"choices": DIALECTS})]
# fmt: on


class FeedRequest(BaseModel):
    """Exit status: 0 when the program is written and its verdict (printed, and 'verdict' in
    --json) is 'within' or 'unchecked' (without --material: the limits not checked are listed); 3
    when it is written but a block breaks a limit ('violations'); 2 bad input, or a program that
    removes nothing from its stock."""

    model_config = _CONFIG
    program: Path = Field(json_schema_extra={"flag": "program"},
                          description="NC program (G21 or G20)")  # fmt: skip
    rules: str | None = Field(None, description=(
        "rule file (TOML) or rule-base name / id; T1=RULE,T2=RULE for a program that changes "
        "tools (a tool left out, e.g. a drill, keeps its feeds); default: each tool's rule from "
        "the rule base by tool and --material (a tool it lacks keeps its feeds)"))  # fmt: skip
    db: Path | None = Field(None, description="rule base for a name / id (default from lab.toml)")
    machine: Machine = "ace-h63"
    tool: Tool = None
    stock: Stock = None
    spacing_mm: Spacing = None
    no_holder_check: NoHolderCheck = False
    output: Path = Field(json_schema_extra={"flag": "-o --output"},
                         description="adjusted program to write")  # fmt: skip
    dialect: Dialect = Field(None, description="controller to write for (default: the machine's)")
    report: Path | None = Field(None, description="report folder (default: OUT's folder)")
    min_piece_mm: float = Field(5.0, gt=0, le=1000, json_schema_extra={"unit": "mm"},
                                description="shortest split block, mm")  # fmt: skip
    no_split: bool = Field(False, description="one feed per block, no splits")
    force_limit_n: float | None = Field(
        None,
        gt=0,
        le=1e6,
        json_schema_extra={"unit": "N"},
        description="largest predicted peak force, N",
    )
    material: str | None = Field(None, description="material (configs/materials.toml): "
                                 "predicted peak force per block, and the coefficients for "
                                 "--force-limit")  # fmt: skip
    spindle_rpm: float | None = Field(None, gt=0, le=100_000, json_schema_extra={"unit": "rpm"},
                                      description="rpm for the force model if the program has "
                                      "no S")  # fmt: skip
    limit: bool = Field(False, description="cap every feed by the machine's and tool's limits "
                        "(planning.limits; needs --material)")  # fmt: skip
    lobes: Lobes = None


class SimulateRequest(BaseModel):
    """Z-map virtual machining of a program or a plan."""

    model_config = _CONFIG
    program: Path = Field(json_schema_extra={"flag": "program"},
                          description="NC program, or an operation plan (.toml)")  # fmt: skip
    machine: Machine = "ace-h63"
    tool: Tool = None
    stock: Stock = None
    spacing_mm: Spacing = None
    no_holder_check: NoHolderCheck = False
    png: Path | None = Field(None, json_schema_extra={"kind": "picture"},
                             description="final stock PNG")  # fmt: skip


class RoughRequest(BaseModel):
    """`cutlab plan rough CONFIG [--method M] [--dialect D] [--machine M] -o OUT.nc [--json]`: Z-level
    roughing (seed 000).

    Plans the part by every method (bisection, equal, lee, optimal) under the same cusp and depth
    limits, writes the chosen method's program to OUT.nc (through planning.nc's writer) for the
    controller's dialect (--dialect fanuc|linuxcnc|grbl; default the --machine's, else fanuc),
    prints the per-level table of the chosen method (as seed 000 Table 1) and the totals of all
    methods side by side, then cuts the program on a Z-map and reports the material left above the
    offset surface and any gouge. Pictures (unless --no-png), next to OUT.nc: OUT.levels.png
    (levels of all methods in a side view), OUT.paths.png (passes of the chosen method),
    OUT.roughed.png (the roughed Z-map and the material left).

    Exit status: 0 when the program is written, the Z-map check passes and the limits' verdict is
    'within' or 'unchecked' (the limits not checked are listed); 3 when it is written but the Z-map
    check finds a gouge or material left, or a block breaks a limit ('violations'; --limit splits
    levels and lowers feeds to cure them); 2 bad input.
    """  # noqa: E501 (the help's lines as they print)

    model_config = _CONFIG
    config: str = Field(
        json_schema_extra={"flag": "config"},
        description="part file, e.g. configs/parts/seed000-bump.toml (or its name)",
    )
    method: Literal["bisection", "equal", "lee", "optimal"] = "bisection"
    output: Path = Field(
        json_schema_extra={"flag": "-o --output"}, description="NC program to write"
    )
    dialect: Dialect = Field(None, description="controller to write for (default: the machine's)")
    machine: str | None = Field(
        None,
        description="machine config name or path: its dialect and "
        "tool changer (default: none, fanuc)",
    )
    cusp_model: Literal["paper", "exact"] | None = Field(
        None,
        description="override rough.cusp_model (paper: (h1-h2)cos(beta); exact: measured distance)",
    )
    no_png: bool = Field(
        False, json_schema_extra={"flag": "--no-png"}, description="skip the pictures"
    )
    no_check: bool = Field(False, description="skip the Z-map check")
    check_spacing_mm: float = Field(
        0.5,
        gt=0,
        le=100,
        json_schema_extra={"unit": "mm"},
        description="Z-map grid spacing of the check, mm",
    )
    limit: bool = Field(
        False,
        description="split levels or lower feeds until every block is "
        "within the machine's and tool's limits",
    )
    material: str | None = Field(
        None, description="workpiece material (default: the part's cutting.material)"
    )
    lobes: Lobes = None


class CheckRequest(BaseModel):
    """Exit status: 0 every block within every limit (verdict 'within'); 3 a block breaks a limit
    ('violations'); 4 none breaks one but a limit could not be checked (no tool modes or lobes, no
    spindle curve, a drill, nothing cut: 'unchecked', listed); 2 bad input."""

    model_config = _CONFIG
    program: Path = Field(json_schema_extra={"flag": "program"}, description="NC program")
    tool: str | None = Field(
        None,
        description="end mill in configs/tools.toml, or T1=NAME,T2=NAME "
        "for a program that changes tools (each section checked with its own)",
    )
    material: str | None = Field(
        None, description="material (configs/materials.toml): force coefficients"
    )
    machine: Machine = "ace-h63"
    stock: Stock = None
    spacing_mm: Spacing = None
    lobes: Lobes = None
    spindle_rpm: float | None = Field(
        None,
        gt=0,
        le=100_000,
        json_schema_extra={"unit": "rpm"},
        description="rpm where the program has no S",
    )
    plot: Path | None = Field(None, description="PNG of each quantity per block against its limit")


class OrientRequest(BaseModel):
    """`cutlab plan orient CONFIG -o OUT [--json]`: collision-free 5-axis tool orientation (seed 002).

    Writes to the folder OUT: ``cl.csv`` (CL data: tip, cutter centre, axis, angles per CC point),
    ``program.nc`` (G-code for the config's 5-axis machine by inverse kinematics),
    ``energy_map.png`` (the eq 7 energy over (alpha, beta) at one CC point, as seed 002 Fig. 8),
    ``orientation.png`` (the surfaces with the chosen tool axes, as Figs. 9-11) and
    ``summary.json``. Every output orientation is re-checked on a fresh dense mesh before anything
    is written; a CC point without a collision-free orientation stops the command with its reason.
    """  # noqa: E501 (the help's lines as they print)

    model_config = _CONFIG
    config: Path = Field(
        json_schema_extra={"flag": "config"},
        description="orientation config, e.g. configs/orient/impeller.toml",
    )
    out: Path = Field(json_schema_extra={"flag": "-o --out"}, description="output folder")
    map_point: int | None = Field(
        None,
        ge=0,
        description="CC point for the energy map (default: "
        "the one that needed most energy evaluations)",
    )
    no_plot: bool = Field(False, description="skip both PNGs (energy map and orientation)")
    dialect: Dialect = Field(
        None,
        description="controller to write for (default: the machine's); "
        "grbl has no rotary axes and is refused",
    )


def feed_job(
    req: FeedRequest, progress: Progress | None = None, warn: Callable[[str], None] | None = None
) -> tuple[FeedPostResult, JsonObject]:
    """:func:`planning.feed.feed_program` of a request, under the limits it asks
    (:func:`planning.limits.feed_options.feed_limits`)."""
    from planning.feed import feed_program
    from planning.limits.feed_options import feed_limits

    lim = feed_limits(req.rules, req.tool, req.material, req.machine, req.lobes,
                      req.force_limit_n, req.limit, req.spindle_rpm)  # fmt: skip
    return feed_program(
        req.program, req.rules, req.output, db=req.db, machine=req.machine, tool_name=req.tool,
        stock_spec=req.stock, spacing_mm=req.spacing_mm, report_dir=req.report,
        progress=progress, warn=warn, min_piece_mm=req.min_piece_mm, split=not req.no_split,
        check_holder=not req.no_holder_check, force_limit_n=req.force_limit_n,
        material=None if lim.lookup_only else req.material, spindle_rpm=req.spindle_rpm,
        dialect=req.dialect, limit_step=lim.step, feed_cap=lim.cap, rules_material=req.material,
    )  # fmt: skip


def simulate_request(
    req: SimulateRequest, progress: Progress | None = None
) -> tuple[list[OperationResult], JsonObject]:
    """:func:`planning.feed.simulate_job` of a request."""
    from planning.feed import simulate_job

    return simulate_job(
        req.program, machine=req.machine, tool_name=req.tool, stock_spec=req.stock,
        spacing_mm=req.spacing_mm, check_holder=not req.no_holder_check, png=req.png,
        progress=progress,
    )  # fmt: skip


def rough_job(
    req: RoughRequest, progress: Callable[[str], None] | None = None,
    status: Callable[[str], None] | None = None,
) -> RoughAnswer:  # fmt: skip
    """:func:`planning.rough.run_rough` of a request, under the limits it asks, with the limits'
    verdict (:func:`planning.limits.text.rough_answer`)."""
    from planning.limits import rough_limiter
    from planning.limits.text import rough_answer
    from planning.rough import run_rough

    limits = rough_limiter(fix=req.limit, machine=req.machine, material=req.material,
                           lobes=req.lobes)  # fmt: skip
    return rough_answer(run_rough(
        req.config, req.output, req.method, req.cusp_model, check=not req.no_check,
        check_spacing_mm=req.check_spacing_mm, png=not req.no_png, progress=progress,
        status=status, dialect=req.dialect, machine=req.machine, limits=limits,
    ))  # fmt: skip


def check_request(
    req: CheckRequest, progress: Progress | None = None
) -> tuple[list[CheckResult], JsonObject]:
    """:func:`planning.limits.check_job` of a request."""
    from planning.limits import check_job

    return check_job(
        req.program, tool_name=req.tool, material=req.material, machine=req.machine,
        stock_spec=req.stock, spacing_mm=req.spacing_mm, lobes=req.lobes,
        spindle_rpm=req.spindle_rpm, plot=req.plot, progress=progress,
    )  # fmt: skip


def orient_job(
    req: OrientRequest,
    progress: Callable[[int, int], None] | None = None,
    status: Callable[[str], None] | None = None,
) -> JsonObject:
    """:func:`planning.orient.run_orient` of a request."""
    from planning.orient import run_orient

    return run_orient(req.config, req.out, req.map_point, not req.no_plot, progress, status,
                      req.dialect)  # fmt: skip
