"""What `cutlab analyze modal` asks of :func:`analysis.modal.modal_file`: one model, read by the
API and the CLI alike (the options are its fields: rig.cli.options.model_rows)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from analysis.validation import JsonObject


class ModalRequest(BaseModel):
    """Modes from an impulse-hammer record (dynamometer, tool)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    file: str = Field(
        description="CSV/DynoWare export or run file with a hammer channel",
        json_schema_extra={"flag": "file"},
    )
    hammer: str = Field("hammer", description="name of the hammer force channel")
    columns: str | None = Field(
        None,
        json_schema_extra={"metavar": "NAMES"},
        description=(
            "the columns of a file without a header row, in order, units in brackets: e.g. "
            "time[s],hammer[N],accel[m/s^2] (the rate from the time column, or --rate)"
        ),
    )
    rate_hz: float | None = Field(
        None,
        gt=0,
        le=10_000_000,
        json_schema_extra={"unit": "Hz"},
        description="Hz, for files without a rate",
    )
    record_s: float = Field(
        0.08,
        gt=0,
        le=3600,
        json_schema_extra={"unit": "s", "flag": "--record-s"},
        description="s of record per hit (at least 0.01 s and 128 samples)",
    )
    window_end: float = Field(
        0.05, gt=0, le=1, description="exponential window value at the record's end"
    )
    response: Literal["force", "disp", "accel"] | None = Field(
        None,
        description=(
            "what response columns without a unit in their name measure: force (N, a dynamometer; "
            "the default), disp (m) or accel (m/s^2); a unit in the column name (ax [g], dx [mm]) "
            "decides by itself"
        ),
    )
    spindle_rpm: list[float] | None = Field(
        None,
        json_schema_extra={"flag": "--rpm", "nargs": "*", "unit": "rpm", "gt": 0, "le": 1_000_000},
        description="planned spindle speeds to check against the modes",
    )
    teeth: int = Field(1, ge=1, le=1000, description="teeth of the planned cutter")
    rig_path: str | None = Field(
        None,
        json_schema_extra={"flag": "--rig"},
        description="rig config (default configs/rig.toml)",
    )
    plot_png: Path | None = Field(
        None,
        json_schema_extra={"kind": "picture", "metavar": "PNG"},
        description="write the FRF and coherence",
    )
    stabilisation_png: Path | None = Field(
        None,
        json_schema_extra={"kind": "picture", "metavar": "PNG"},
        description="write the stabilisation diagram (LSCF poles by model order)",
    )
    save: str | None = Field(
        None,
        json_schema_extra={"metavar": "MODES.toml"},
        description=(
            "write the modes per direction (frequency, damping, modal stiffness and mass) for a "
            "stability calculation; .toml or .json"
        ),
    )


def modal_job(req: ModalRequest) -> JsonObject:
    """:func:`analysis.modal.modal_file` of a request (its modes, and the files it asks)."""
    from analysis.modal import modal_file

    return modal_file(req.file, **req.model_dump(exclude={"file"}))
