"""An end mill's cut as the stability lobes see it, from plain numbers: the tool's modes, the
material's end-mill cutting coefficients (N/m², as the case takes them), teeth and radial
immersion, down milling. The one place a run's cut becomes a :class:`StabilityCase` (the
adaptive controller's pockets and the console's margin both come through here).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from analysis.stability.case import StabilityCase

#: one mode: (axis "x"/"y", natural frequency Hz, damping ratio, stiffness N/m)
Mode = tuple[str, float, float, float]


def endmill_case(
    modes: Sequence[Mode], kt_n_m2: float, kn_n_m2: float, teeth: int,
    radial_immersion: float, rpm: Sequence[float] | np.ndarray, name: str = "",
) -> StabilityCase:  # fmt: skip
    """The down-milling :class:`StabilityCase` of the cut at the speeds ``rpm``."""
    axis, f_hz, zeta, k_n_m = zip(*modes, strict=True)
    return StabilityCase(
        teeth=int(teeth), milling="down", radial_immersion=float(radial_immersion),
        kt_n_m2=float(kt_n_m2), kn_n_m2=float(kn_n_m2), f_hz=np.array(f_hz, float),
        zeta=np.array(zeta, float), k_n_m=np.array(k_n_m, float), direction=tuple(axis),
        rpm=np.atleast_1d(np.asarray(rpm, float)), name=name,
    )  # fmt: skip
