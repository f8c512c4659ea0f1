"""The check's picture: each quantity per cutting block against its limit."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from planning.limits.check import CheckResult
from planning.limits.model import LIMIT_UNITS

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def plot_check(res: CheckResult | list[CheckResult], path: str | Path, title: str = "") -> Path:
    """One panel per quantity (value per block, the allowed value dashed, violations red), the
    blocks of every tool's check in ``res``; a program that cuts nothing gets one panel saying
    so, not empty axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    checks = res if isinstance(res, list) else [res]
    frames = [c.blocks for c in checks if len(c.blocks)]
    df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    names = [k for k in LIMIT_UNITS if k in df]
    if not names:
        fig, ax = plt.subplots(figsize=(9, 2.5))
        ax.text(0.5, 0.5, "no cutting: no block removes stock", ha="center", va="center")
        ax.set_axis_off()
        return _save(fig, path, title)
    fig, axes = plt.subplots(len(names), 1, figsize=(9, 1.9 * len(names) + 0.6), sharex=True,
                             squeeze=False)  # fmt: skip
    for ax, k in zip(axes[:, 0], names):
        ok = df[f"{k}_allowed"].notna() if f"{k}_allowed" in df else df[k].isna()
        ax.plot(df["block"][ok], df[k][ok], ".", ms=3, color="tab:blue")
        # blocks whose tool has no such limit: grey rings, and the panel says so
        ax.plot(df["block"][~ok], df[k][~ok], "o", ms=3, mfc="none", color="0.6")
        if ok.any():
            ax.plot(df["block"][ok], df[f"{k}_allowed"][ok], "--", color="k", lw=1)
            bad = df[f"{k}_ratio"] > 1 + 1e-6
            ax.plot(df["block"][bad], df[k][bad], ".", ms=4, color="tab:red")
        if not ok.all():
            why = "no --force-limit given" if k == "force" else "limit not checked"
            ax.text(0.99, 0.9, f"grey: {why}", transform=ax.transAxes, ha="right", va="top",
                    fontsize=8, color="0.4")  # fmt: skip
        label = "depth" if k == "stability" else k
        ax.set_ylabel(f"{label} ({LIMIT_UNITS[k]})")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("block")
    return _save(fig, path, title)


def _save(fig: Figure, path: str | Path, title: str) -> Path:
    import matplotlib.pyplot as plt

    fig.suptitle(title or "limits per block")
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
