"""What the `cutlab plan` commands ask (:class:`FeedRequest`, :class:`SimulateRequest`: one model
each, read by the API and the CLI alike, the options being their fields:
rig.cli.options.model_rows) and the jobs that answer them (:func:`feed_job`,
:func:`simulate_request`; the work: :mod:`planning.feed.job`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

from pydantic import BaseModel, ConfigDict, Field

from planning.nc import DIALECTS

if TYPE_CHECKING:
    from analysis.validation import JsonObject
    from planning.feed import FeedPostResult
    from planning.feed.job import Progress
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
    dialect: str | None = Field(
        None,
        json_schema_extra={"choices": DIALECTS},
        description="controller to write for (default: the machine's)",
    )
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
    lobes: Path | None = Field(None, description="stability lobes CSV (spindle_rpm,"
                               "depth_limit_mm; `cutlab analyze stability -o`), default: the "
                               "tool's modes if any")  # fmt: skip


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
