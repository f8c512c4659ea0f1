"""Structural dynamics: modes from an impulse-hammer test, several per channel
(:mod:`~analysis.modal.hammer`, its stabilisation diagram :mod:`~analysis.modal.stabilisation`,
from a file: :mod:`~analysis.modal.files`), the modes file a stability calculation reads
(:mod:`~analysis.modal.modes`), and the dynamometer's filter on measured forces
(:mod:`~analysis.modal.filter`).
"""

from analysis.modal.files import hammer_file_record, modal_file, modal_lines
from analysis.modal.filter import DynamometerFilter
from analysis.modal.hammer import ImpactRecord, modal_analysis, tooth_passing_warnings
from analysis.modal.modes import ModalMode, ModeSet, load_modes, renamed_mode_fields, save_modes
from analysis.modal.plot import plot_frf

__all__ = [
    "DynamometerFilter",
    "ImpactRecord",
    "ModalMode",
    "ModeSet",
    "hammer_file_record",
    "load_modes",
    "modal_analysis",
    "modal_file",
    "modal_lines",
    "plot_frf",
    "renamed_mode_fields",
    "save_modes",
    "tooth_passing_warnings",
]
