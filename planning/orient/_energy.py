"""The modified potential energy of seed 002 eq 7 and its gradient in (alpha, beta).

The part surfaces carry charges at points of a mesh (spacing ``charge_spacing_mm``, each with the
area it stands for as its charge, mm^2). The tool system's charge sits on its surfaces of
revolution; for eq 7's pair term f(d) = 1/d (0 < d < R_t), 0 (d >= R_t) -- d the distance of a
part charge from the tool axis, R_t the tool radius at that height -- the tool side integrates to
one term per part charge, so

    U(alpha, beta) = sum over part charges inside the tool system of  w_j / d_j.

U is exactly 0 when nothing collides (seed 002's point of modifying the energy). "Inside" uses
the exact solid: for the cutter a charge counts when it lies deeper than the gouge tolerance (so
the touching CC neighbourhood costs nothing), for holder and spindle nose when it is closer than
the clearance. A cKDTree over the part charges, queried with spheres that cover the tool system,
keeps the sum to the near pairs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from planning.orient.tool import (
    ToolSystem,
    cutter_position,
    meridian,
    tool_axis,
    tool_axis_grad,
)

RHO_MIN_MM = 0.05  # keeps 1/d finite for a charge on the axis


@dataclass(frozen=True)
class Charges:
    """Part charges: points (N, 3) mm, charge w (N,) mm^2, surface index (N,), and their tree."""

    points: np.ndarray
    weight_mm2: np.ndarray
    surface: np.ndarray
    tree: cKDTree

    @classmethod
    def from_points(
        cls, points: np.ndarray, weight_mm2: np.ndarray, surface: np.ndarray
    ) -> Charges:
        return cls(points, weight_mm2, surface, cKDTree(points))


@dataclass(frozen=True)
class Site:
    """One CC point: position p, unit normal n, frame b, f (each (3,)), mm."""

    p: np.ndarray
    n: np.ndarray
    b: np.ndarray
    f: np.ndarray


def place(tool: ToolSystem, site: Site, alpha: float, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """Tool axis (3,), tip (3,) mm for one orientation (rad)."""
    u = tool_axis(np.asarray(alpha), np.asarray(beta), site.b, site.f, site.n)
    tip, _ = cutter_position(site.p, site.n, u, tool.R_mm, tool.r_mm)
    return u, tip


def near(
    tree: cKDTree, tool: ToolSystem, tip: np.ndarray, u: np.ndarray, pad_mm: float
) -> np.ndarray:
    """Indices of tree points within reach of the tool system placed at tip along u."""
    z, rad = tool.stations()
    centres = tip + z[:, None] * u
    hits = tree.query_ball_point(centres, rad + pad_mm, return_sorted=False)
    # A set union is cheaper than np.unique for the few hundred indices involved.
    return np.fromiter(set().union(*hits), dtype=np.intp)


def inside_mask(
    tool: ToolSystem, sd: np.ndarray, which: np.ndarray, tol_mm: float, clearance_mm: float
) -> npt.NDArray[np.bool_]:
    """True where a point counts as colliding with the tool system (see module docstring)."""
    return np.where(which == 0, sd < -tol_mm, sd < clearance_mm)


def energy(
    tool: ToolSystem,
    charges: Charges,
    site: Site,
    alpha: float,
    beta: float,
    tol_mm: float,
    clearance_mm: float,
    grad: bool = False,
) -> tuple[float, np.ndarray]:
    """U (mm, charge area / distance) and dU/d(alpha, beta) (per rad, zeros unless ``grad``)."""
    u, tip = place(tool, site, alpha, beta)
    idx = near(charges.tree, tool, tip, u, clearance_mm + tol_mm)
    g = np.zeros(2)
    if idx.size == 0:
        return 0.0, g
    P = charges.points[idx]
    rho, z = meridian(P, tip, u)
    sd, which = tool.signed_distance(rho, z)
    hit = inside_mask(tool, sd, which, tol_mm, clearance_mm)
    if not hit.any():
        return 0.0, g
    w = charges.weight_mm2[idx][hit]
    rho_h = np.maximum(rho[hit], RHO_MIN_MM)
    U = float((w / rho_h).sum())
    if grad:
        # d rho / d theta by the chain rule; the tip's own motion by a central difference.
        d = P[hit] - tip
        zh = z[hit]
        du_da, du_db = tool_axis_grad(np.asarray(alpha), np.asarray(beta), site.b, site.f, site.n)
        h = 1e-6
        for k, (du, da, db) in enumerate(((du_da, h, 0.0), (du_db, 0.0, h))):
            _, t1 = place(tool, site, alpha + da, beta + db)
            _, t0 = place(tool, site, alpha - da, beta - db)
            dtip = (t1 - t0) / (2 * h)
            dz = -(dtip @ u) + d @ du
            drho = (-(d @ dtip) - zh * dz) / rho_h
            g[k] = float((-w / rho_h**2 * drho).sum())
    return U, g
