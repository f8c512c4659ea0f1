"""Dynamometer dynamics: modes from an impulse-hammer test (:mod:`~analysis.modal.hammer`) and the
dynamometer's filter on measured forces (:mod:`~analysis.modal.filter`).
"""

from analysis.modal.filter import DynamometerFilter
from analysis.modal.hammer import ImpactRecord, modal_analysis, plot_frf, tooth_passing_warnings

__all__ = [
    "DynamometerFilter",
    "ImpactRecord",
    "modal_analysis",
    "plot_frf",
    "tooth_passing_warnings",
]
