"""What a run file holds, as one JSON-able dict (`cutlab data info`)."""

from __future__ import annotations

from pathlib import Path
from typing import TypedDict

from analysis.runs.file import LOSS_KINDS, load_run

__all__ = ["DataGap", "RunSummary", "run_summary"]


class DataGap(TypedDict):
    """A data gap of a run: its event kind, first sample, samples lost, time (s), message."""

    kind: str
    sample: int
    lost: int
    time_s: float
    message: str


class RunSummary(TypedDict):
    """`cutlab data info --json` on a run file (:func:`run_summary`)."""

    file: str
    status: str
    reason: str
    complete: bool
    channels: list[str]
    physical_channels: list[str]
    sample_format: str
    rate_hz: float
    samples_stored: int
    samples_acquired: int
    samples_lost: int
    duration_s: float
    t0_s: float
    events: dict[str, int]
    gaps: list[DataGap]
    nc_blocks: int
    program: dict[str, object]  # as recorded (name, sha256, lines)
    conditions: dict[str, object]  # as recorded: free-form keys
    calibration_id: str | None
    software_version: str


def run_summary(path: str | Path) -> RunSummary:
    """Status, channels, rate, sample counts, duration, event counts, data gaps (with their time
    in s), NC blocks, program, conditions, calibration and software version of a run file; the
    samples are not read."""
    run = load_run(path, samples=False)
    ev = run.events
    gaps = ev[ev["kind"].isin(LOSS_KINDS) & (ev["lost"] > 0)]
    counts = ev["kind"].value_counts().to_dict()
    return {
        "file": str(run.path),
        "status": run.status,
        "reason": run.reason,
        "complete": run.complete,
        "channels": list(run.channel_names),
        "physical_channels": list(run.physical_channels),
        "sample_format": run.sample_format,
        "rate_hz": run.rate_hz,
        "samples_stored": run.samples_stored,
        "samples_acquired": run.samples_acquired,
        "samples_lost": run.samples_lost,
        "duration_s": run.duration_s,
        "t0_s": run.t0_s,
        "events": {str(k): int(v) for k, v in counts.items()},
        "gaps": [
            {
                "kind": kind,
                "sample": int(sample),
                "lost": int(lost),
                "time_s": float(sample / run.rate_hz),
                "message": message,
            }
            for kind, sample, lost, message in zip(
                gaps["kind"], gaps["sample"].to_numpy(), gaps["lost"].to_numpy(), gaps["message"]
            )
        ],
        "nc_blocks": len(run.blocks),
        "program": run.program_info,
        "conditions": run.conditions,
        "calibration_id": (
            run.calibration.attrs.get("calibration_id") if run.calibration else None
        ),
        "software_version": run.software_version,
    }
