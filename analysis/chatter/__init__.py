"""Chatter in recorded runs: per run and per NC block, from the force spectrum (energy away from
bands around the spindle's, so the tooth-passing, harmonics, and its strongest frequency), from
once-per-revolution sampling (Schmitz's statistic: the scatter of samples taken at one spindle
angle, revolution after revolution, against the scatter of the whole signal) and from the growth
of the part off the harmonics over the stretch. Defaults calibrated on the regenerative twin
(bench/bench_chatter_detect.py).

``detect_run(path_or_run)`` for a run file, ``detect_chatter(forces, rate, rpm, blocks=...)`` for
arrays, ``indicators(...)`` for one stretch; ``ChatterWatch`` judges a live force read by read
(:mod:`analysis.chatter.live`: the campaign's chatter suspender and the adaptive controller).
"""

from analysis.chatter.detect import (
    ChatterSettings,
    RunChatter,
    StretchChatter,
    detect_chatter,
    detect_run,
    indicators,
)
from analysis.chatter.live import ChatterWatch

__all__ = [
    "ChatterSettings",
    "ChatterWatch",
    "RunChatter",
    "StretchChatter",
    "detect_chatter",
    "detect_run",
    "indicators",
]
