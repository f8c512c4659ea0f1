"""Campaigns of test cuts: the config, the plan, the programs, a run on the simulated or the real
rig, the manifest of what was done.
"""

from rig.campaign.config import load_campaign
from rig.campaign.dryrun import dry_run, mode_warnings
from rig.campaign.runner import (
    CampaignResult,
    campaign_folder,
    campaign_status,
    plan_campaign,
    run_campaign,
    run_status,
)

__all__ = [
    "CampaignResult",
    "campaign_folder",
    "campaign_status",
    "dry_run",
    "load_campaign",
    "mode_warnings",
    "plan_campaign",
    "run_campaign",
    "run_status",
]
