"""Tool-path plots (matplotlib, Agg): a 3-D view and a top (XY) view side by side.

Rapids are dashed, feed moves solid (coloured by feed), arcs drawn as chords within 0.01 mm.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from planning.nc.arcs import linearize
from planning.nc.motion import RAPID, Motion


def plot_motion(
    motion: Motion, path: str | Path, *, title: str = "", chord_tol_mm: float = 0.01
) -> Path:
    """Write a PNG of ``motion`` to ``path`` (parent folders created); returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lin = linearize(motion, chord_tol_mm)
    rapid = lin.kind == RAPID
    feed = motion.is_feed[lin.source]
    fig = plt.figure(figsize=(13, 6))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    segs = np.stack([lin.start, lin.end], axis=1)
    if rapid.any():
        ax3.add_collection3d(
            Line3DCollection(
                segs[rapid], colors="0.5", linestyles="--", linewidths=0.8, label="rapid"
            )
        )
        ax2.add_collection(
            LineCollection(
                segs[rapid][:, :, :2], colors="0.5", linestyles="--", linewidths=0.8, label="rapid"
            )
        )
    if feed.any():
        f = motion.feed_mm_min[lin.source][feed]
        lc3 = Line3DCollection(segs[feed], cmap="viridis", linewidths=1.2, label="feed")
        lc3.set_array(f)
        ax3.add_collection3d(lc3)
        lc2 = LineCollection(segs[feed][:, :, :2], cmap="viridis", linewidths=1.2, label="feed")
        lc2.set_array(f)
        ax2.add_collection(lc2)
        fig.colorbar(lc2, ax=ax2, label="feed, mm/min", shrink=0.8)
    if len(lin):
        pts = np.concatenate([lin.start, lin.end])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = np.maximum(0.05 * (hi - lo).max(), 1.0)
        ax3.set_xlim(lo[0] - pad, hi[0] + pad)
        ax3.set_ylim(lo[1] - pad, hi[1] + pad)
        ax3.set_zlim(lo[2] - pad, hi[2] + pad)
        ax2.set_xlim(lo[0] - pad, hi[0] + pad)
        ax2.set_ylim(lo[1] - pad, hi[1] + pad)
    ax3.set_xlabel("X, mm")
    ax3.set_ylabel("Y, mm")
    ax3.set_zlabel("Z, mm")
    ax3.set_title("3-D view")
    ax2.set_aspect("equal", adjustable="box")
    ax2.set_xlabel("X, mm")
    ax2.set_ylabel("Y, mm")
    ax2.set_title("top view (XY)")
    handles = [
        Line2D([], [], color="0.5", linestyle="--", linewidth=0.8, label="rapid"),
        Line2D([], [], color=plt.get_cmap("viridis")(0.6), linewidth=1.2, label="feed"),
    ]
    ax2.legend(handles=handles, loc="upper right", fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
