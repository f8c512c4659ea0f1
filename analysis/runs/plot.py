"""Force-trace PNG of a recorded run: one panel per channel, events marked, holes shaded."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from analysis.runs import file as rf

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
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
