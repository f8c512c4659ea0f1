"""The feed post-processor's report files: per-block CSV, load and feed along the path,
load histogram and final stock (PNG, matplotlib Agg). It reads a finished
:class:`~planning.feed.result.FeedPostResult`; the result knows nothing of its report.
"""

from __future__ import annotations

from pathlib import Path
from typing import TypedDict

import numpy as np

from planning.feed.result import FeedPostResult
from planning.stock import save_stock_png


class FeedReportPaths(TypedDict):
    """The report files :func:`write_report` wrote."""

    csv: Path
    load_feed_png: Path
    histogram_png: Path
    stock_png: Path


def write_report(
    result: FeedPostResult, folder: str | Path, stem: str = "feedpost"
) -> FeedReportPaths:
    """Write ``stem``-blocks.csv, -load-feed.png, -histogram.png, -stock.png; return the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    csv = out / f"{stem}-blocks.csv"
    result.blocks.to_dataframe().to_csv(csv, index=False, float_format="%.6g")
    paths["csv"] = csv

    sim = result.simulation
    feed_piece = result.motion_before.is_feed[sim.piece_segment]
    dist = np.cumsum(np.where(feed_piece, sim.piece_length_mm, 0.0))
    before = result.motion_before.feed_mm_min[sim.piece_segment]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True, dpi=110)
    ax1.plot(dist[feed_piece], result.piece_load_pct[feed_piece], lw=0.8, color="tab:red")
    top = float(np.nanmax(result.piece_load_pct[feed_piece], initial=0.0)) * 1.05 or 1.0
    for e in result.rule.load_edges_pct:  # the rule's bins: a feed step where a line is crossed
        if e <= top:
            ax1.axhline(e, color="0.85", lw=0.5, zorder=0)
    ax1.set_ylim(0, top)
    ax1.set_ylabel("cutting load (%)")
    rules = ", ".join(dict.fromkeys(
        f"T{sc.tool_number} {sc.rule.name if sc.rule else 'kept'}" for sc in result.sections
    )) if len(result.sections) > 1 else result.rule.name  # fmt: skip
    ax1.set_title(f"load (grey: the rule's bin edges) and feed along the path ({rules})")
    ax2.plot(dist[feed_piece], before[feed_piece], lw=0.8, color="0.5", label="programmed")
    ax2.plot(
        dist[feed_piece], result.piece_feed_mm_min[feed_piece], lw=0.8, color="tab:blue",
        label="adjusted",
    )  # fmt: skip
    ax2.set_ylabel("feed (mm/min)")
    ax2.set_xlabel("feed path length (mm)")
    ax2.legend(loc="upper right")
    fig.tight_layout()
    paths["load_feed_png"] = out / f"{stem}-load-feed.png"
    fig.savefig(paths["load_feed_png"])
    plt.close(fig)

    rule = result.rule
    summ = result.summary()
    counts, blocks = summ["load_histogram_path_mm"], summ["load_histogram"]
    assert isinstance(counts, list) and isinstance(blocks, list)  # summary() makes lists
    fig, ax = plt.subplots(figsize=(8, 4), dpi=110)
    ax.bar(np.arange(rule.n_bins), np.asarray(counts, float), color="tab:red")
    for i, nb in enumerate(blocks):
        if nb:
            ax.annotate(f"{nb}", (i, counts[i]), ha="center", va="bottom", fontsize=7)
    ax.set_xticks(np.arange(rule.n_bins))
    ax.set_xticklabels([f"{e:.3g}" for e in rule.load_edges_pct[1:]], rotation=60, fontsize=7)
    ax.set_xlabel("load bin upper edge (%)")
    ax.set_ylabel("feed path (mm)")
    ax.set_title("cutting load histogram over the rule's bins (numbers: blocks by block load)")
    fig.tight_layout()
    paths["histogram_png"] = out / f"{stem}-histogram.png"
    fig.savefig(paths["histogram_png"])
    plt.close(fig)

    paths["stock_png"] = save_stock_png(result.stock, out / f"{stem}-stock.png", "final stock")
    return {"csv": paths["csv"], "load_feed_png": paths["load_feed_png"],
            "histogram_png": paths["histogram_png"], "stock_png": paths["stock_png"]}  # fmt: skip
