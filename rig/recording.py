"""`cutlab daq record`'s job: what it asks (:class:`RecordRequest`, read by the API and the CLI
alike: the options are its fields, rig.cli.options.model_rows), checked before any device opens
(:func:`prepare_recording`), then recorded (:meth:`Recording.run`, :func:`rig.log.record_rig`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pydantic import BaseModel, ConfigDict, Field

if TYPE_CHECKING:
    from rig.daq import Daq
    from rig.log import RecordPlan, RecordResult

_SIM = "--sim: "


class RecordRequest(BaseModel):
    """Record the dynamometer into an HDF5 run file (see `cutlab data info`)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    sim: bool = Field(False, description="simulated DAQ instead of the NI device")
    seconds: float = Field(gt=0, le=1e6, json_schema_extra={"unit": "s"},
                           description="s of acquisition")  # fmt: skip
    rate_hz: float | None = Field(None, gt=0, le=1e7, description="Hz per channel (default: "
        "config)", json_schema_extra={"unit": "Hz", "flag": "--rate-hz"})  # fmt: skip
    channels: int | None = Field(None, ge=1, le=64, description="channel count (default: config)")
    output: str = Field(json_schema_extra={"flag": "-o --output"},
                        description="run file to write (.h5)")  # fmt: skip
    rig_path: str | None = Field(None, description="rig config TOML (default configs/rig.toml)")
    speed: float = Field(1.0, ge=0, le=1e6, json_schema_extra={"unit": "x real time"},
                         description=_SIM + "simulated s per wall s (1 = real time, 0 = as fast "
                         "as possible)")  # fmt: skip
    raw: bool = Field(False, description=_SIM + "store int16 ADC codes")
    sim_noise_v: float = Field(0.002, ge=0, le=100, json_schema_extra={"unit": "V"},
                               description=_SIM + "rms noise, V")  # fmt: skip
    sim_overflow_at: list[int] = Field([], json_schema_extra={"nargs": "*", "ge": 0},
        description=_SIM + "inject a buffer overflow at these sample indices")  # fmt: skip
    flush_s: float = Field(1.0, gt=0, le=60, json_schema_extra={"unit": "s", "flag": "--flush-s"},
                           description="s between flushes (<= 60)")  # fmt: skip
    conditions: list[str] = Field([], json_schema_extra={"nargs": "+", "metavar": "KEY=VALUE"},
        description="cutting conditions as KEY=VALUE pairs (spindle_rpm=600 tool=phi10-flat; "
        "numbers stored as numbers) or one JSON object ('{\"feed_mm_min\": 300}')")  # fmt: skip
    min_free_mb: float = Field(64.0, ge=0, le=1e6, json_schema_extra={"unit": "MB"}, description=(
        "MB to keep free on the file's disk: a recording that would need them does not start, "
        "one that reaches them stops cleanly (default 64)"))  # fmt: skip
    force: bool = Field(False, description="overwrite an existing file")


@dataclass(frozen=True)
class Recording:
    """A recording checked (its plan) with its DAQ made, not started."""

    request: RecordRequest
    plan: RecordPlan
    daq: Daq

    def run(self, progress: Callable[[float], None] | None = None) -> RecordResult:
        from rig.log import record_rig

        return record_rig(self.daq, self.plan, flush_interval_s=self.request.flush_s,
                          progress=progress)  # fmt: skip


def prepare_recording(req: RecordRequest, warn: Callable[[str], None]) -> Recording:
    """``req`` checked (rig config, rate, file, free disk: :func:`rig.log.plan_recording`, its
    notes to ``warn``) and its DAQ made: the simulated one with ``sim``, else the NI device."""
    from analysis.identify.conditions_arg import parse_conditions
    from rig.log import plan_recording

    plan = plan_recording(req.rig_path, req.output, req.seconds, rate_hz=req.rate_hz,
                          overwrite=req.force, conditions=parse_conditions(req.conditions),
                          min_free_mb=req.min_free_mb)  # fmt: skip
    for w in plan.notes:
        warn(w)
    daq: Daq
    if req.sim:
        from rig.sim import SimDaq

        daq = SimDaq.from_rig(
            plan.rig, rate_hz=plan.rate_hz, seconds=plan.seconds, channels=req.channels,
            speed=req.speed, raw=req.raw, noise_v=req.sim_noise_v,
            overflow_at=req.sim_overflow_at, where=plan.where, warn=warn,
        )  # fmt: skip
    else:
        from rig.daq.ni import NiDaq

        daq = NiDaq.from_rig(plan.rig, rate_hz=req.rate_hz, channels=req.channels,
                             where=plan.where)  # fmt: skip
    return Recording(req, plan, daq)
