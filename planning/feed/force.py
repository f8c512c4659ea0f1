"""Engagement of each cut piece from the Z-map, and its predicted forces at any feed
(analysis.forces.endmill): the force column and ``force_limit_n`` of ``plan feed`` (a step beyond
seed 001), and the force, deflection and power of ``plan check`` (:mod:`planning.limits`).

Engagement: the arcs of the cutter's periphery that met stock at each piece's middle before it
cut, each with its depth (``Simulation.piece_arcs``, the Z-map's 2 deg samples); where there are
none (a plunge, a ball end mill, a sliver between grid points), one strip of width removed
cross-section / depth at the cutter's edge in down milling (M3), whose chip is thickest. M4
mirrors the arcs (the cutter turns the other way).

Forces come from tables over a tooth period per distinct (depth, end angle): the edge forces add,
so a piece's force is the sum of its arcs', and an arc (e, x) is the arc (0, x) less (0, e).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from analysis.config import EndMill, EndMillCoefficients
from planning.stock import ARC_STEP_RAD, MAX_ARCS, Simulation

N_PHI = 36  # tooth-period samples of the peak force
N_DISCS = 12  # axial discs of the force tables (the twin slices its cutter in 12 too)
ENGAGEMENT_STEP = 0.02  # relative rounding (up) of the depth for the force tables
MAX_CACHED = 50_000  # force tables kept per tool and material (1.7 kB each)
_Tables = tuple[NDArray[np.float64], NDArray[np.float64]]
_TABLES: dict[tuple[str, str], dict[tuple[int, int], _Tables]] = {}


def _arcs(
    sim: Simulation,
    c: NDArray[np.bool_],
    depth_mm: NDArray[np.float64],
    ae_mm: NDArray[np.float64],
    d_mm: float,
) -> NDArray[np.float64]:
    """Engaged arcs per cutting piece, (k, MAX_ARCS, 3): entry rad, exit rad, depth mm (NaN
    rows: no more arcs); the strip where the Z-map found none (module docstring)."""
    from analysis.forces.endmill import immersion_angles

    arcs = np.full((len(ae_mm), MAX_ARCS, 3), np.nan)
    arcs[:, 0, 0], arcs[:, 0, 1] = immersion_angles(ae_mm, d_mm, "down")
    arcs[:, 0, 2] = depth_mm
    if sim.piece_arcs is not None:
        found = sim.piece_arcs[c].reshape(-1, MAX_ARCS, 3).astype(float)
        arcs = np.where(np.isfinite(found[:, :1, :1]), found, arcs)
    m4 = sim.motion.spindle_rpm[sim.piece_segment][c] < 0
    arcs[m4, :, :2] = np.pi - arcs[m4][..., 1::-1]
    return arcs


class ForceModel:
    """Engagement of each cutting piece of a simulation (``track_depth``) and its forces at any
    feed. ``cutting`` (default: pieces that remove stock with the spindle turning) selects the
    pieces; per-piece arrays hold the cutting pieces only."""

    def __init__(
        self,
        tool: EndMill,
        coef: EndMillCoefficients,
        sim: Simulation,
        rpm: NDArray[np.float64],
        cutting: NDArray[np.bool_] | None = None,
    ) -> None:
        self.tool, self.coef = tool, coef
        length = sim.piece_length_mm
        if cutting is None:
            cutting = (sim.piece_removed_mm3 > 1e-9) & (length > 0) & (rpm > 0)
        self.cutting = c = cutting
        self.rpm = rpm[c]
        # deeper than the flutes is the shank rubbing: the force model stops at the flutes
        self.depth_mm = np.clip(sim.piece_depth_mm[c], 1e-3, tool.flute_length_mm)
        self.area_mm2 = sim.piece_removed_mm3[c] / length[c]  # removed per mm of path
        self.ae_mm = np.clip(self.area_mm2 / self.depth_mm, 1e-3, tool.diameter_mm)
        self.arcs = _arcs(sim, c, self.depth_mm, self.ae_mm, tool.diameter_mm)
        entry, exit_ = self.arcs[..., 0], self.arcs[..., 1]
        depth = np.clip(self.arcs[..., 2], 1e-3, tool.flute_length_mm)  # (NaN: no arc)
        self.depth_sweep_mm = np.nansum(depth * (exit_ - entry), axis=1)  # mm rad
        # the largest chip is fz sin(phi) at the arcs' point nearest pi/2
        self.chip_factor = np.nanmax(np.sin(np.clip(np.pi / 2, entry, exit_)), axis=1)
        # tables per distinct (depth, end angle), the depth rounded up to ENGAGEMENT_STEP
        # (relative) and the arc widened to the Z-map's 2 deg grid (on the safe side)
        step = math.log1p(ENGAGEMENT_STEP)
        dk = np.ceil(np.log(depth) / step - 1e-9)
        ends = np.stack([np.stack([dk, np.ceil(exit_ / ARC_STEP_RAD - 1e-3)], -1),
                         np.stack([dk, np.floor(entry / ARC_STEP_RAD + 1e-3)], -1)])  # fmt: skip
        ends = ends.reshape(-1, 2)  # (2 k MAX_ARCS, 2): the exits, then the entries
        has = np.isfinite(ends).all(1) & (ends[:, 1] > 0)  # an arc from 0 adds nothing
        uniq, inv = np.unique(ends[has], axis=0, return_inverse=True)
        self._keys = [tuple(k) for k in uniq.astype(np.int64).tolist()]
        table = np.full(len(ends), len(uniq))  # the last table is no force
        table[has] = inv.ravel()
        self._exit_table, self._entry_table = table.reshape(2, -1, MAX_ARCS)
        self._tables: _Tables | None = None

    def _fz(self, feed_mm_min: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.maximum(feed_mm_min, 1e-9) / (self.tool.flutes * self.rpm)

    def _force_tables(self) -> _Tables:
        """Force over a tooth period per distinct engagement, (m + 1, N_PHI, 3) each (the last:
        no arc), as F(fz) = fz A + B: the edge model is affine in the chip thickness, which is
        affine in fz (fz sin(phi), plus runout). Each (depth, end angle) is evaluated once per
        tool and material in the process (``plan rough --limit`` checks the same cuts again)."""
        if self._tables is None:
            cache = _TABLES.setdefault(
                (self.tool.model_dump_json(), self.coef.model_dump_json()), {}
            )
            missing = [k for k in self._keys if k not in cache]
            if len(cache) + len(missing) > MAX_CACHED:
                cache.clear()
                missing = list(self._keys)
            for i in range(0, len(missing), 1000):
                keys = missing[i : i + 1000]
                for k, a, b in zip(keys, *self._evaluate(np.array(keys, float)), strict=True):
                    cache[k] = (a, b)
            none = np.zeros((N_PHI, 3))
            self._tables = (np.stack([cache[k][0] for k in self._keys] + [none]),
                            np.stack([cache[k][1] for k in self._keys] + [none]))  # fmt: skip
        return self._tables

    def _evaluate(self, keys: NDArray[np.int64]) -> _Tables:
        """A and B (k, N_PHI, 3) of the arcs from 0 for keys (k, 2): depth step, end index."""
        from analysis.forces import EndMillCut, model_for

        phi = np.linspace(0.0, 2 * np.pi / self.tool.flutes, N_PHI, endpoint=False)[:, None]
        depth = np.minimum(np.exp(keys[:, 0] * math.log1p(ENGAGEMENT_STEP)),
                           self.tool.flute_length_mm)  # fmt: skip
        end_deg = np.degrees(keys[:, 1] * ARC_STEP_RAD)
        model = model_for(self.tool)
        f0, f1 = (model.forces(phi, self.tool, self.coef, EndMillCut(fz, depth, 0.0, end_deg),
                               N_DISCS) for fz in (0.1, 0.2))  # fmt: skip
        # two feeds where every tooth in the cut has a chip (at fz = 0 none is cutting)
        a = np.moveaxis(f1 - f0, 0, 1) / 0.1
        return a, np.moveaxis(f0, 0, 1) - 0.1 * a

    def forces_n(
        self, fz: NDArray[np.float64], mean: bool = False
    ) -> tuple[NDArray[np.float64], ...]:
        """(peak resultant, peak lateral[, mean resultant over a tooth period]) force per
        cutting piece at feeds per tooth ``fz``, N."""
        a_tab, b_tab = self._force_tables()
        force = np.empty(len(fz))
        lateral = np.empty(len(fz))
        mean_n = np.empty(len(fz))
        for i in range(0, len(fz), 2000):
            sl = slice(i, i + 2000)
            x, e = self._exit_table[sl], self._entry_table[sl]
            a = a_tab[x].sum(1) - a_tab[e].sum(1)
            f = fz[sl, None, None] * a + b_tab[x].sum(1) - b_tab[e].sum(1)
            resultant = np.linalg.norm(f, axis=-1)
            force[sl] = resultant.max(1)
            mean_n[sl] = resultant.mean(1)
            lateral[sl] = np.linalg.norm(f[..., :2], axis=-1).max(1)
        return (force, lateral, mean_n) if mean else (force, lateral)

    def force_n(self, feed_mm_min: NDArray[np.float64]) -> NDArray[np.float64]:
        """Peak force of every piece at the given feeds (all pieces), N (NaN where not
        cutting)."""
        out = np.full(len(self.cutting), np.nan)
        if self.cutting.any():
            out[self.cutting] = self.forces_n(self._fz(feed_mm_min[self.cutting]))[0]
        return out

    def feed_cap(self, limit_n: float) -> NDArray[np.float64]:
        """Feed of every piece at which its peak force reaches ``limit_n``, mm/min (inf where
        none: not cutting, or never that high; 0: above it at the smallest feed)."""
        cap = np.full(len(self.cutting), np.inf)
        if self.cutting.any():
            cap[self.cutting] = self.force_cap_fz(limit_n, None) * self.tool.flutes * self.rpm
        return cap

    def force_cap_fz(self, f_lim: float | None, d_lim: float | None) -> NDArray[np.float64]:
        """Largest fz per cutting piece with peak force <= f_lim and peak lateral force <=
        d_lim, by bisection in log(fz) (the peak forces grow with fz), from below; 0 where even
        1e-5 mm is too much, inf where 2 mm is not."""

        def ok(fz: NDArray[np.float64]) -> NDArray[np.float64]:
            force, lateral = self.forces_n(fz)
            good = np.ones(len(fz), bool)
            if f_lim is not None:
                good &= force <= f_lim
            if d_lim is not None:
                good &= lateral <= d_lim
            return good

        lo = np.full(len(self.rpm), math.log(1e-5))
        hi = np.full(len(self.rpm), math.log(2.0))
        ok_lo = ok(np.exp(lo))
        ok_hi = ok(np.exp(hi))
        for _ in range(18):  # 18 halvings of log(2e5): fz within 0.005 %
            mid = 0.5 * (lo + hi)
            good = ok(np.exp(mid))
            lo, hi = np.where(good, mid, lo), np.where(good, hi, mid)
        return np.where(ok_hi, np.inf, np.where(ok_lo, np.exp(lo), 0.0))
