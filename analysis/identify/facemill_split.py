"""Which face-mill coefficients a run set identifies, decided from its design (not from a truth).

Each direction's force is a cutting term (K ~ chip area S) plus an edge term (P ~ edge length l).
At one feed per tooth both grow with the depth alike; what tells them apart is the chip's shape
along the pass (the cutting force follows h = f sin(theta) over the arc, the edge force does not)
and the nose's cusp (S and l have different intercepts). Over a narrow arc the two columns of
the design are nearly parallel, and then the fit holds only their sum, the force per mm of depth
at that feed (K f + P / cos(lead) per direction), not the split.

The measure: the partial correlation rho of each cutting column with its edge column, given the
other four, over all runs, channels and bins of the fitted (mode-filtered) design, and its
inflation 1 / sqrt(1 - rho^2): how much freeing the edge term enlarges the cutting term's
uncertainty, and how much a shape error of the model (a mismatch the least squares spreads over
both columns) moves the cutting coefficient, relative to the error itself. Seed 003's model
matches independent data (rig/sim/facemill_independent.py) to 0.4 % of the peak force, so an
inflation up to :data:`SPLIT_INFLATION_LIMIT` (5) keeps that within 2 %. Measured on that data:
one feed (0.236 mm/tooth, 0.5..3 mm, 50 mm wide, 125 mm cutter) rho 0.9975, inflation 14 (K_T
-1.0 %, K_R +2.2 %, K_A +2.5 %); three feeds (0.1, 0.236, 0.345) rho 0.92, inflation 2.5 (all
within 0.7 %).

K_R and K_A are ratios to K_T: they need their own direction's split and the tangential one. The
edge (ploughing) terms need the split and, beyond it, the feeds to tell an edge force from a size
effect (:mod:`analysis.identify.adequacy`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np

__all__ = ["SPLIT_INFLATION_LIMIT", "Split", "SplitDict", "design_split", "pair_inflation"]

#: The largest inflation of a cutting coefficient by its edge term at which it counts as
#: identified (see the module docstring: 0.4 % model shape error x 5 = 2 %).
SPLIT_INFLATION_LIMIT = 5.0

#: Per direction, the columns (cutting, edge) of analysis.forces.facemill.PARAMETERS
#: (P_T, K_T, P_R, K_R K_T, P_A, K_A K_T).
PAIRS = {"T": (1, 0), "R": (3, 2), "A": (5, 4)}

#: Per summary coefficient, the directions whose split it needs, and whether it is an edge term.
NEEDS = {
    "K_T_n_mm2": (("T",), False), "K_R": (("T", "R"), False), "K_A": (("T", "A"), False),
    "P_T_n_mm": (("T",), True), "P_R_n_mm": (("R",), True), "P_A_n_mm": (("A",), True),
}  # fmt: skip

#: Per cutting coefficient, the force per mm of depth (above the cusp) that one feed f holds.
PER_DEPTH = {"K_T_n_mm2": "K_T f + P_T", "K_R": "K_R K_T f + P_R", "K_A": "K_A K_T f + P_A"}

#: The status of an edge term the design splits but the feeds cannot tell from a size effect.
SIZE_EFFECT = "not identified: the runs do not separate edge forces from a size effect " \
    "(see model adequacy)"  # fmt: skip


class SplitDict(TypedDict):
    """:meth:`Split.as_dict` (the JSON result's ``split``)."""

    correlation: dict[str, float]
    inflation: dict[str, float]
    inflation_limit: float
    feeds_mm: list[float]
    status: dict[str, str]


@dataclass(frozen=True)
class Split:
    """Per direction T, R, A: ``correlation`` (partial, cutting with edge column) and
    ``inflation``; per coefficient (the fit's summary names) ``status`` ('identified',
    'identified as force per depth only (one feed): ...' or 'not identified: ...') and
    ``identified`` (True only for 'identified'); ``feeds_mm`` the distinct feeds."""

    correlation: dict[str, float]
    inflation: dict[str, float]
    status: dict[str, str]
    feeds_mm: tuple[float, ...] = ()
    limit: float = SPLIT_INFLATION_LIMIT
    identified: dict[str, bool] = field(default_factory=dict)

    def as_dict(self) -> SplitDict:
        return {"correlation": self.correlation, "inflation": self.inflation,
                "inflation_limit": self.limit, "feeds_mm": list(self.feeds_mm),
                "status": self.status}  # fmt: skip

    def clause(self) -> str:
        """The fit message's clause for what the design does not split ('' when it splits all;
        the size-effect verdict has its own clause)."""
        per_depth = [_short(k) for k, s in self.status.items() if s.startswith("identified as")]
        unsplit = [_short(k) for k, s in self.status.items() if "does not split" in s]
        if not per_depth and not unsplit:
            return ""
        out = ""
        if per_depth:
            out += (
                f"; {', '.join(per_depth)} identified as force per depth only (one feed: "
                "K f + P / cos(lead) per direction), not split from the edge terms"
            )
        if unsplit:
            out += f"; {', '.join(unsplit)} not identified: the design does not split them"
        worst = ", ".join(f"{d} {self.inflation[d]:.1f}" for d in PAIRS)
        rho = ", ".join(f"{self.correlation[d]:.4f}" for d in PAIRS)
        return out + f" (cutting/edge column inflation {worst}, limit {self.limit:g}; " \
            f"correlation {rho})"  # fmt: skip


def _short(name: str) -> str:
    return name.replace("_n_mm2", "").replace("_n_mm", "")


def pair_inflation(X: np.ndarray) -> tuple[dict[str, float], dict[str, float]]:
    """(partial correlation, inflation) per direction of the design X (points, 6)."""
    norm = np.linalg.norm(X, axis=0)
    Xs = X / np.where(norm > 0, norm, 1.0)
    prec = np.linalg.pinv(Xs.T @ Xs)
    corr, infl = {}, {}
    for d, (c, e) in PAIRS.items():
        den = math.sqrt(max(prec[c, c] * prec[e, e], 0.0))
        rho = float(-prec[c, e] / den) if den > 0 else 1.0
        corr[d] = rho
        infl[d] = 1.0 / math.sqrt(max(1.0 - rho * rho, 1e-300))
    return corr, infl


def design_split(
    X: np.ndarray, fz_mm: Sequence[float], edge_supported: bool, lead_deg: float,
    limit: float = SPLIT_INFLATION_LIMIT,
) -> Split:  # fmt: skip
    """The :class:`Split` of a face-mill design ``X`` (points, 6) over runs at feeds ``fz_mm``;
    ``edge_supported``: the adequacy check supports edge forces over a size effect."""
    corr, infl = pair_inflation(X)
    feeds = tuple(sorted({round(float(f), 9) for f in fz_mm}))
    status: dict[str, str] = {}
    for name, (dirs, edge) in NEEDS.items():
        bad = [d for d in dirs if infl[d] > limit]
        if not bad:
            status[name] = SIZE_EFFECT if edge and not edge_supported else "identified"
            continue
        why = "; ".join(f"{d}: cutting and edge columns correlate {corr[d]:.4f}, inflation "
                        f"{infl[d]:.1f} > {limit:g}" for d in bad)  # fmt: skip
        if len(feeds) == 1 and not edge:
            status[name] = (
                f"identified as force per depth only (one feed): {PER_DEPTH[name]} / "
                f"cos({lead_deg:g} deg) at f = {feeds[0]:g} mm/tooth, not its split from the "
                f"edge term ({why})"
            )
        else:
            one = " (one feed: only the chip's shape along the pass and the nose's cusp split " \
                "them)" if len(feeds) == 1 else ""  # fmt: skip
            status[name] = f"not identified: the design does not split cutting from edge " \
                f"forces ({why}){one}"  # fmt: skip
    ok = {k: v == "identified" for k, v in status.items()}
    return Split(corr, infl, status, feeds, limit, ok)
