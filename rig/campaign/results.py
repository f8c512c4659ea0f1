"""What a campaign run returns: every run's record and the campaign's result (in memory, frozen),
and the campaign package's JSON-shaped results with their keys and value types spelled out: what
`cutlab campaign run|status|dry-run --json` print and what the manifest (``campaign.json``)
records per run."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import NotRequired, TypedDict

from analysis.runs import file as rf
from analysis.validation import JsonObject

__all__ = [
    "CampaignResult",
    "CampaignStatus",
    "CampaignSummary",
    "DryRunSummary",
    "InputRecord",
    "ManifestEntry",
    "ManifestRow",
    "RunConditionsJson",
    "RunRecord",
    "RunRecordJson",
    "StatusRow",
]


class RunConditionsJson(TypedDict):
    """One test of the matrix (:meth:`RunConditions.as_dict`): feeds in both units."""

    index: int
    name: str
    group: str
    fz_mm: float
    feed_mm_min: float
    depth_mm: float
    width_mm: float
    spindle_rpm: float
    feed_mode: str
    rule: str | None


class RunRecordJson(TypedDict):
    """A run of a campaign run (:class:`~rig.campaign.runner.RunRecord`'s fields)."""

    index: int
    name: str
    group: str
    file: str
    status: str
    reason: str
    skipped: bool
    peak_force_n: float
    wall_s: float


class CampaignSummary(TypedDict):
    """`cutlab campaign run --json`: counts by status, wall time (s), every run, and the
    report's summary (its sections by title; None when no report was written)."""

    campaign: str
    folder: str
    ok: bool
    stopped: bool
    counts: dict[str, int]
    wall_s: float
    runs: list[RunRecordJson]
    report: Mapping[str, object] | None


class StatusRow(TypedDict):
    """A planned run's status in the campaign's folder (``missing``: no file)."""

    run: int
    name: str
    status: str
    reason: str


class CampaignStatus(TypedDict):
    """`cutlab campaign status --json`."""

    campaign: str
    folder: str
    runs: list[StatusRow]


class DryRunSummary(TypedDict):
    """`cutlab campaign dry-run --json` (:class:`~rig.campaign.dryrun.DryRun`'s fields, the
    expected machine time rounded to 0.1 s, and ``ok``)."""

    campaign: str
    rig: str
    tests: int
    programs_checked: int
    expected_machine_s: float
    hardware: list[str]
    problems: list[str]
    warnings: list[str]
    ok: bool


class InputRecord(TypedDict):
    """An input the runs depend on, in the manifest: its hash and where it was read; the
    config's also with its experiment fields (to name the ones that changed)."""

    sha256: str
    source: str
    fields: NotRequired[JsonObject]


class ManifestEntry(TypedDict, total=False):
    """A run's entry in the manifest: written at its start (index ... program_sha256) and at
    its end (status, reason, ended_utc, peak_force_n, wall_s)."""

    index: int
    group: str
    file: str
    status: str
    reason: str
    started_utc: str
    ended_utc: str
    earlier_attempt: str | None
    conditions: RunConditionsJson
    program_sha256: str
    peak_force_n: float
    wall_s: float


class ManifestRow(ManifestEntry, total=False):
    """A run's manifest entry with its name, as the report reads the manifest back."""

    name: str


@dataclass(frozen=True)
class RunRecord:
    index: int
    name: str
    group: str
    file: str
    status: str
    reason: str
    skipped: bool = False
    peak_force_n: float = float("nan")
    wall_s: float = 0.0

    def as_json(self) -> RunRecordJson:
        """Every field, in order."""
        return {"index": self.index, "name": self.name, "group": self.group, "file": self.file,
                "status": self.status, "reason": self.reason, "skipped": self.skipped,
                "peak_force_n": self.peak_force_n, "wall_s": self.wall_s}  # fmt: skip


@dataclass(frozen=True)
class CampaignResult:
    name: str
    folder: Path
    runs: tuple[RunRecord, ...]
    stopped: bool = False
    wall_s: float = 0.0
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.stopped and all(r.status == rf.STATUS_SUCCESS for r in self.runs)

    def summary(self, report: Mapping[str, object] | None = None) -> CampaignSummary:
        """Name, folder, ok, stopped, status counts, wall time (s), every run, and ``report``
        (the report's summary, None when none was written)."""
        return {
            "campaign": self.name,
            "folder": str(self.folder),
            "ok": self.ok,
            "stopped": self.stopped,
            "counts": self.counts,
            "wall_s": round(self.wall_s, 2),
            "runs": [r.as_json() for r in self.runs],
            "report": report,
        }
