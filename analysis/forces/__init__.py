"""Cutting-force models: the face mill with ploughing (seed 003), the end mill (flat, ball, bull),
and the most even force any feeds can give a program of steady cuts (evenness).
"""

from analysis.forces.endmill import EndMillCut, endmill_forces, peak_force
from analysis.forces.evenness import ForceTable, SteadyCut
from analysis.forces.facemill import FaceMillCut, facemill_forces

__all__ = [
    "EndMillCut",
    "FaceMillCut",
    "ForceTable",
    "SteadyCut",
    "endmill_forces",
    "facemill_forces",
    "peak_force",
]
