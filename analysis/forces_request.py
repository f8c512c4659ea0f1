"""What `cutlab analyze forces` asks: the runs (files, or a run catalogue's) and how to fit them,
one model read by the API and the CLI alike (the options are its fields:
rig.cli.options.model_rows); :func:`fit_forces` does the job."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Literal

from pydantic import BaseModel, ConfigDict, Field

from analysis.runs import IDENTIFY_TOLERANCE

if TYPE_CHECKING:
    from analysis.identify import ImportOptions
    from analysis.identify.reading import Progress
    from analysis.identify.results import ForcesResult


class ForcesRequest(BaseModel):
    """Fit cutting-force coefficients to recorded runs."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    runs: list[str] = Field(
        [], json_schema_extra={"flag": "runs", "nargs": "*"},
        description="run files (.h5) or DynoWare/CSV exports")  # fmt: skip
    catalog: str | None = Field(None, json_schema_extra={"metavar": "DIR|INDEX"}, description=(
        "the runs of this run catalogue (`cutlab catalog index`) instead of files, reduced as "
        "dask tasks and cached by file hash"))  # fmt: skip
    where: str | None = Field(None, json_schema_extra={"metavar": "EXPR"}, description=(
        "with --catalog: the runs to fit, as `cutlab catalog query` takes them (default every "
        "run)"))  # fmt: skip
    scheduler: str | None = Field(None, json_schema_extra={"metavar": "ADDRESS"}, description=(
        "with --catalog: a dask.distributed scheduler (tcp://HOST:PORT), or threads / processes "
        "/ sync (default: the dask config's scheduler-address, else threads)"))  # fmt: skip
    model: Literal["facemill", "endmill"] | None = Field(
        None, description="force model (default: from the tool's kind)"
    )
    tool: str | None = Field(None, description="tool name in configs/tools.toml")
    rig_path: str | None = Field(None, description="rig config (default configs/rig.toml)")
    conditions: list[str] | None = Field(None, json_schema_extra={
        "nargs": "*", "metavar": "KEY=VALUE|TABLE"}, description=(
        "conditions applied over each run's own (file header or run file), key by key "
        "(spindle_rpm=600 depth_mm=2 mode=slot ...), or a table (.csv/.toml, one row per file: "
        "file,spindle_rpm,feed_mm_min|fz_mm,ap_mm,ae_mm[,teeth,tool,mode])"))  # fmt: skip
    rate_hz: float | None = Field(None, gt=0, le=10_000_000, json_schema_extra={"unit": "Hz"},
                                  description="Hz, for exports without a rate")  # fmt: skip
    steady_tolerance: float = Field(
        IDENTIFY_TOLERANCE, gt=0, le=1, json_schema_extra={
            "unit": "fraction", "metavar": "FRACTION"}, description=(
        "revolutions whose mean force is within this fraction of the steady level (median) count "
        f"as steady cutting; fraction, default {IDENTIFY_TOLERANCE} (0.02 = 2 %)"))  # fmt: skip
    validate_runs: list[str] | None = Field(None, json_schema_extra={
        "flag": "--validate", "nargs": "*", "metavar": "RUN"},
        description="runs to predict with the fitted coefficients")  # fmt: skip
    plot_dir: str | None = Field(None, json_schema_extra={"flag": "--plot", "metavar": "DIR"},
                                 description="write validation PNGs here")  # fmt: skip
    keep: bool = Field(False, description="fit runs beyond the tool's limits too (max_chip_mm): "
                       "by default they are named and left out")  # fmt: skip


def fit_forces(
    req: ForcesRequest, options: ImportOptions | None = None, progress: Progress | None = None,
    *, catalog_progress: bool = False, note: Callable[[str], None] = lambda line: None,
) -> ForcesResult:  # fmt: skip
    """The fit ``req`` asks: :func:`analysis.identify.fit_files` of its run files (``progress``
    per file), or :func:`analysis.catalog.fit_catalog` of its catalogue's runs (a progress
    display if ``catalog_progress``; ``note`` gets the catalogue's line); ``options``: how
    exports are read (its conditions table: ``req.conditions``)."""
    from dataclasses import replace

    from analysis.catalog.compute import FitOptions
    from analysis.identify import ImportOptions, fit_files
    from analysis.identify.conditions_arg import conditions_arg, runs_or_catalog

    pairs, table = conditions_arg(req.conditions)
    kw = FitOptions(model=req.model, tool=req.tool, overrides=pairs, rig_path=req.rig_path,
              rate_hz=req.rate_hz, tolerance=req.steady_tolerance, validate=req.validate_runs,
              plot_dir=req.plot_dir, options=replace(options or ImportOptions(), table=table),
              keep=req.keep)  # fmt: skip
    if runs_or_catalog(req.runs, req.catalog, where=req.where, scheduler=req.scheduler):
        from analysis.catalog import fit_catalog, fit_line

        out = fit_catalog(req.catalog, req.where, req.scheduler, catalog_progress, **kw)
        note(fit_line(out))
        return out
    return fit_files(req.runs, progress=progress, **kw)
