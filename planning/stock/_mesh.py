"""Height field of a triangle mesh: the top-most triangle over each grid point (private to zmap).

Rasterised here, vectorised over triangles, because trimesh's ray queries need rtree or embree
(not installed) and a height field only needs the highest triangle over each point.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def rasterise_top(
    tri: NDArray[np.float64], x0: float, y0: float, s: float, nx: int, ny: int, bottom: float
) -> NDArray[np.float64]:
    """Highest triangle height over each cell centre; ``bottom`` where no triangle covers it."""
    h = np.full(ny * nx, -np.inf)
    # Skip vertical triangles: they add nothing to a height field.
    e1 = tri[:, 1, :2] - tri[:, 0, :2]
    e2 = tri[:, 2, :2] - tri[:, 0, :2]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    keep = np.abs(det) > 1e-12
    tri, det, e1, e2 = tri[keep], det[keep], e1[keep], e2[keep]
    i_lo = np.clip(np.ceil((tri[:, :, 0].min(1) - x0) / s - 0.5), 0, nx).astype(np.int64)
    i_hi = np.clip(np.floor((tri[:, :, 0].max(1) - x0) / s - 0.5) + 1, 0, nx).astype(np.int64)
    j_lo = np.clip(np.ceil((tri[:, :, 1].min(1) - y0) / s - 0.5), 0, ny).astype(np.int64)
    j_hi = np.clip(np.floor((tri[:, :, 1].max(1) - y0) / s - 0.5) + 1, 0, ny).astype(np.int64)
    wi = np.maximum(i_hi - i_lo, 0)
    wj = np.maximum(j_hi - j_lo, 0)
    count = wi * wj
    # In batches so the expanded (triangle, cell) list stays bounded.
    start = 0
    csum = np.cumsum(count)
    while start < len(tri):
        base = csum[start - 1] if start else 0
        stop = int(np.searchsorted(csum, base + 4_000_000, side="right"))
        stop = max(stop, start + 1)
        sl = slice(start, stop)
        c = count[sl]
        t_idx = np.repeat(np.arange(start, stop), c)
        if len(t_idx):
            off = np.arange(len(t_idx)) - np.repeat(np.cumsum(c) - c, c)
            ii = i_lo[t_idx] + off % wi[t_idx]
            jj = j_lo[t_idx] + off // wi[t_idx]
            px = x0 + (ii + 0.5) * s - tri[t_idx, 0, 0]
            py = y0 + (jj + 0.5) * s - tri[t_idx, 0, 1]
            d = det[t_idx]
            u = (px * e2[t_idx, 1] - py * e2[t_idx, 0]) / d
            v = (py * e1[t_idx, 0] - px * e1[t_idx, 1]) / d
            inside = (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1 + 1e-9)
            z = (
                tri[t_idx, 0, 2]
                + u * (tri[t_idx, 1, 2] - tri[t_idx, 0, 2])
                + v * (tri[t_idx, 2, 2] - tri[t_idx, 0, 2])
            )
            np.maximum.at(h, (jj * nx + ii)[inside], z[inside])
        start = stop
    h[~np.isfinite(h)] = bottom
    return h.reshape(ny, nx)
