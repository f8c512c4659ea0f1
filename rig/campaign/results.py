"""What a campaign run returns: every run's record and the campaign's result (in memory, frozen),
and their JSON (:meth:`CampaignResult.summary`, `cutlab campaign run --json`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis.runs import file as rf

__all__ = ["CampaignResult", "RunRecord"]


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

    def summary(self, report: dict[str, Any] | None = None) -> dict[str, Any]:
        """Name, folder, ok, stopped, status counts, wall time (s), every run, and ``report``
        (the report's summary, None when none was written)."""
        return {
            "campaign": self.name,
            "folder": str(self.folder),
            "ok": self.ok,
            "stopped": self.stopped,
            "counts": self.counts,
            "wall_s": round(self.wall_s, 2),
            "runs": [r.__dict__ for r in self.runs],
            "report": report,
        }
