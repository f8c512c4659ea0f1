"""Forces of the live ring's rows: the run's zero and calibration, as the run file derives them."""

from __future__ import annotations

from typing import Any

import numpy as np

from analysis.runs import file as rf


def force_n(meta: dict[str, Any], rows: np.ndarray) -> np.ndarray:
    """(n, c) N of the ring's rows (volts or codes) with the run info's zero and calibration."""
    volts = rows.astype(np.float64)
    if meta.get("sample_format") == rf.SAMPLE_FORMAT_RAW and meta.get("scaling_coeff"):
        volts = rf.raw_to_volts(rows, np.asarray(meta["scaling_coeff"], float))
    zero = np.asarray(meta.get("zero_v") or np.zeros(volts.shape[1]), float)
    return np.einsum("nj,ij->ni", volts - zero, np.asarray(meta["volts_to_n"], float))
