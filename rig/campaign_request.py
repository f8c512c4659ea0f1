"""What `cutlab campaign run` asks (:class:`CampaignRunRequest`: one model read by the API and the
CLI alike, the options being its fields: rig.cli.options.model_rows), the campaign it names
(:func:`request_campaign`) and the run (:func:`run_request`, :func:`rig.campaign.run_campaign`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

from pydantic import BaseModel, ConfigDict, Field

if TYPE_CHECKING:
    from rig.campaign import CampaignResult
    from rig.campaign.config import Campaign
    from rig.campaign.run import StopRequest
    from rig.campaign.runner import SessionFactory


class CampaignRunRequest(BaseModel):
    """Run (or resume) a campaign; ``dry_run`` checks without cutting."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    # fmt: off
    config: str = Field(json_schema_extra={"flag": "config"},
                        description="campaign TOML, or a name in configs/campaigns/")
    dry_run: bool = Field(False, description="check config, hardware and programs")
    out: str | None = Field(None, description="folder of campaign folders (default: "
                            "campaign.output_dir)")
    no_report: bool = Field(False, description="skip the analysis and report")
    fresh: bool = Field(False, description="start over: earlier runs are moved to "
                        "<folder>/before-<time>/")
    force_resume: bool = Field(False, description="resume although inputs changed (recorded in "
                               "campaign.json)")
    adaptive: Literal["feed", "spindle", "both"] | None = Field(None, description=(
        "GRBL: the [adaptive] loop in this mode (its target and limits: the config's [adaptive])"))
    # fmt: on


def request_campaign(req: CampaignRunRequest) -> Campaign:
    """The campaign ``req`` names, with its ``adaptive`` mode if any."""
    from rig.campaign import load_campaign
    from rig.campaign.commands import with_adaptive

    campaign = load_campaign(req.config)
    return with_adaptive(campaign, req.adaptive) if req.adaptive else campaign


def run_request(
    campaign: Campaign, req: CampaignRunRequest, progress: bool = True,
    session_factory: SessionFactory | None = None, stop: StopRequest | None = None,
) -> CampaignResult:  # fmt: skip
    """:func:`rig.campaign.run_campaign` of ``campaign`` as ``req`` asks (``session_factory``
    and ``stop``: a live console's)."""
    from rig.campaign import run_campaign

    return run_campaign(campaign, out_root=req.out, progress=progress, fresh=req.fresh,
                        force_resume=req.force_resume, session_factory=session_factory,
                        stop=stop)  # fmt: skip
