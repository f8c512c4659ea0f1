"""Milling stability lobes: the chatter-free axial depth per spindle speed from the tool's modes
and the cutting coefficients, by semi-discretization (:mod:`~analysis.stability.sd`, the default;
it finds the period-doubling lobes of interrupted cuts) or the zero-order approximation
(:mod:`~analysis.stability.zoa`); the case from TOML (:mod:`~analysis.stability.case`) or an
end mill's cut (:func:`endmill_case`).
"""

from analysis.stability.case import StabilityCase, load_case
from analysis.stability.endmill import endmill_case
from analysis.stability.lobes import METHODS, Lobes, plot_lobes, stability_lobes

__all__ = [
    "METHODS",
    "Lobes",
    "StabilityCase",
    "endmill_case",
    "load_case",
    "plot_lobes",
    "stability_lobes",
]
