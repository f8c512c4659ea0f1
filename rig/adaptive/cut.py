"""The run's cut as the stability lobes see it, read from the campaign (one place for the adaptive
controller's pockets, :func:`rig.adaptive.session.lobes_for`, and the console's margin,
:func:`rig.console.chatter.stability_case`): the tool's modes (the twin's ``[sim] tool_modes``
first, else the tool's own), the material's end-mill coefficients, the campaign's teeth and the
test's radial immersion; the case itself is :func:`analysis.stability.endmill_case`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from analysis.stability import StabilityCase
    from rig.adaptive.campaign_view import LobeCampaign, LobeTest

NO_LOBES = "no lobes"


@dataclass(frozen=True)
class LobeCut:
    """A run's cut for the lobes: ``modes`` (axis, Hz, damping ratio, N/m), cutting coefficients
    N/m², teeth and radial immersion (width of cut over the diameter, at most 1)."""

    modes: tuple[tuple[str, float, float, float], ...]
    kt_n_m2: float
    kn_n_m2: float
    teeth: int
    radial_immersion: float

    def case(self, rpm: npt.ArrayLike, name: str = "") -> StabilityCase:
        """The :class:`analysis.stability.StabilityCase` at the speeds ``rpm``."""
        from analysis.stability import endmill_case

        return endmill_case(self.modes, self.kt_n_m2, self.kn_n_m2, self.teeth,
                            self.radial_immersion, np.atleast_1d(rpm), name)  # fmt: skip


def lobe_cut(campaign: LobeCampaign, test: LobeTest) -> LobeCut | str:
    """``test``'s cut in ``campaign`` for the lobes, or why there are none (one line)."""
    from analysis.forces import ENDMILL

    tool = getattr(campaign, "tool", None)
    spec = getattr(campaign, "spec", None)
    sim = getattr(spec, "sim", None)
    is_sim = getattr(getattr(spec, "campaign", None), "rig", "") == "sim"
    modes = sim.tool_modes if is_sim and sim is not None and sim.tool_modes else None
    modes = modes or getattr(tool, "modes", None)
    coef = getattr(getattr(campaign, "material", None), "endmill", None)
    if not modes:
        return f"{NO_LOBES}: the tool has no modes ([[tools.NAME.modes]] or [[sim.tool_modes]])"
    if not ENDMILL.describes(tool) or coef is None:
        return (f"{NO_LOBES}: lobes are computed for end mills with the material's end-mill "
                "coefficients")  # fmt: skip
    width = float(test.width_mm) if math.isfinite(test.width_mm) else float(tool.diameter_mm)
    return LobeCut(
        modes=tuple((m.axis, float(m.f_hz), float(m.zeta), float(m.k_N_m)) for m in modes),
        kt_n_m2=coef.Ktc_n_mm2 * 1e6, kn_n_m2=coef.Krc_n_mm2 * 1e6, teeth=int(campaign.teeth),
        radial_immersion=min(width / tool.diameter_mm, 1.0),
    )  # fmt: skip
