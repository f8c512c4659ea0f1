"""Force-trace PNGs: a recorded run (one panel per channel, events marked, holes shaded) and a
parsed export (``plot_table``, `cutlab data plot` on a DynoWare/CSV file)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from analysis.errors import AnalysisError
from analysis.runs import file as rf
from analysis.runs.table import ForceTable, _time_column

_MARK = {
    rf.EV_OVERFLOW: "tab:red",
    rf.EV_GAP: "tab:red",
    rf.EV_QUEUE_FULL: "tab:orange",
    rf.EV_INTERLOCK: "tab:purple",
    rf.EV_FAULT: "black",
    rf.EV_SATURATION: "tab:brown",
    rf.EV_ZERO: "tab:green",
    rf.EV_PAUSE: "tab:gray",
}


def _envelope(t: np.ndarray, y: np.ndarray, bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Min/max per bin so that a long run plots every peak without drawing every sample."""
    n = len(t) // bins * bins
    if n == 0:
        return t, y
    tb = t[:n].reshape(bins, -1)
    yb = y[:n].reshape(bins, -1)
    tt = np.repeat(tb[:, 0], 2)
    yy = np.column_stack([yb.min(axis=1), yb.max(axis=1)]).ravel()
    return tt, yy


def plot_run(run: rf.Run, out: str | Path, max_points: int = 4000) -> Path:
    """Write ``out`` (PNG): calibrated force (N), or volts without a calibration, vs time (s)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = run.force_n if run.force_n is not None else run.volts
    unit = "N" if run.force_n is not None else "V"
    t = run.time_s - (run.t0_s if np.isfinite(run.t0_s) else 0.0)
    c = data.shape[1]
    fig, axes = plt.subplots(c, 1, sharex=True, figsize=(10, 1.8 + 1.6 * c), squeeze=False)
    ev = run.events
    # Contiguous stretches are drawn separately so a hole is not bridged by a line.
    cuts = np.flatnonzero(np.diff(run.sample_index) > 1) + 1
    pieces = np.split(np.arange(len(t)), cuts)
    for k, ax in enumerate(axes[:, 0]):
        for idx in pieces:
            bins = max(1, max_points * len(idx) // max(1, len(t)) // 2)
            if len(idx) > 2 * bins and len(t) > max_points:
                tt, yy = _envelope(t[idx], data[idx, k], bins)
            else:
                tt, yy = t[idx], data[idx, k]
            ax.plot(tt, yy, lw=0.6, color="tab:blue")
        ax.set_ylabel(f"{run.channel_names[k]} ({unit})")
        ax.grid(alpha=0.3)
        for _, e in ev.iterrows():
            color = _MARK.get(e["kind"])
            if color is None or e["sample"] < 0:
                continue
            x0 = e["sample"] / run.rate_hz
            if e["lost"] > 0:
                ax.axvspan(x0, x0 + e["lost"] / run.rate_hz, color=color, alpha=0.25, lw=0)
            else:
                ax.axvline(x0, color=color, lw=0.8, alpha=0.7)
    axes[-1, 0].set_xlabel("time since first sample (s)")
    lost = f", {run.samples_lost} samples lost" if run.samples_lost else ""
    state = run.status if run.complete else "INCOMPLETE (writer did not close the file)"
    fig.suptitle(
        f"{Path(run.path).name}: {c} channels at {run.rate_hz:g} Hz, "
        f"{run.duration_s:.3f} s, {state}{lost}",
        fontsize=10,
    )
    return _save(fig, out)


def _save(fig, out: str | Path) -> Path:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def plot_table(t: ForceTable, out: str | Path, rate_hz: float | None = None,
               max_points: int = 4000) -> Path:  # fmt: skip
    """Write ``out`` (PNG): each column of a parsed export but the time against time (s)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rate = rate_hz if rate_hz is not None else t.rate_hz
    if not (math.isfinite(rate) and rate > 0):
        raise AnalysisError(f"{t.path}: no sampling rate (no rate in the header and no time "
                            "column); give --rate HZ")  # fmt: skip
    t_col = _time_column(t.columns)
    cols = [k for k in range(len(t.columns)) if k != t_col]
    time_s = np.arange(len(t.data)) / rate
    fig, axes = plt.subplots(len(cols), 1, sharex=True, figsize=(10, 1.8 + 1.6 * len(cols)),
                             squeeze=False)  # fmt: skip
    bins = max(1, max_points // 2)
    for ax, k in zip(axes[:, 0], cols):
        if len(time_s) > max_points:
            tt, yy = _envelope(time_s, t.data[:, k], bins)
        else:
            tt, yy = time_s, t.data[:, k]
        ax.plot(tt, yy, lw=0.6, color="tab:blue")
        ax.set_ylabel(f"{t.columns[k]} ({t.units[k] or '?'})")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time since first sample (s)")
    fig.suptitle(f"{t.path.name}: {len(cols)} columns at {rate:g} Hz, "
                 f"{len(time_s) / rate:.3f} s (export)", fontsize=10)  # fmt: skip
    return _save(fig, out)
