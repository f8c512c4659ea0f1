"""PNG plots of the campaign report (matplotlib, Agg)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from rig.report.base import LoadedRun


def _plt():  # noqa: ANN202 - the pyplot module
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_traces(runs: Sequence[LoadedRun], path: Path, title: str, max_runs: int = 12) -> Path:
    """Force channels against time of up to ``max_runs`` runs, one panel each (min/max band);
    the title says how many of how many when it leaves runs out."""
    plt = _plt()
    shown = list(runs)[:max_runs]
    n = max(1, len(shown))
    cols = 3 if n > 4 else 1
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.0 * rows + 0.6), squeeze=False)
    for ax, lr in zip(axes.flat, shown):
        run = lr.run
        if run.force_n is None or not len(run.force_n):
            continue
        # Min/max envelope per bucket: plain decimation would alias the tooth-passing pulses.
        n = len(run.time_s)
        rpm = abs(float(run.conditions.get("spindle_rpm") or 0.0))
        # One bucket per revolution (a band over the tooth passes), at most 2000 buckets.
        step = max(1, n // 2000, int(run.rate_hz * 60.0 / rpm) if rpm else 1)
        m = n // step
        t = run.time_s[: m * step : step] - run.time_s[0]
        f = run.force_n[: m * step].reshape(m, step, -1)
        lo, hi = f.min(axis=1), f.max(axis=1)
        for k, name in enumerate(run.channel_names[: f.shape[2]]):
            ax.fill_between(t, lo[:, k], hi[:, k], lw=0, alpha=0.6, label=name)
        ax.set_title(lr.name, fontsize=7)
        ax.tick_params(labelsize=6)
        _revolutions_inset(ax, run, rpm)
    for ax in list(axes.flat)[len(shown) :]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=6, loc="upper left")
    fig.supxlabel("time in run, s", fontsize=8)
    fig.supylabel("force, N", fontsize=8)
    subset = f" ({len(shown)} of {len(runs)} runs shown)" if len(shown) < len(runs) else ""
    fig.suptitle(f"{title}: force traces{subset}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _revolutions_inset(ax: Any, run: Any, rpm: float, revs: int = 2) -> None:
    """Raw samples of ``revs`` revolutions from the middle of the cut, inset in the run's panel
    (the band shows the whole run; the inset shows what one revolution looks like)."""
    f = run.force_n
    n = len(f)
    span = int(run.rate_hz * revs * 60.0 / rpm) if rpm else int(run.rate_hz * 0.05)
    if n < 4 * max(span, 1):
        return
    res = np.abs(f).sum(axis=1)
    busy = np.flatnonzero(res > 0.2 * np.percentile(res, 99))
    mid = int(np.median(busy)) if busy.size else n // 2
    a = int(np.clip(mid - span // 2, 0, n - span))
    ins = ax.inset_axes([0.62, 0.58, 0.36, 0.38])
    tt = (run.time_s[a : a + span] - run.time_s[a]) * 1e3
    for k in range(f.shape[1]):
        ins.plot(tt, f[a : a + span, k], lw=0.5)
    ins.set_title(f"{revs} rev, ms" if rpm else "50 ms", fontsize=5, pad=1)
    ins.tick_params(labelsize=4, length=1, pad=1)
    ins.patch.set_alpha(0.85)


def plot_pred_vs_meas(rows: Sequence[dict], path: Path, title: str) -> Path:
    """Predicted against measured mean forces, one point per run and axis, with the 1:1 line."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    lim = 0.0
    for axis, mk in (("x", "o"), ("y", "s"), ("z", "^")):
        m = np.array([r[f"F{axis}_measured_N"] for r in rows])
        p = np.array([r[f"F{axis}_predicted_N"] for r in rows])
        ax.plot(m, p, mk, ms=4, label=f"F{axis}")
        lim = max(lim, float(np.nanmax(np.abs(np.r_[m, p]))) if len(m) else 0.0)
    ax.plot([-lim, lim], [-lim, lim], "k-", lw=0.6)
    ax.set_xlabel("measured mean force, N")
    ax.set_ylabel("predicted mean force, N")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)
    ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
