"""Chatter in recorded runs: per run and per NC block, from the force spectrum (energy away from
bands around the spindle's, so the tooth-passing, harmonics, and its strongest frequency), from
once-per-revolution sampling (Schmitz's statistic: the scatter of samples taken at one spindle
angle, revolution after revolution, against the scatter of the whole signal) and from the growth
of the part off the harmonics over the stretch. Defaults calibrated on the regenerative twin
(bench/bench_chatter_detect.py).

``detect_run(path_or_run)`` for a run file, ``detect_chatter(forces, rate, rpm, blocks=...)`` for
arrays, ``indicators(...)`` for one stretch (a live window, as an interlock would judge it).
"""

from analysis.chatter.detect import (
    ChatterSettings,
    RunChatter,
    StretchChatter,
    detect_chatter,
    detect_run,
    indicators,
)

__all__ = [
    "ChatterSettings",
    "RunChatter",
    "StretchChatter",
    "detect_chatter",
    "detect_run",
    "indicators",
]
