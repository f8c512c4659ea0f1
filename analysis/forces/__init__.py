"""Cutting-force models: the face mill with ploughing (seed 003), the end mill (flat, ball, bull),
each behind the :class:`ForceModel` protocol (``model_for(tool)``: the registry, the only place
that tests a tool's class), and the most even force any feeds can give a program of steady cuts
(evenness).
"""

from analysis.forces.endmill import EndMillCut, endmill_forces, peak_force
from analysis.forces.evenness import ForceTable, SteadyCut
from analysis.forces.facemill import FaceMillCut, facemill_forces
from analysis.forces.models import ENDMILL, FACEMILL, MODELS, ForceModel, model_for, model_named

__all__ = [
    "ENDMILL",
    "FACEMILL",
    "MODELS",
    "EndMillCut",
    "FaceMillCut",
    "ForceModel",
    "ForceTable",
    "SteadyCut",
    "endmill_forces",
    "facemill_forces",
    "model_for",
    "model_named",
    "peak_force",
]
