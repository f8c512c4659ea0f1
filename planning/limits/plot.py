"""The check's picture: each quantity per cutting block against its limit."""

from __future__ import annotations

from pathlib import Path

from planning.limits.check import CheckResult
from planning.limits.model import LIMIT_UNITS


def plot_check(res: CheckResult, path: str | Path, title: str = "") -> Path:
    """One panel per quantity (value per block, the allowed value dashed, violations red)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    df = res.blocks
    names = [k for k in LIMIT_UNITS if k in df]
    fig, axes = plt.subplots(len(names), 1, figsize=(9, 1.9 * len(names) + 0.6), sharex=True,
                             squeeze=False)  # fmt: skip
    for ax, k in zip(axes[:, 0], names):
        ax.plot(df["block"], df[k], ".", ms=3, color="tab:blue")
        if f"{k}_allowed" in df:
            ax.plot(df["block"], df[f"{k}_allowed"], "--", color="k", lw=1)
            bad = df[f"{k}_ratio"] > 1 + 1e-6
            ax.plot(df["block"][bad], df[k][bad], ".", ms=4, color="tab:red")
        label = "depth" if k == "stability" else k
        ax.set_ylabel(f"{label} ({LIMIT_UNITS[k]})")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("block")
    fig.suptitle(title or "limits per block")
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
