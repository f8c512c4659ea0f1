"""The load the program ahead will make: a per-position, per-override table of the revolution
mean feed-plane force ``|Fxy|`` along a campaign's cutting pass, from its stock model (the
stepped block) and the material's end-mill coefficients, for the adaptive loop's feed-forward
(:mod:`rig.adaptive.feedforward`), as ``plan feed`` predicts the load offline for seed 001.

The engagement (a slot along +X, the cutter's leading half in the block): an edge point at
immersion angle ``phi`` (0 at +Y, pi/2 along the feed, analysis.forces.endmill's convention) of
an axial slice of radius ``rho`` sits ``rho sin(phi)`` ahead of the cutter's centre, outside
every earlier position of the cutter, so it cuts where the *uncut* block's top there is above the
slice. The block's tops are cut into layers between the distinct step heights (each split in
``SUBLAYERS`` slices with their own radius); a layer's force over the arcs where the stock ahead
reaches it is the arcs' force at the layer's top depth less that at its bottom depth, and an arc
(a, b) is the arc (0, b) less (0, a) (the edge forces add, as ``planning.feed.force`` sums a
piece's arcs). Forces are affine in the feed per tooth, so each (depth, end angle) is evaluated
at two feeds once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from analysis.config import EndMill, EndMillCoefficients
    from rig.adaptive.campaign_view import AdaptiveCampaign, AdaptiveTest, PassGeometry

#: override grid of the table, % (GRBL 1.1's 10-200 in steps of 2)
PCT_GRID = np.arange(10, 201, 2)
#: path grid spacing, mm (a fifth of a revolution's feed at 1000 mm/min and 2000 rpm)
X_STEP_MM = 0.1
#: end angles of the arc tables, 1 deg apart (interpolated between)
ANGLES_DEG = np.arange(0.0, 180.5, 1.0)
SUBLAYERS = 3
N_PHI = 72  # rotation angles over one revolution (the mean over a revolution)
N_DISCS = 24


@dataclass(frozen=True)
class LoadProfile:
    """``force_n[i, j]``: the predicted revolution mean of |Fxy|, N, with the cutter's centre
    at ``x_mm[i]`` of the cutting pass and the feed override at ``PCT_GRID[j]`` % of
    ``feed_mm_min``; the pass runs from ``x_start_mm`` to ``x_end_mm`` along +X."""

    x_mm: np.ndarray
    force_n: np.ndarray
    feed_mm_min: float
    rpm: float
    x_start_mm: float
    x_end_mm: float
    source: str

    def force_at(self, x_mm: float | np.ndarray, pct: float | np.ndarray) -> np.ndarray:
        """Predicted |Fxy| N at positions ``x_mm`` and overrides ``pct`` (broadcast), bilinear
        in the table; 0 outside the pass."""
        x = np.asarray(x_mm, float)
        p = np.clip(np.asarray(pct, float), PCT_GRID[0], PCT_GRID[-1])
        fi = np.clip((x - self.x_mm[0]) / X_STEP_MM, 0, len(self.x_mm) - 1)
        fj = (p - PCT_GRID[0]) / (PCT_GRID[1] - PCT_GRID[0])
        i0 = np.minimum(fi.astype(int), len(self.x_mm) - 2)
        j0 = np.minimum(fj.astype(int), len(PCT_GRID) - 2)
        wi, wj = fi - i0, fj - j0
        f = self.force_n
        top = f[i0, j0] * (1 - wj) + f[i0, j0 + 1] * wj
        bot = f[i0 + 1, j0] * (1 - wj) + f[i0 + 1, j0 + 1] * wj
        out = top * (1 - wi) + bot * wi
        return np.where((x < self.x_mm[0]) | (x > self.x_mm[-1]), 0.0, out)

    def pct_for(self, x_mm: float, force_n: float, lo: int, hi: int) -> tuple[int, bool]:
        """(the override % within lo..hi whose predicted force at ``x_mm`` is nearest
        ``force_n``, whether it is within 1 % of it)."""
        p = PCT_GRID[(PCT_GRID >= lo) & (PCT_GRID <= hi)].astype(float)
        f = self.force_at(np.full(p.shape, x_mm), p)
        err = np.abs(f - force_n)
        k = int(np.argmin(err))
        # refine between the grid's neighbours (the force grows with the feed)
        best = p[k]
        for kk in (k - 1, k):
            if 0 <= kk < len(p) - 1 and (f[kk] - force_n) * (f[kk + 1] - force_n) <= 0:
                df = f[kk + 1] - f[kk]
                best = p[kk] + (force_n - f[kk]) / df * (p[kk + 1] - p[kk]) if df else p[kk]
        pct = int(round(min(max(best, lo), hi)))
        ok = abs(float(self.force_at(x_mm, pct)) / force_n - 1.0) <= 0.01 if force_n > 0 else False
        return pct, ok


def _rho(tool: EndMill, z_mm: np.ndarray) -> np.ndarray:
    """Radius of the cutter at height ``z_mm`` above its tip (ball, bull or flat end mill)."""
    r, rc = tool.diameter_mm / 2.0, min(float(tool.corner_radius_mm or 0.0), tool.diameter_mm / 2)
    z = np.asarray(z_mm, float)
    if rc <= 0:
        return np.full(z.shape, r)
    zz = np.minimum(z, rc)
    out: np.ndarray = (r - rc) + np.sqrt(np.maximum(rc**2 - (rc - zz) ** 2, 0.0))
    return out


def _arc_tables(
    tool: EndMill, coef: EndMillCoefficients, depths: np.ndarray, fz0: float
) -> tuple[np.ndarray, ...]:
    """A, B (depths, angles, N_PHI, 3): the force over a revolution of the arc (0, angle) at
    each depth, F = fz A + B (0 at depth 0 and at angle 0)."""
    from analysis.forces import EndMillCut, model_for

    model = model_for(tool)
    phi = np.linspace(0.0, 2 * np.pi, N_PHI, endpoint=False)[:, None]
    d = np.repeat(depths, len(ANGLES_DEG))
    ang = np.tile(ANGLES_DEG, len(depths))
    live = d > 0
    f0 = np.zeros((N_PHI, d.size, 3))
    f1 = np.zeros((N_PHI, d.size, 3))
    for fz, out in ((fz0, f0), (2 * fz0, f1)):
        for i in range(0, int(live.sum()), 400):  # bounded memory per call
            idx = np.flatnonzero(live)[i : i + 400]
            cut = EndMillCut(np.full(idx.size, fz), d[idx], 0.0, ang[idx])
            out[:, idx] = model.forces(phi, tool, coef, cut, N_DISCS)
    a = (f1 - f0) / fz0
    b = f0 - fz0 * a
    shape = (len(depths), len(ANGLES_DEG), N_PHI, 3)
    return (np.moveaxis(a, 0, 1).reshape(shape), np.moveaxis(b, 0, 1).reshape(shape))


def _interp(tab: np.ndarray, di: int, ang_deg: float) -> np.ndarray:
    k = min(int(ang_deg), len(ANGLES_DEG) - 2)
    w = ang_deg - k
    out: np.ndarray = tab[di, k] * (1 - w) + tab[di, k + 1] * w
    return out


def _covered(edges: np.ndarray, heights: np.ndarray, level: float) -> list[tuple[float, float]]:
    """X intervals of the uncut block whose height above the cutter's tip reaches ``level``."""
    out: list[tuple[float, float]] = []
    for a, b, h in zip(edges[:-1], edges[1:], heights, strict=True):
        if h >= level - 1e-9:
            if out and abs(out[-1][1] - a) < 1e-9:
                out[-1] = (out[-1][0], float(b))
            else:
                out.append((float(a), float(b)))
    return out


