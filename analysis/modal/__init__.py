"""Dynamometer dynamics: modes from an impulse-hammer test (:mod:`~analysis.modal.hammer`, from a
file: :mod:`~analysis.modal.files`) and the dynamometer's filter on measured forces
(:mod:`~analysis.modal.filter`).
"""

from analysis.modal.files import hammer_file_record, modal_file
from analysis.modal.filter import DynamometerFilter
from analysis.modal.hammer import ImpactRecord, modal_analysis, plot_frf, tooth_passing_warnings

__all__ = [
    "DynamometerFilter",
    "ImpactRecord",
    "hammer_file_record",
    "modal_analysis",
    "modal_file",
    "plot_frf",
    "tooth_passing_warnings",
]
