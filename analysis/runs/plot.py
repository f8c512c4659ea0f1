"""Force-trace PNGs: a recorded run (one panel per channel, events marked, holes shaded) and a
parsed export (``plot_table``, `cutlab data plot` on a DynoWare/CSV file). Beside each channel's
whole record (a min/max band per bucket) a second panel shows a few revolutions of raw samples
from the middle of the cut, where the tooth passes can be seen."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

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


#: revolutions the detail panel shows (a window of DETAIL_S where the spindle speed is unknown)
DETAIL_REVS, DETAIL_S = 3, 0.05


def _detail_window(data: np.ndarray, rate_hz: float, rpm: float) -> tuple[slice, str]:
    """Samples of DETAIL_REVS revolutions (or DETAIL_S) centred on the busiest part of the
    record (the largest moving RMS of the resultant): the steady cut, not the air."""
    n = len(data)
    span = int(rate_hz * (DETAIL_REVS * 60.0 / rpm if rpm > 0 else DETAIL_S))
    span = max(8, min(span, n))
    what = f"{DETAIL_REVS} revolutions at {rpm:g} rpm" if rpm > 0 else f"{DETAIL_S * 1e3:g} ms"
    if n <= span:
        return slice(0, n), what
    step = max(1, n // 400)  # moving RMS on a coarse grid: cheap for long runs
    power = np.nan_to_num((data[::step] ** 2).sum(axis=1))
    k = max(1, span // step)
    csum = np.r_[0.0, np.cumsum(power)]
    mov = csum[k:] - csum[:-k]
    # the middle of the stretch near the maximum (a plateau's centre, not its first edge)
    top = np.flatnonzero(mov >= 0.9 * mov.max())
    centre = int(top[len(top) // 2]) * step + span // 2
    a = int(np.clip(centre - span // 2, 0, n - span))
    return slice(a, a + span), what


def plot_run(run: rf.Run, out: str | Path, max_points: int = 4000) -> Path:
    """Write ``out`` (PNG): calibrated force (N), or volts without a calibration, vs time (s)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = run.force_n if run.force_n is not None else run.volts
    unit = "N" if run.force_n is not None else "V"
    t = run.time_s - (run.t0_s if np.isfinite(run.t0_s) else 0.0)
    c = data.shape[1]
    fig, grid = plt.subplots(c, 2, sharex="col", figsize=(13, 1.8 + 1.6 * c), squeeze=False,
                             gridspec_kw={"width_ratios": [2.4, 1]})  # fmt: skip
    axes = grid[:, :1]
    rpm = abs(float(run.conditions.get("spindle_rpm") or 0.0)) if run.conditions else 0.0
    win, what = _detail_window(data, run.rate_hz, rpm)
    for k, ax in enumerate(grid[:, 1]):
        ax.plot(t[win] * 1e3, data[win, k], lw=0.7, color="tab:blue", marker=".", ms=1.5)
        ax.grid(alpha=0.3)
    grid[0, 1].set_title(f"detail: {what}, raw samples", fontsize=8)
    grid[-1, 1].set_xlabel("time since first sample (ms)")
    if len(t):
        for ax in axes[:, 0]:
            ax.axvspan(t[win][0], t[win][-1], color="tab:orange", alpha=0.15, lw=0)
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


def _save(fig: Any, out: str | Path) -> Path:
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
    fig, grid = plt.subplots(len(cols), 2, sharex="col", squeeze=False,
                             figsize=(13, 1.8 + 1.6 * len(cols)),
                             gridspec_kw={"width_ratios": [2.4, 1]})  # fmt: skip
    axes = grid[:, :1]
    rpm = _header_rpm(t.header)
    win, what = _detail_window(t.data[:, cols], rate, rpm)
    for ax, k in zip(grid[:, 1], cols):
        ax.plot(time_s[win] * 1e3, t.data[win, k], lw=0.7, color="tab:blue", marker=".", ms=1.5)
        ax.grid(alpha=0.3)
    grid[0, 1].set_title(f"detail: {what}, raw samples", fontsize=8)
    grid[-1, 1].set_xlabel("time since first sample (ms)")
    bins = max(1, max_points // 2)
    for ax, k in zip(axes[:, 0], cols):
        ax.axvspan(time_s[win][0], time_s[win][-1], color="tab:orange", alpha=0.15, lw=0)
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


def _header_rpm(header: dict[str, str]) -> float:
    """The spindle speed an export's header gives (rpm), 0 if none."""
    import re

    for key, value in header.items():
        if "rpm" in key.lower() or "spindle" in key.lower() or "drehzahl" in key.lower():
            m = re.match(r"^\s*([0-9]+(?:[.,][0-9]+)?)", str(value))
            if m:
                return float(m.group(1).replace(",", "."))
    return 0.0
