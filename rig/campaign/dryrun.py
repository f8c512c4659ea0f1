"""A campaign checked without cutting: its programs, the hardware and the room on the disk."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from analysis.errors import ConfigError
from rig.campaign.config import Campaign
from rig.campaign.plan import plan_campaign
from rig.campaign.results import DryRunSummary
from rig.campaign.runner import campaign_folder


@dataclass(frozen=True)
class DryRun:
    campaign: str
    rig: str
    tests: int
    programs_checked: int
    expected_machine_s: float
    hardware: list[str]
    problems: list[str]
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems

    def as_dict(self) -> DryRunSummary:
        """Every field, the expected machine time rounded to 0.1 s, and ``ok``."""
        return {"campaign": self.campaign, "rig": self.rig, "tests": self.tests,
                "programs_checked": self.programs_checked,
                "expected_machine_s": round(self.expected_machine_s, 1),
                "hardware": list(self.hardware), "problems": list(self.problems),
                "warnings": list(self.warnings), "ok": self.ok}  # fmt: skip


def dry_run(campaign: Campaign, out_root: str | Path | None = None) -> DryRun:
    """Check what the campaign will use without cutting: every program (feed rules included),
    the hardware (``rig = "real"``: the NI device, its rate limit, the serial port) and the room
    on the disk for its runs. The config itself was checked by :func:`load_campaign`. Problems
    are listed, not raised, so all of them are seen at once."""
    from rig.log import free_space_problem

    problems: list[str] = []
    try:
        plans = plan_campaign(campaign)
    except ConfigError as exc:
        plans, problems = [], str(exc).splitlines()
    if campaign.spec.campaign.rig == "real":
        from rig.campaign.real import check_hardware

        hardware, missing = check_hardware(campaign)
        problems += missing
    else:
        hardware = ["simulated rig: controller on a pseudo-terminal, simulated DAQ"]
    rate_hz = campaign.spec.daq.rate_hz or campaign.rig.daq.rate_hz
    per_s = rate_hz * len(campaign.rig.dynamometer.channels) * 8
    need = sum(per_s * (p.expected_s + 2 * campaign.spec.daq.rest_s + 10.0) for p in plans)
    space = free_space_problem(campaign_folder(campaign, out_root), need)
    problems += [space] if space else []
    n = len(campaign.tests)
    return DryRun(
        campaign.name, campaign.spec.campaign.rig, n, len(plans),
        sum(p.expected_s for p in plans), hardware, problems, mode_warnings(campaign),
    )  # fmt: skip


def mode_warnings(campaign: Campaign) -> list[str]:
    """Tooth-passing harmonics of the planned spindle speeds near a dynamometer mode (seed 003
    3.2: the measured force would be amplified there)."""
    from analysis.modal import tooth_passing_warnings

    rpms = sorted({t.spindle_rpm for t in campaign.tests})
    return tooth_passing_warnings(campaign.rig.dynamometer.modes, rpms, campaign.teeth)
