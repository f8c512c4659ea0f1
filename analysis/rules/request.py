"""What `cutlab rules derive` asks (:class:`DeriveRequest`: one model read by the API and the CLI
alike, the options being its fields: rig.cli.options.model_rows) and the job that answers it
(:func:`derive_rule`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from analysis.rules.derive import DerivedRule

Feed = Annotated[float | None, Field(gt=0, le=200_000, json_schema_extra={"unit": "mm/min"})]


class DeriveRequest(BaseModel):
    """Base feed from a feed sweep, then the 20-bin rule (seed 001)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    # fmt: off
    runs: list[Path] = Field(json_schema_extra={"flag": "runs", "nargs": "+"},
                             description="HDF5 run files of the feed sweep")
    output: Path = Field(json_schema_extra={"flag": "-o --output"},
                         description="rule file to write (TOML)")
    name: str | None = Field(None, description="rule name (default: the output file's stem)")
    base_feed_mm_min: Feed = Field(None, description="mm/min; skip the detection and use this")
    min_feed_mm_min: Feed = Field(None, description="mm/min (default: 0.1 x base, seed 001)")
    max_feed_mm_min: Feed = Field(None, description="mm/min (default: 3.5 x base, seed 001)")
    machine: str | None = Field(None, description="machine config: min/max feeds are clamped to "
                                "its limits")
    reference_load_pct: float | None = Field(None, gt=0, json_schema_extra={"unit": "%"},
        description="%, load of the base-feed cut (default: a slot at the runs' depth)")
    exponent: float = Field(1.0, gt=0, le=5, description="p in feed = base (L_ref/L)^p (1: "
                            "constant removal rate)")
    bins: int = Field(20, ge=3, le=200)
    slope_ratio: float = Field(1.6, gt=0)
    vibration_ratio: float = Field(2.0, gt=0)
    criterion: Literal["any", "both", "slope", "vibration"] = "any"
    png: Path | None = Field(None, json_schema_extra={"kind": "picture"},
                             description="also plot the rule and the sweep here")
    # fmt: on


def derive_rule(req: DeriveRequest) -> DerivedRule:
    """The rule of ``req``'s sweep (:func:`analysis.rules.derive_from_sweep`), written to its
    output (and plotted to its png)."""
    from analysis.rules import derive_from_sweep, plot_rule, save_rule

    d = derive_from_sweep(
        req.runs, req.name or req.output.stem, base_feed_mm_min=req.base_feed_mm_min,
        min_feed_mm_min=req.min_feed_mm_min, max_feed_mm_min=req.max_feed_mm_min,
        machine=req.machine, reference_load_pct=req.reference_load_pct, exponent=req.exponent,
        n_bins=req.bins, slope_ratio=req.slope_ratio, vibration_ratio=req.vibration_ratio,
        criterion=req.criterion,
    )  # fmt: skip
    save_rule(d.rule, req.output)
    if req.png:
        plot_rule(d.rule, req.png)
    return d
