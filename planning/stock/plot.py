"""PNG of a Z-map stock: shaded height map (matplotlib, Agg)."""

from __future__ import annotations

import math
from pathlib import Path

from planning.stock.zmap import ZMap


def save_stock_png(stock: ZMap, path: str | Path, title: str = "stock") -> Path:
    """Shaded height map of ``stock`` written to ``path`` (PNG); returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LightSource, Normalize

    h = stock.heights_mm
    step = max(1, int(math.ceil(max(h.shape) / 1500)))  # keep the image a sane size
    hs = h[::step, ::step]
    xmin, xmax, ymin, ymax = stock.extent_mm
    fig, ax = plt.subplots(figsize=(7, 6), dpi=110)
    ls = LightSource(azdeg=315, altdeg=45)
    span = float(hs.max() - hs.min()) or 1.0
    shaded = ls.shade(
        hs, cmap=plt.get_cmap("viridis"), vert_exag=max(hs.shape) / span * 0.05,
        blend_mode="soft", dx=stock.spacing_mm * step, dy=stock.spacing_mm * step,
    )  # fmt: skip
    ax.imshow(shaded, origin="lower", extent=(xmin, xmax, ymin, ymax))
    sm = plt.cm.ScalarMappable(cmap="viridis", norm=Normalize(float(hs.min()), float(hs.max())))
    fig.colorbar(sm, ax=ax, label="height (mm)")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(title)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out
