"""The per-block check of a program against the limits (:mod:`planning.limits.model`).

The program is machined on a Z-map as ``plan feed`` and ``plan simulate`` do
(:func:`planning.stock.simulate_motion`, pieces of at most ``piece_mm``), and each cutting piece's
engagement and forces come from :class:`planning.feed.ForceModel` (the arcs of the cutter that
met stock, each with its depth). The stability check uses the piece's deepest height drop and
its removed cross-section / depth as the width. Per piece, at its feed and spindle speed:

* force: the largest resultant over a tooth period, and the largest lateral (XY) force for the
  deflection, of :func:`analysis.forces.endmill_forces` (the material's end-mill coefficients);
* power P = F_t v and torque T = F_t D / 2 with the mean tangential force F_t summed over the
  teeth in closed form: F_t v = K_tc Q + K_te v N sum(a (phi_ex - phi_st)) / (2 pi) over the
  arcs, Q the removal rate from the Z-map (mm^3/s);
* chip: the largest chip thickness fz sin(phi) over the arcs;
* stability: the axial depth against the chatter-free depth at that speed.

A block's value for a limit is its worst piece's (highest value / allowed). Every feed-driven
quantity grows with the feed, so each piece also gets the feed at which it meets every limit
(``feed_cap_mm_min``); depth (stability) cannot be cured by feed. The table also gives each
block's time-mean resultant force (``force_mean``, air pieces 0), what a dynamometer record
averaged over the block reads.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from analysis.config import EndMill, EndMillCoefficients
from analysis.validation import JsonObject, JsonValue
from planning.errors import PlanningError
from planning.feed import ForceModel
from planning.limits.model import (
    LIMIT_UNITS,
    Limits,
    cutting_speed_mm_s,
    modal_depth_limit_mm,
)
from planning.nc import Motion
from planning.stock import Simulation, ZMap, simulate_motion

if TYPE_CHECKING:
    import pandas as pd

PIECE_MM = 2.5  # pieces of the check's Z-map run, mm (plan feed's default: min piece / 2)
FEED_LIMITS = ("force", "deflection", "power", "torque", "chip")  # cured by a lower feed
TOL = 1e-6  # relative: a value this close to its limit holds


class Pieces(ForceModel):
    """Engagement and forces of each cutting piece (:class:`planning.feed.ForceModel`), and
    its quantities against the limits at any feed."""

    def __init__(
        self,
        tool: EndMill,
        coef: EndMillCoefficients,
        limits: Limits,
        sim: Simulation,
        rpm: NDArray[np.float64],
    ) -> None:
        feed_move = sim.motion.is_feed[sim.piece_segment]  # a rapid that cuts is a crash
        cutting = (sim.piece_removed_mm3 > 1e-9) & (sim.piece_length_mm > 0) & (rpm > 0)
        super().__init__(tool, coef, sim, rpm, cutting & feed_move)
        self.limits = limits
        self.depth_allowed_mm = np.full(len(self.rpm), np.inf)
        if limits.lobes is not None:
            self.depth_allowed_mm = limits.lobes.depth_mm(self.rpm)
        elif limits.stability_modes and len(self.rpm):
            imm = self.ae_mm / tool.diameter_mm
            self.depth_allowed_mm = modal_depth_limit_mm(tool, coef, self.rpm, imm)
        self.depth_allowed_mm = self.depth_allowed_mm * limits.stability_margin

    def _power_parts_kw(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Power = a feed + b, kW: a from K_tc x removal rate, b from the edge force."""
        a = self.coef.Ktc_n_mm2 * self.area_mm2 / 60.0 * 1e-6  # per mm/min of feed
        v = cutting_speed_mm_s(self.tool.diameter_mm, self.rpm)
        # edge length in the cut, on average over a turn
        edge_mm = self.tool.flutes * self.depth_sweep_mm / (2 * np.pi)
        edge_n = self.coef.Kte_n_mm * edge_mm
        return a, edge_n * v * 1e-6

    def _torque_per_kw(self) -> NDArray[np.float64]:
        return 1e3 * 60.0 / (2 * np.pi * self.rpm)  # T (N m) per kW at this speed

    def quantities(self, feed_mm_min: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Value per limit, one per cutting piece (feeds of the cutting pieces)."""
        fz = self._fz(feed_mm_min)
        force, lateral, mean_n = self.forces_n(fz, mean=True)
        a, b = self._power_parts_kw()
        power = a * feed_mm_min + b
        out = {"force": force, "power": power, "torque": power * self._torque_per_kw(),
               "chip": fz * self.chip_factor, "stability": self.depth_mm}  # fmt: skip
        if self.limits.stiffness_n_mm is not None:
            out["deflection"] = lateral / self.limits.stiffness_n_mm
        out["lateral_force"] = lateral
        out["mean_force"] = mean_n
        return out

    def allowed(self) -> dict[str, float | NDArray[np.float64]]:
        """Allowed value per limit that is on (scalars, or per piece for stability)."""
        lim = self.limits
        out: dict[str, float | NDArray[np.float64] | None]
        out = {"force": lim.force_n, "deflection": lim.deflection_mm,
                               "power": lim.power_kw, "torque": lim.torque_nm,
                               "chip": lim.chip_mm}  # fmt: skip
        on = {k: v for k, v in out.items() if v is not None}
        if lim.has_stability:
            on["stability"] = self.depth_allowed_mm
        return on

    def feed_cap_mm_min(self) -> NDArray[np.float64]:
        """Highest feed per cutting piece within every feed-driven limit, mm/min (inf: none;
        0: not even the smallest feed)."""
        lim = self.limits
        k = len(self.rpm)
        cap = np.full(k, np.inf)
        per_fz = self.tool.flutes * self.rpm  # mm/min per mm/tooth
        if lim.chip_mm is not None:
            cap = np.minimum(cap, lim.chip_mm / self.chip_factor * per_fz)
        a, b = self._power_parts_kw()
        for p_lim in (lim.power_kw, None if lim.torque_nm is None else
                      lim.torque_nm / self._torque_per_kw()):  # fmt: skip
            if p_lim is not None:
                cap = np.minimum(cap, np.maximum(p_lim - b, 0.0) / a)
        f_lim = lim.force_n
        d_lim = None
        if lim.deflection_mm is not None and lim.stiffness_n_mm is not None:
            d_lim = lim.deflection_mm * lim.stiffness_n_mm  # lateral force limit, N
        if (f_lim is not None or d_lim is not None) and k:
            cap = np.minimum(cap, self.force_cap_fz(f_lim, d_lim) * per_fz)
        return cap


@dataclass(frozen=True)
class CheckResult:
    """Per cutting block: the worst value of each quantity; the violations; the pieces."""

    blocks: pd.DataFrame  # one row per cutting block
    violations: list[dict[str, Any]]  # JSON rows (block, line, limit, value, allowed, ...)
    limits: Limits
    pieces: Pieces
    simulation: Simulation
    piece_values: dict[str, NDArray[np.float64]] = field(repr=False, default_factory=dict)

    def block_caps(self) -> dict[int, float]:
        """Block -> the highest feed its pieces allow (blocks with a finite cap only)."""
        cap = self.pieces.feed_cap_mm_min()
        blk = self.piece_block
        out = np.full(int(blk.max(initial=-1)) + 1, np.inf)
        np.minimum.at(out, blk, cap)
        return {int(b): float(out[b]) for b in np.unique(blk) if math.isfinite(out[b])}

    @property
    def piece_block(self) -> NDArray[np.int_]:
        sim = self.simulation
        out: NDArray[np.int_] = sim.motion.block[sim.piece_segment][self.pieces.cutting]
        return out

    def summary(self) -> JsonObject:
        worst: JsonObject = {}
        for k in LIMIT_UNITS:
            col = f"{k}_ratio"
            if col in self.blocks and len(self.blocks) and self.blocks[col].notna().any():
                # idxmax of the default index: the first largest ratio, NaN skipped
                row = self.blocks.iloc[int(np.nanargmax(self.blocks[col].to_numpy(float)))]
                worst[k] = {"block": int(row["block"]), "value": float(row[k]),
                            "allowed": float(row[f"{k}_allowed"]),
                            "margin_pct": round(100 * (1 - float(row[col])), 2)}  # fmt: skip
        unchecked: list[JsonValue] = [{"limit": k, "reason": r} for k, r in self.limits.unchecked]
        if not len(self.blocks):
            unchecked.append({"limit": "all", "reason": "no block removes stock"})
        return {
            "verdict": verdict(self.violations, unchecked),
            "violations": list(self.violations),
            "unchecked": unchecked,
            "limits": self.limits.to_json(),
            "cutting_blocks": int(len(self.blocks)),
            "worst": worst,
        }


def verdict(violations: Sequence[object], unchecked: Sequence[object]) -> str:
    """The verdict: "violations" if any block breaks a limit; else "unchecked" if a limit could
    not be checked (a check that could not run is never "within"); else "within"."""
    if violations:
        return "violations"
    return "unchecked" if unchecked else "within"


def evaluate(
    sim: Simulation,
    tool: EndMill,
    coef: EndMillCoefficients,
    limits: Limits,
    spindle_rpm: float | None = None,
    file: str = "",
) -> CheckResult:
    """The check of a simulated program (``sim`` with ``track_depth``) at its own feeds."""
    import pandas as pd

    motion = sim.motion
    seg = sim.piece_segment
    rpm = np.abs(motion.spindle_rpm[seg]).astype(float)
    if spindle_rpm:
        rpm = np.where(rpm > 0, rpm, spindle_rpm)
    cutting = (sim.piece_removed_mm3 > 1e-9) & motion.is_feed[seg]
    if np.any(cutting & (rpm <= 0)):
        b = int(motion.block[seg[np.argmax(cutting & (rpm <= 0))]])
        raise PlanningError(
            f"{file}:{b + 1}: the block cuts with the spindle stopped (no S/M3): give the "
            "spindle speed (--spindle RPM)"
        )
    pieces = Pieces(tool, coef, limits, sim, rpm)
    c = pieces.cutting
    feed = motion.feed_mm_min[seg][c]
    values = pieces.quantities(feed)
    allowed = pieces.allowed()
    blk = motion.block[seg][c]
    blocks, inv = np.unique(blk, return_inverse=True)
    cols: dict[str, Any] = {"block": blocks, "line": blocks + 1}
    feed_b = np.full(len(blocks), np.inf)
    np.minimum.at(feed_b, inv, feed)
    rpm_b = np.zeros(len(blocks))
    np.maximum.at(rpm_b, inv, pieces.rpm)
    cols |= {"feed_mm_min": feed_b, "spindle_rpm": rpm_b}
    for name, unit_col in (("depth", pieces.depth_mm), ("ae", pieces.ae_mm)):
        v = np.zeros(len(blocks))
        np.maximum.at(v, inv, unit_col)
        cols[f"{name}_mm"] = v
    cols["force_mean"] = _block_mean(sim, c, values["mean_force"], blocks)
    violations: list[dict[str, Any]] = []
    for k in LIMIT_UNITS:
        if k not in values:
            continue
        v = values[k]
        if k in allowed:
            al = np.broadcast_to(np.asarray(allowed[k], float), v.shape)
            ratio = np.where(np.isfinite(al), v / al, 0.0)
            # the worst piece of each block: sort by ratio, keep the last per block
            order = np.lexsort((ratio, inv))
            last = order[np.r_[inv[order][1:] != inv[order][:-1], True]] if len(v) else order
            cols[k], cols[f"{k}_allowed"], cols[f"{k}_ratio"] = v[last], al[last], ratio[last]
            bad = np.nonzero(ratio[last] > 1 + TOL)[0]
            for i in bad.tolist():
                violations.append({
                    "block": int(blocks[i]), "line": int(blocks[i]) + 1, "limit": k,
                    "value": round(float(v[last][i]), 6),
                    "allowed": round(float(al[last][i]), 6), "unit": LIMIT_UNITS[k],
                    "margin_pct": round(100 * (1 - float(ratio[last][i])), 2),
                })  # fmt: skip
        else:
            w = np.zeros(len(blocks))
            np.maximum.at(w, inv, v)
            cols[k] = w
    violations.sort(key=lambda d: (d["block"], d["limit"]))
    return CheckResult(pd.DataFrame(cols), violations, limits, pieces, sim, values)


def _block_mean(
    sim: Simulation,
    cutting: NDArray[np.bool_],
    value: NDArray[np.float64],
    blocks: NDArray[np.int_],
) -> NDArray[np.float64]:
    """Time mean of a cutting piece's ``value`` over each block's feed pieces (0 in the air),
    as a force record reduced per executing block reads it."""
    motion = sim.motion
    seg = sim.piece_segment
    feed = motion.is_feed[seg] & (sim.piece_length_mm > 0)
    dt = np.where(feed, sim.piece_length_mm / np.maximum(motion.feed_mm_min[seg], 1e-9), 0.0)
    v = np.zeros(len(seg))
    v[cutting] = value
    k = np.searchsorted(blocks, motion.block[seg]).clip(0, len(blocks) - 1)
    mine = feed & (blocks[k] == motion.block[seg]) if len(blocks) else feed & False
    num, den = np.zeros(len(blocks)), np.zeros(len(blocks))
    np.add.at(num, k[mine], (v * dt)[mine])
    np.add.at(den, k[mine], dt[mine])
    return num / np.maximum(den, 1e-12)


def check_motion(
    motion: Motion,
    tool: EndMill,
    coef: EndMillCoefficients,
    limits: Limits,
    stock: ZMap,
    *,
    spindle_rpm: float | None = None,
    piece_mm: float = PIECE_MM,
    file: str = "",
    progress: Callable[[int, int], None] | None = None,
) -> CheckResult:
    """Machine ``motion`` on ``stock`` (lowered in place) and check every cutting block."""
    sim = simulate_motion(stock, tool, motion, piece_mm=piece_mm, check_holder=False,
                          track_depth=True, progress=progress)  # fmt: skip
    return evaluate(sim, tool, coef, limits, spindle_rpm, file)
