"""What `cutlab campaign run` and `status` need beyond their arguments: the dry run as text,
``--adaptive`` applied to the campaign, the heartbeat's note of the runs ended, the runs' table
and the note on a campaign folder that does not exist."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from analysis.errors import ConfigError
from analysis.output import table_lines
from rig.campaign.config import Campaign
from rig.campaign.dryrun import DryRun

if TYPE_CHECKING:
    from rig.campaign.results import CampaignStatus
    from rig.campaign.runner import CampaignResult

__all__ = ["dry_run_lines", "missing_folder_note", "run_lines", "run_rows", "runs_done",
           "status_lines", "with_adaptive"]  # fmt: skip


def dry_run_lines(d: DryRun) -> list[str]:
    """The dry run's counts, the expected machine time, and each check (ok, PROBLEM, warning)."""
    out = [
        f"campaign {d.campaign}: {d.tests} tests, {d.programs_checked} programs checked, "
        f"rig = {d.rig}",
        f"expected machine time: {d.expected_machine_s / 60:.1f} min",
    ]
    for prefix, lines in (("ok", d.hardware), ("PROBLEM", d.problems), ("warning", d.warnings)):
        out += [f"  {prefix}: {line}" for line in lines]
    return out


def with_adaptive(campaign: Campaign, mode: str) -> Campaign:
    """The campaign with ``[adaptive] mode`` set by ``--adaptive``; refused (one line) without
    an ``[adaptive]`` table (its target and limits are the config's) or without GRBL."""
    from rig.adaptive.session import check_adaptive

    a = campaign.spec.adaptive
    if a is None:
        raise ConfigError(
            f"{campaign.path}: --adaptive {mode}: the campaign has no [adaptive] table; add one "
            "with target_force_n (N) and max_force_n (N) (docs/configuration.md)"
        )
    spec = campaign.spec.model_copy(update={"adaptive": a.model_copy(update={"mode": mode})})
    campaign = dataclasses.replace(campaign, spec=spec)
    check_adaptive(campaign)
    return campaign


def runs_done(folder: Path, total: int) -> Callable[[], str]:
    """``3 of 8 runs ended`` from the campaign's manifest (written atomically), for the progress
    line on stderr."""

    def note() -> str:
        runs = json.loads((folder / "campaign.json").read_text()).get("runs", {})
        ended = sum(1 for r in runs.values() if r.get("status") not in (None, "running"))
        return f"{ended} of {total} runs ended"

    return note


def run_rows(result: CampaignResult) -> list[dict[str, object]]:
    """``campaign run``'s table: each run's index, name, status, peak force (N) and the start
    of its reason."""
    return [{"run": r.index, "name": r.name, "status": r.status, "peak_N": r.peak_force_n,
             "reason": r.reason[:60]} for r in result.runs]  # fmt: skip


def run_lines(result: CampaignResult, folder: Path | None) -> list[str]:
    """``campaign run``'s text: the runs' table, then the report folder (if one was written)."""
    return [*table_lines(run_rows(result)), *([f"report: {folder}"] if folder else [])]


def status_lines(status: CampaignStatus) -> list[str]:
    """``campaign status``'s text: the campaign folder, then each run's row."""
    return [f"campaign folder: {Path(status['folder']).resolve()}", *table_lines(status["runs"])]


def missing_folder_note(folder: Path) -> str | None:
    """``campaign status`` of a folder that does not exist: where its runs may be instead."""
    if folder.exists():
        return None
    return (f"note: {folder} does not exist: the campaign has not run from here, or its runs "
            "are elsewhere (--out FOLDER; `cutlab demo` writes to out/demo)")  # fmt: skip
