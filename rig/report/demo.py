"""``cutlab demo``: seed 003's face-milling campaign run on the simulated rig, then reported.

:func:`run_demo` runs the campaign (a fresh folder unless resuming) and writes its report; the
identified coefficients, beside the simulator's truth, are in :attr:`DemoResult.facemill`.
"""

from __future__ import annotations

import dataclasses
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.campaign import CampaignResult, campaign_folder, load_campaign, run_campaign
from rig.errors import RigError
from rig.report.base import Report
from rig.report.results import DemoSummary
from rig.report.write import write_report

#: the campaign the demo runs by default (configs/campaigns/)
DEMO_CAMPAIGN = "facemill-ploughing"

#: where the twin's face-milling forces come from (``[sim] force_model``)
FORCE_MODELS = ("seed003", "independent")


@dataclass(frozen=True)
class DemoResult:
    """The campaign's result, its report (None when the campaign stopped), the demo's folder and
    its wall time (s)."""

    campaign: CampaignResult
    report: Report | None
    folder: Path
    wall_s: float
    force_model: str = "seed003"

    @property
    def stopped(self) -> bool:
        return self.campaign.stopped

    @property
    def facemill(self) -> dict[str, Any]:
        """The report's face-mill identification: message, coefficients (identified, truth,
        error_pct, std_error), max_error_pct_seed003, validation_max_abs_error_pct, ..."""
        return self.report.summary.get("facemill-coefficients", {}) if self.report else {}

    @property
    def ok(self) -> bool:
        """Every run succeeded and the coefficients were identified."""
        return self.campaign.ok and bool(self.facemill.get("success"))

    def summary(self) -> DemoSummary:
        """``cutlab demo --json``: runs, status counts, the identification, the report folder."""
        fm = self.facemill
        return {
            "campaign": self.campaign.name,
            "force_model": self.force_model,
            "runs": len(self.campaign.runs),
            "status_counts": self.campaign.counts,
            "identification": fm.get("message"),
            "coefficients": fm.get("coefficients", []),
            "max_error_pct_seed003": fm.get("max_error_pct_seed003"),
            "validation_max_abs_error_pct": fm.get("validation_max_abs_error_pct"),
            "report": str(self.report.folder) if self.report else None,
            "wall_s": round(self.wall_s, 1),
        }


def run_demo(
    campaign: str = DEMO_CAMPAIGN,
    out_root: str | Path = "out/demo",
    *,
    resume: bool = False,
    progress: bool = True,
    status: Callable[[str], None] = lambda msg: None,
    forces: str | None = None,
) -> DemoResult:
    """Run ``campaign`` (a name or TOML; it must use the simulated rig) into ``out_root``,
    replacing an earlier demo's folder unless ``resume``, then write its report (not when the
    campaign stopped). ``status(message)`` gets each step; ``progress`` shows the campaign bar.
    ``forces`` overrides the campaign's ``[sim] force_model`` (:data:`FORCE_MODELS`)."""
    t0 = time.monotonic()
    c = load_campaign(campaign)
    if c.spec.campaign.rig != "sim":
        raise RigError(f"{c.path}: the demo runs on the simulated rig (rig = 'sim')")
    if forces is not None:
        if forces not in FORCE_MODELS:
            raise RigError(f"--forces {forces}: expected one of {', '.join(FORCE_MODELS)}")
        sim = c.spec.sim.model_copy(update={"force_model": forces})
        c = dataclasses.replace(c, spec=c.spec.model_copy(update={"sim": sim}))
    folder = campaign_folder(c, out_root)
    if folder.exists() and not resume:
        status(f"demo: replacing the earlier demo output in {folder}")
        shutil.rmtree(folder)
    status(
        f"demo: campaign {c.name}: {len(c.tests)} test cuts on the simulated rig "
        f"(x{c.spec.sim.speed:g} real time, forces: {c.spec.sim.force_model}); "
        f"runs -> {folder / 'runs'}"
    )
    result = run_campaign(c, out_root=out_root, progress=progress)
    report = None
    if not result.stopped:
        status("demo: identifying the coefficients and writing the report ...")
        report = write_report(folder)
    return DemoResult(result, report, folder, time.monotonic() - t0, c.spec.sim.force_model)