def _arcs_deg(x: float, rho: float, spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Immersion arcs (deg) of a slice of radius ``rho`` centred at ``x`` whose points ahead,
    ``rho sin(phi)``, lie in ``spans``."""
    out = []
    for a, b in spans:
        u0, u1 = max(a - x, 0.0), min(b - x, rho)
        if u1 <= u0:
            continue
        t0 = math.degrees(math.asin(min(u0 / rho, 1.0)))
        t1 = math.degrees(math.asin(min(u1 / rho, 1.0)))
        if t1 >= 90.0 - 1e-9:  # the arc crosses the feed direction: one arc
            out.append((t0, 180.0 - t0))
        else:
            out += [(t0, t1), (180.0 - t1, 180.0 - t0)]
    return out


def load_profile(
    cut: PassGeometry, tool: EndMill, coef: EndMillCoefficients, rpm: float, source: str = ""
) -> LoadProfile:
    """The table of a campaign's cutting pass ``cut`` (:class:`rig.campaign.programs.
    CutProgram`: its stepped block, cutting Z, path Y and X range, feed)."""
    block = cut.block
    edges = np.asarray(block.step_x_mm, float)
    heights = np.asarray(block.step_top_mm, float) - cut.z_cut_mm
    levels = np.unique(heights[heights > 1e-9])
    bounds = [0.0]
    for lev in levels:  # sub-layers: their own radius each
        lo = bounds[-1]
        bounds += list(np.linspace(lo, lev, SUBLAYERS + 1)[1:])
    depths = np.asarray(bounds)
    fz0 = cut.cut_feed_mm_min / (abs(rpm) * tool.flutes)
    a_tab, b_tab = _arc_tables(tool, coef, depths, fz0)
    r = tool.diameter_mm / 2.0
    x = np.arange(cut.x_start_mm, cut.x_end_mm + X_STEP_MM / 2, X_STEP_MM)
    a_x = np.zeros((x.size, N_PHI, 3))
    b_x = np.zeros((x.size, N_PHI, 3))
    for k in range(1, len(depths)):
        spans = _covered(edges, heights, depths[k])
        if not spans:
            continue
        rho = float(_rho(tool, np.array([0.5 * (depths[k - 1] + depths[k])]))[0])
        for i, xi in enumerate(x):
            if xi + r < spans[0][0] or xi > spans[-1][1]:
                continue
            for t0, t1 in _arcs_deg(float(xi), rho, spans):
                for tab, acc in ((a_tab, a_x), (b_tab, b_x)):
                    acc[i] += (_interp(tab, k, t1) - _interp(tab, k, t0)
                               - _interp(tab, k - 1, t1) + _interp(tab, k - 1, t0))  # fmt: skip
    fz = fz0 * PCT_GRID / 100.0
    force = np.empty((x.size, PCT_GRID.size))
    for j, f in enumerate(fz):
        fv = f * a_x[..., :2] + b_x[..., :2]
        force[:, j] = np.hypot(fv[..., 0], fv[..., 1]).mean(axis=1)
    return LoadProfile(x, force, float(cut.cut_feed_mm_min), abs(float(rpm)),
                       float(cut.x_start_mm), float(cut.x_end_mm), source)  # fmt: skip


def campaign_profile(
    campaign: AdaptiveCampaign, test: AdaptiveTest, cut: PassGeometry | None
) -> tuple[LoadProfile | None, str]:
    """(the table of ``test``'s cutting pass ``cut``, the campaign's generated program
    (rig.campaign.programs.CutProgram, None: not known), what it comes from) or (None, why
    there is none: the loop then runs on the measured force alone)."""
    from analysis.forces import ENDMILL

    tool = getattr(campaign, "tool", None)
    coef = getattr(getattr(campaign, "material", None), "endmill", None)
    if cut is None:
        return None, "no stock model: the run's program geometry is not known"
    if tool is None or not ENDMILL.describes(tool) or coef is None:
        return None, "no stock model: the prediction needs an end mill and its coefficients"
    if getattr(test, "feed_mode", "constant") == "post-processed":
        return None, "no prediction for a post-processed program (its F words vary)"
    prog = campaign.spec.program
    if prog.kind not in ("step-depth", "slot"):
        return None, f"no stock model for a {prog.kind!r} program"
    half = tool.diameter_mm / 2.0
    if not (cut.block.y_min_mm <= cut.y_path_mm - half and cut.y_path_mm + half
            <= cut.block.y_max_mm):  # fmt: skip
        return None, "no stock model for a cut narrower than the cutter (slots only)"
    # (the run file's start note carries it: its events hold 200 characters)
    what = f"the {prog.kind} block's stock ({len(cut.block.step_top_mm)} steps)"
    return load_profile(cut, tool, coef, test.spindle_rpm, what), what
