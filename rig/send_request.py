"""What `cutlab dnc send` asks (:class:`SendRequest`: one model read by the API and the CLI alike,
the options being its fields: rig.cli.options.model_rows) and the job's two steps: the send
checked and prepared before the port opens (:func:`prepare`), the force loop of ``--adaptive``
on the rig's DAQ (:func:`adaptive_loop`); the send: :func:`rig.dnc.session.send_under_control`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Literal

from pydantic import BaseModel, ConfigDict, Field

if TYPE_CHECKING:
    from rig.adaptive.send import SendLoop
    from rig.dnc import SendJob

_ADAPTIVE = "--adaptive: "


class SendRequest(BaseModel):
    """Stream an NC program to a controller over serial. Operator control, {keys}: each action is
    one status line on stderr and is recorded (--json: operator_actions). GRBL: hold is '!',
    resume '~', abort '!' then Hold:0 then a soft reset; Fanuc drip feed: the line takes no feed
    hold, press FEED HOLD / CYCLE START on the control, abort stops feeding. A restart
    (--start-block) approaches at the program's clearance (its highest rapid before the block, or
    the R plane; --safe-z overrides) and plunges at the program's plunge feed (--plunge-feed if
    it has none)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    # fmt: off
    file: str = Field(description="NC program", json_schema_extra={"flag": "file"})
    # the link (options shared by the dnc commands: rig.cli.options.serial_rows)
    port: str | None = None
    protocol: str
    machine: str | None = None
    baud: int | None = Field(None, ge=1, le=4_000_000)
    timeout: float | None = Field(None, gt=0, le=3600)
    start_block: int = Field(0, ge=0, description="restart at this block (0-based)")
    safe_z_mm: float | None = Field(None, json_schema_extra={"unit": "mm"}, description=(
        "restart: clearance Z to approach from, mm (default: the program's)"))
    plunge_feed_mm_min: float | None = Field(None, gt=0, le=200_000, json_schema_extra={
        "unit": "mm/min"}, description="restart: feed down to the restart point, mm/min "
        "(default: the program's last plunge before the block)")
    dry_run: bool = Field(False, description="print the restart preamble and the first blocks "
                          "that would be sent; send nothing")
    mode: str = Field("char-counting", description="GRBL: char-counting | send-response")
    unlock: bool = Field(False, description="GRBL: send $X if it is in Alarm")
    no_strip: bool = Field(False, description="GRBL: send lines as written (default: no "
                           "comments, spaces, N and O words)")
    no_wait_dc1: bool = Field(False, description="Fanuc: send without waiting for DC1")
    adaptive: Literal["feed", "spindle", "both"] | None = Field(None, description=(
        "GRBL: hold a force target with real-time overrides (refused for controllers without a "
        "real-time override, the Fanuc drip feed)"))
    target_force_n: float | None = Field(None, gt=0, le=1e6, json_schema_extra={"unit": "N"},
        description=_ADAPTIVE + "per-revolution mean |Fxy| to hold, N")
    max_force_n: float | None = Field(None, gt=0, le=1e6, json_schema_extra={"unit": "N"},
        description=_ADAPTIVE + "resultant force that holds the feed, N")
    spindle_rpm: float | None = Field(None, gt=0, le=1e6, json_schema_extra={
        "unit": "rpm", "flag": "--spindle-rpm"},
        description=_ADAPTIVE + "the program's spindle speed, rpm")
    stall_revs: float = Field(3.0, gt=0, le=1e4, json_schema_extra={"unit": "revolutions"},
        description=_ADAPTIVE + "revolutions without a DAQ block, beyond one block, before the "
        "loop counts the force signal lost and holds (default 3)")
    rig_path: str | None = Field(None, description=_ADAPTIVE + "the DAQ's rig TOML (default "
                                 "configs/rig.toml)")
    record_csv: str | None = Field(None, json_schema_extra={"flag": "--record"},
                                   description="write the block record to this CSV file")
    no_progress: bool = Field(False, description="no progress bar on stderr")
    # fmt: on


def prepare(req: SendRequest) -> SendJob:
    """The send checked before the port opens (:func:`rig.dnc.prepare_send`; ``--adaptive``
    refused for a controller without a real-time override); a dry run records nothing."""
    from rig.dnc import prepare_send

    if req.adaptive:
        from rig.adaptive.send_options import check_send_adaptive

        check_send_adaptive(req.adaptive, req.protocol, req.machine, req.target_force_n,
                            req.max_force_n, req.spindle_rpm)  # fmt: skip
    return prepare_send(
        req.file, req.protocol, machine=req.machine, port=req.port, baud=req.baud,
        timeout_s=req.timeout, start_block=req.start_block, safe_z_mm=req.safe_z_mm,
        plunge_feed_mm_min=req.plunge_feed_mm_min,
        record_csv=None if req.dry_run else req.record_csv, progress=not req.no_progress,
        grbl_mode=req.mode, grbl_unlock=req.unlock, grbl_strip=not req.no_strip,
        fanuc_wait_dc1=not req.no_wait_dc1, guard=not req.dry_run,
    )  # fmt: skip


def adaptive_loop(job: SendJob, req: SendRequest, say: Callable[[str], None]) -> SendLoop:
    """The rig's DAQ opened and zeroed, the loop on the send's streamer (rig.adaptive.send)."""
    from rig.adaptive import AdaptiveSettings
    from rig.adaptive.send import SendLoop

    # prepare() refused an --adaptive send without its target, limit and speed
    assert req.adaptive and req.target_force_n and req.max_force_n and req.spindle_rpm
    settings = AdaptiveSettings(mode=req.adaptive, target_force_n=req.target_force_n,
                                max_force_n=req.max_force_n, stall_revs=req.stall_revs)  # fmt: skip
    return SendLoop(job, settings, req.spindle_rpm, rig=req.rig_path, say=say)
