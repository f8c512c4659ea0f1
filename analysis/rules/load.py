"""Cutting load, exactly as seed 001 (2.2) defines it: a relative metal-removal rate in percent.

For a plunge (a Z-only move)::

    load = removed volume / (pi r^2 x path length) x 100

for every other move::

    load = removed volume / (flute length x tool diameter x path length) x 100

i.e. the removed volume against the largest volume the tool could remove along that path. The
feed post-processor (``planning.feed.post``) and the rule derivation (``analysis.rules.rule``) both
use :func:`cutting_load_percent`, so there is one definition.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.errors import AnalysisError


def cutting_load_percent(
    removed_mm3: ArrayLike,
    path_mm: ArrayLike,
    plunge: ArrayLike,
    tool_diameter_mm: float,
    flute_length_mm: float,
) -> NDArray[np.float64]:
    """Seed 001's cutting load, percent, per move (vectorised).

    Parameters
    ----------
    removed_mm3 : array_like, shape (n,), mm^3
        Volume the move removed (from the Z-map).
    path_mm : array_like, shape (n,), mm
        Length of the tool path of the move. A move of zero length has load 0.
    plunge : array_like of bool, shape (n,)
        True for a Z-only move (the plunge formula), False otherwise.
    tool_diameter_mm, flute_length_mm : float, mm
        The tool's diameter and flute (cutting edge) length.

    Returns
    -------
    load : ndarray, shape (n,), percent
    """
    if not (math.isfinite(tool_diameter_mm) and tool_diameter_mm > 0):
        raise AnalysisError(f"tool_diameter_mm = {tool_diameter_mm}: must be > 0 (mm)")
    if not (math.isfinite(flute_length_mm) and flute_length_mm > 0):
        raise AnalysisError(f"flute_length_mm = {flute_length_mm}: must be > 0 (mm)")
    vol = np.asarray(removed_mm3, dtype=float)
    path = np.asarray(path_mm, dtype=float)
    plunge_b = np.asarray(plunge, dtype=bool)
    vol, path, plunge_b = np.broadcast_arrays(vol, path, plunge_b)
    if np.any(vol < 0) or np.any(path < 0):
        bad = "removed_mm3" if np.any(vol < 0) else "path_mm"
        arr = vol if bad == "removed_mm3" else path
        i = int(np.argmax(arr < 0))
        raise AnalysisError(f"{bad}[{i}] = {arr.flat[i]}: must be >= 0 (mm^3 / mm)")
    r = tool_diameter_mm / 2
    section_mm2 = np.where(plunge_b, math.pi * r * r, flute_length_mm * tool_diameter_mm)
    with np.errstate(divide="ignore", invalid="ignore"):
        load = np.where(path > 0, vol / (section_mm2 * np.where(path > 0, path, 1.0)) * 100, 0.0)
    return load


def groove_area_mm2(
    kind: str, diameter_mm: float, depth_mm: float, corner_radius_mm: float = 0.0
) -> float:
    """Cross-section of a full-width slot cut by an end mill at axial depth ``depth_mm``, mm^2.

    Closed forms: flat ``D d``; ball, the circular segment of radius R at depth d (d <= R, then
    the straight flank); bull, the flat bottom plus two quarter-torus corners. Used to compute
    the reference load of a slotting test cut (seed 001 Table 2: 0.3 mm deep with a phi 30 ball).
    """
    D, d = float(diameter_mm), float(depth_mm)
    if not D > 0 or not d >= 0:
        raise AnalysisError(f"diameter_mm = {D}, depth_mm = {d}: need D > 0 and depth >= 0 (mm)")
    if kind == "flat":
        return D * d
    rc = D / 2 if kind == "ball" else float(corner_radius_mm)
    if kind not in ("ball", "bull"):
        raise AnalysisError(f"tool kind '{kind}': expected flat, ball or bull")
    flat_w = D - 2 * rc  # width of the flat bottom
    dc = min(d, rc)  # depth within the corner radius
    # Each rounded corner: area between the corner arc and the tool's outer vertical line, to dc.
    seg = rc * rc * math.acos((rc - dc) / rc) - (rc - dc) * math.sqrt(max(2 * rc * dc - dc * dc, 0))
    corners = seg  # two half-segments = one full circular segment of the corner circle
    above = max(d - rc, 0.0) * D  # straight flank above the corner radius
    return flat_w * d + corners + above


def slot_load_percent(
    kind: str,
    diameter_mm: float,
    depth_mm: float,
    flute_length_mm: float,
    corner_radius_mm: float = 0.0,
) -> float:
    """Seed 001 load of a straight full-width slot at ``depth_mm`` (the base-feed test cut), %."""
    area = groove_area_mm2(kind, diameter_mm, depth_mm, corner_radius_mm)
    return float(cutting_load_percent(area, 1.0, False, diameter_mm, flute_length_mm))
