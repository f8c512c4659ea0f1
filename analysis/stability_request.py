"""What `cutlab analyze stability` asks (:class:`StabilityRequest`: one model read by the API and
the CLI alike, the options being its fields: rig.cli.options.model_rows) and the job that
answers it (:func:`stability_job`, :func:`analysis.stability.output.lobes_file`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from analysis.validation import JsonObject


class StabilityRequest(BaseModel):
    """`cutlab analyze stability CONFIG -o lobes.csv [--method sd|zoa] [--steps M] [--json]
    [--plot lobes.png]`: milling stability lobes, the chatter-free axial depth per spindle speed.

    CONFIG (TOML) holds the tool's teeth, the cut (up/down milling, radial immersion), the cutting
    coefficients (or coefficients_file: `cutlab analyze forces --json` output), the tool's modes per
    direction (or modes_file: `cutlab analyze modal --save`), and the spindle speeds; see
    configs/stability/. The CSV has one row per speed: spindle_rpm, depth_limit_mm, chatter_hz, kind
    (hopf, flip or stable), steps and convergence_pct; numbers are written round-trip exact, and a
    speed stable up to the deepest depth searched (--max-depth, default 30 x the lowest ZOA limit)
    reads depth_limit_mm inf, chatter_hz nan, kind stable. Methods: sd, semi-discretization
    (default: it finds the period-doubling lobes of interrupted cuts), and zoa, the zero-order
    approximation, which warns where it misses them. SD starts at the config's steps per tooth
    period (30) and doubles them at each speed until the limit changes by at most 1 % (up to
    240; convergence_pct is the last doubling's change, the summary line gives the largest);
    --steps M fixes the count instead (no check).
    """  # noqa: E501 (the help's lines as they print)

    model_config = ConfigDict(extra="forbid", frozen=True)
    # fmt: off
    config: str = Field(json_schema_extra={"flag": "config"},
                        description="stability case (TOML), e.g. configs/stability/*.toml")
    output: Path = Field(json_schema_extra={"flag": "-o --output"},
                         description="CSV of the lobes to write")
    method: Literal["sd", "zoa"] = Field("sd", description="sd: semi-discretization (default); "
                                         "zoa: zero-order approx.")
    steps: int | None = Field(None, ge=4, le=400, json_schema_extra={"metavar": "M"}, description=(
        "fixed steps per tooth period of sd (default: start at the config's, 30, and double per "
        "speed until within 1 %)"))
    max_depth_mm: float | None = Field(None, gt=0, le=1000.0, json_schema_extra={
        "unit": "mm", "metavar": "MM"}, description="deepest cut searched, mm (default: the "
        "config's, else 30 x the lowest ZOA limit)")
    plot: Path | None = Field(None, json_schema_extra={"kind": "picture", "metavar": "PNG"},
                              description="write the lobes plot")
    # fmt: on


def stability_job(
    req: StabilityRequest, note: Callable[[str], None] = lambda message: None
) -> tuple[JsonObject, str]:
    """The lobes ``req`` asks, written (:func:`analysis.stability.output.lobes_file`)."""
    from analysis.stability.output import lobes_file

    return lobes_file(req.config, req.output, req.method, req.steps, req.max_depth_mm, req.plot,
                      note=note)  # fmt: skip
