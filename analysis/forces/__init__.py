"""Cutting-force models: the face mill with ploughing (seed 003), the end mill (flat, ball, bull),
each behind the :class:`ForceModel` protocol (``model_for(tool)``: the registry, the only place
that tests a tool's class), and the most even force any feeds can give a program of steady cuts
(evenness).
"""

from analysis.forces._facemill_geometry import chip_section, edge_table
from analysis.forces.endmill import EndMillCut, endmill_forces, peak_force
from analysis.forces.evenness import ForceTable, SteadyCut
from analysis.forces.facemill import FaceMillCut, facemill_forces
from analysis.forces.models import ENDMILL, FACEMILL, MODELS, ForceModel, model_for, model_named

__all__ = [
    "ENDMILL",
    "EndMillCut",
    "FACEMILL",
    "FaceMillCut",
    "ForceModel",
    "ForceTable",
    "MODELS",
    "SteadyCut",
    "chip_section",
    "edge_table",
    "endmill_forces",
    "facemill_forces",
    "model_for",
    "model_named",
    "peak_force",
]
