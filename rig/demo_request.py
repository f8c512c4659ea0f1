"""What `cutlab demo` asks (:class:`DemoRequest`: one model read by the API and the CLI alike, the
options being its fields: rig.cli.options.model_rows) and the job that answers it
(:func:`demo_job`, :func:`rig.report.run_demo`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Literal

from pydantic import BaseModel, ConfigDict, Field

if TYPE_CHECKING:
    from rig.report import DemoResult

#: rig.report.DEMO_CAMPAIGN (not imported: `cutlab --help` stays fast)
CAMPAIGN = "facemill-ploughing"


class DemoRequest(BaseModel):
    """Runs ``configs/campaigns/facemill-ploughing.toml`` on the simulated rig (a simulated Fanuc
    control on a pseudo-terminal fed by the real DNC streamer, the simulated machine cutting with
    the material's true coefficients, the dynamometer's modes, the simulated DAQ and the HDF5
    logger), identifies the face-mill coefficients from the recorded runs, predicts the validation
    runs, and writes the report folder. It prints the identified coefficients beside the
    simulator's truth."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    # fmt: off
    out: str | None = Field(None, description="output folder (default: out/demo, "
                            "out/demo-independent with --forces independent)")
    campaign: str = Field(CAMPAIGN, description=f"campaign to run (default: {CAMPAIGN})")
    resume: bool = Field(False, description="keep finished runs of an earlier demo")
    forces: Literal["seed003", "independent"] | None = Field(None, description=(
        "where the twin's face-milling forces come from: seed003 (analysis.forces, the model the "
        "fit inverts) or independent (a simulator written apart from it); default: the "
        "campaign's [sim] force_model"))
    # fmt: on


def demo_job(
    req: DemoRequest, progress: bool = True, status: Callable[[str], None] = lambda msg: None
) -> DemoResult:
    """:func:`rig.report.run_demo` of a request (into its folder, or the default one)."""
    from rig.report import run_demo

    out = req.out or ("out/demo-independent" if req.forces == "independent" else "out/demo")
    return run_demo(req.campaign, out, resume=req.resume, progress=progress, status=status,
                    forces=req.forces)  # fmt: skip
