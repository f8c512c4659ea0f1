"""The report package's results, keys and value types spelled out: the figures a section reads
from a run (in memory: arrays beside numbers) and what `cutlab demo --json` prints."""

from __future__ import annotations

from collections.abc import Mapping
from typing import NotRequired, TypedDict

import numpy as np

__all__ = [
    "BandFigures",
    "ChatterDecay",
    "DemoSummary",
    "OnsetRow",
    "RevolutionStats",
    "SteadyMeans",
]


class SteadyMeans(TypedDict):
    """Mean forces over a run's steady cutting part, N (NaN: none), and its revolutions."""

    Fx_mean_N: float
    Fy_mean_N: float
    Fz_mean_N: float
    revs: int


class RevolutionStats(TypedDict):
    """A run's per-revolution feed-plane force (``means``, N) and the revolutions that cut
    (``cut``: indices); over the cutting ones: count, mean, spread (N; ``cv`` their ratio), cut
    time (s) and the revolution's period (s). With fewer than 3 cutting revolutions: NaN figures
    and no std_N, max_N, period_s."""

    run: str
    revolutions: int
    mean_N: float
    std_N: NotRequired[float]
    cv: float
    max_N: NotRequired[float]
    cut_time_s: float
    means: np.ndarray
    cut: np.ndarray
    period_s: NotRequired[float]
    program_feed_time_s: NotRequired[float]  # the afc section's: the program's feed time, s


class BandFigures(TypedDict):
    """The share of an adaptive run's cutting revolutions within the band of the target, over
    all of them and over the reachable ones (outside the controller's saturation spans); NaN
    when nothing cut."""

    within: float
    revolutions: int
    cut_time_s: float
    means: np.ndarray
    within_reachable: float
    reachable_revolutions: int
    saturated_revolutions: int
    saturated_s: float


class ChatterDecay(TypedDict):
    """The chatter component per revolution after a spindle move: the revolutions until it
    stays cleared (None: never), its share and RMS (N) per revolution, the revolutions judged."""

    cleared_revs: int | None
    shares: list[float]
    rms_n: list[float]
    revolutions: int


class OnsetRow(TypedDict, total=False):
    """The stability sweep's row per speed: the predicted limit (mm; None with a reason), the
    cuts' depths (mm) and verdicts, the observed onset (mm; None with a reason), its bracket,
    the error against the prediction (%), whether within tolerance, stable cuts above it."""

    spindle_rpm: float
    predicted_limit_mm: float | None
    predicted_limit_mm_reason: str
    depths_mm: list[float]
    chatter: list[bool]
    observed_onset_mm: float | None
    observed_onset_mm_reason: str
    bracket_mm: list[float | None] | None
    stable_above_onset_mm: list[float]
    error_pct: float | None
    within_tolerance: bool
    true_limit_mm: float  # the twin's true modes' limit (a simulated rig only)
    predicted_chatter_hz: float


class DemoSummary(TypedDict):
    """`cutlab demo --json`: runs, status counts, the identification (its message and the
    coefficient rows of the report's face-mill section), the report folder, wall s."""

    campaign: str
    force_model: str
    runs: int
    status_counts: dict[str, int]
    identification: str | None
    coefficients: list[Mapping[str, object]]
    max_error_pct_seed003: float | None
    validation_max_abs_error_pct: float | None
    report: str | None
    wall_s: float
