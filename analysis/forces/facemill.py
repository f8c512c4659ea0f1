"""Face-milling forces with ploughing (seed 003, Kwon & Kim), vectorised over rotation and cut.

Model (per insert, seed 003 eqs 3-4 plus an axial pair)::

    F_T' = P_T l + K_T S
    F_R' = P_R l + K_R K_T S          (K_R is a ratio: the seed prints N/mm^2, eq 4 makes it 1)
    F_A' = P_A l + K_A K_T S

with S the chip area on the rake face (eqs 11-13) and l the engaged edge length (eq 16), both from
the chip thickness CI(theta) (eq 1) and the local depth of cut. The insert forces are turned into
the tool's T, R, A axes with [M]^-1 (eqs 8-9), into the tool's X, Y, Z with eq 14 and into the
dynamometer's X', Y', Z' with eq 2.

Conventions (all in one place so the simulated rig and the identification agree):

- ``theta`` is the insert's angular position, radians, measured from the dynamometer's +Y' axis
  towards +X' (the feed direction); the cutter turns clockwise seen from above (M3) so theta grows
  with time; CI(theta) = f sin(theta) > 0 for 0 < theta < pi (the half ahead of the cutter).
- Forces are those the tool exerts on the workpiece, in the dynamometer axes X' (feed), Y' and
  Z' (up), newtons. With eq 14 and eq 2 combined: X' = F_T cos + F_R sin, Y' = -F_T sin + F_R cos,
  Z' = F_A. T points along the insert's cutting velocity, R radially out, A up.
- The workpiece (width ``width_mm`` across the feed, its centre line ``center_offset_mm`` along
  +Y' from the cutter axis) is cut where Y'_insert = R cos(theta) lies inside it.
- A cutter rotation angle ``theta`` places insert k at theta + a_k (``insert_angles_deg``, default
  evenly spaced); with several inserts, spindle eccentricity (``runout_mm`` of the tool, radial, as
  an amplitude R + e cos(a_k)) changes each insert's chip by its radius minus the radius of the
  insert that passed before it.
- Spindle tilt (optional; seed 003 3.3 measured 0.56 deg and neglected it): the tool axis leans by
  ``tilt_deg`` so that the insert path is lowest at ``tilt_low_deg``; the local depth is
  d - R sin(tilt) (1 - cos(theta - theta_low)), floored at 0.

Public API (shapes: ``theta_rad`` any shape ``(...)``; condition arguments broadcast with it):

- ``projected_angles``, ``rotation_inverse`` (eqs 5-9), ``chip_thickness`` (eq 1),
  ``tool_from_insert_axes`` (eq 14), ``DYNO_FROM_TOOL`` (eq 2), ``engagement_angles``,
  ``chip_area_and_edge_length`` (S, l; eqs 11-13, 16);
- ``FaceMillCut`` (conditions), ``facemill_design`` (regressors, (..., 3, 6)), ``facemill_forces``
  ((..., 3) N), ``insert_loads`` (per insert S, l, F_T'R'A'), ``PARAMETERS``,
  ``coefficient_vector``/``coefficients_from_vector``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.config import FaceMill, FaceMillCoefficients
from analysis.errors import AnalysisError
from analysis.forces._facemill_geometry import (
    EdgeTable,
    chip_section,
    edge_table,
    partial_fraction,
    projected_angles,
    rotation_inverse,
)

__all__ = [
    "DYNO_FROM_TOOL",
    "PARAMETERS",
    "FaceMillCut",
    "InsertLoads",
    "chip_area_and_edge_length",
    "chip_thickness",
    "coefficient_vector",
    "coefficients_from_vector",
    "engagement_angles",
    "facemill_design",
    "facemill_forces",
    "insert_loads",
    "projected_angles",
    "rotation_inverse",
    "tool_from_insert_axes",
    "tool_table",
]

#: Seed 003 eq 2: dynamometer X', Y', Z' from tool X, Y, Z.
DYNO_FROM_TOOL = np.diag([1.0, -1.0, -1.0])

#: The linear parameters of the model, in the column order of :func:`facemill_design`.
PARAMETERS = ("P_T_n_mm", "K_T_n_mm2", "P_R_n_mm", "KRKT_n_mm2", "P_A_n_mm", "KAKT_n_mm2")


def chip_thickness(
    theta_rad: ArrayLike, fz_mm: ArrayLike, radius_mm: float, exact: bool = True
) -> NDArray[np.float64]:
    """Seed 003 eq 1: chip thickness CI(theta), mm (negative behind the cutter).

    ``exact``: R + f sin(theta) - sqrt(R^2 - f^2 cos^2(theta)) (the seed prints f, not f^2,
    under the root); else the usual f sin(theta).
    """
    th = np.asarray(theta_rad, float)
    f = np.asarray(fz_mm, float)
    out: NDArray[np.float64]
    if not exact:
        out = f * np.sin(th)
        return out
    out = radius_mm + f * np.sin(th) - np.sqrt(radius_mm**2 - (f * np.cos(th)) ** 2)
    return out


def tool_from_insert_axes(theta_rad: ArrayLike) -> np.ndarray:
    """Seed 003 eq 14 matrix E(theta), shape (..., 3, 3): F_TRA = E F_XYZ (and F_XYZ = E F_TRA,
    E being its own inverse)."""
    th = np.asarray(theta_rad, float)
    c, s = np.cos(th), np.sin(th)
    e = np.zeros(th.shape + (3, 3))
    e[..., 0, 0], e[..., 0, 1] = c, s
    e[..., 1, 0], e[..., 1, 1] = s, -c
    e[..., 2, 2] = -1.0
    return e


def engagement_angles(
    width_mm: ArrayLike, radius_mm: float, center_offset_mm: ArrayLike = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Entry and exit angles (rad) of an insert crossing a workpiece of the given width.

    The workpiece spans Y' in [offset - w/2, offset + w/2]; an insert at theta sits at
    Y' = R cos(theta). Returns (entry_rad, exit_rad) with 0 <= entry <= exit <= pi; equal when the
    cutter misses the workpiece.
    """
    w = np.asarray(width_mm, float)
    off = np.asarray(center_offset_mm, float)
    hi = np.clip((off + w / 2) / radius_mm, -1.0, 1.0)
    lo = np.clip((off - w / 2) / radius_mm, -1.0, 1.0)
    return np.arccos(hi), np.arccos(lo)


def tool_table(tool: FaceMill) -> EdgeTable:
    """The tabulated insert edge of a face mill (cached)."""
    # What the model reads of the tool (its class is tested in analysis.forces.models only).
    if getattr(tool, "inserts", None) is None or getattr(tool, "lead_angle_deg", None) is None:
        raise AnalysisError(
            f"the face-mill model needs a tool of kind 'facemill', got kind {tool.kind!r}"
        )
    return edge_table(
        float(tool.lead_angle_deg),
        float(tool.radial_rake_deg),
        float(tool.axial_rake_deg),
        float(tool.nose_radius_mm),
        float(tool.insert_edge_length_mm),
    )


def chip_area_and_edge_length(
    tool: FaceMill, h_mm: ArrayLike, depth_mm: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Chip area on the rake face S (mm^2, eqs 11-13) and engaged edge length l (mm, eq 16).

    ``h_mm`` is the chip thickness CI in the radial direction, ``depth_mm`` the axial depth of cut;
    they broadcast. See :mod:`analysis.forces._facemill_geometry` for the construction.
    """
    return chip_section(tool_table(tool), h_mm, depth_mm)


@dataclass(frozen=True)
class FaceMillCut:
    """Cutting conditions of a face-milling pass. Fields may be floats or arrays that broadcast
    with the rotation angles given to the model (e.g. one value per sample in the simulated rig).

    ``entry_deg``/``exit_deg``, if given, override the engagement computed from the width.
    """

    fz_mm: ArrayLike
    depth_mm: ArrayLike
    width_mm: ArrayLike = 100.0
    center_offset_mm: ArrayLike = 0.0
    tilt_deg: float = 0.0
    tilt_low_deg: float = 90.0
    exact_chip: bool = True
    entry_deg: ArrayLike | None = None
    exit_deg: ArrayLike | None = None

    def engagement_rad(self, radius_mm: float) -> tuple[np.ndarray, np.ndarray]:
        if self.entry_deg is not None and self.exit_deg is not None:
            return np.radians(self.entry_deg), np.radians(self.exit_deg)
        return engagement_angles(self.width_mm, radius_mm, self.center_offset_mm)


def _insert_layout(tool: FaceMill) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Angles a_k (rad), feed share of each insert and its radius change vs the insert before."""
    z = tool.inserts
    if tool.insert_angles_deg is None:
        a = 2 * np.pi * np.arange(z) / z
    else:
        a = np.radians(np.asarray(tool.insert_angles_deg, float)) % (2 * np.pi)
    order = np.argsort(a)
    a_sorted = a[order]
    # The insert that passed a spot just before insert k is the next one ahead in angle.
    gap = (np.roll(a_sorted, -1) - a_sorted) % (2 * np.pi)
    gap[gap == 0] = 2 * np.pi
    share = np.empty(z)
    share[order] = gap * z / (2 * np.pi)
    ecc = tool.runout_mm * np.cos(a)
    d_radius = np.empty(z)
    d_radius[order] = ecc[order] - ecc[np.roll(order, -1)]
    return a, share, d_radius, ecc


@dataclass(frozen=True)
class InsertLoads:
    """Per-insert quantities, each of shape (..., inserts): insert angle (rad), chip thickness
    h (mm), local depth (mm), chip area S (mm^2), edge length l (mm), engaged flag."""

    theta_rad: np.ndarray
    h_mm: np.ndarray
    depth_mm: np.ndarray
    S_mm2: np.ndarray
    l_mm: np.ndarray
    engaged: np.ndarray


def insert_loads(theta_rad: ArrayLike, tool: FaceMill, cut: FaceMillCut) -> InsertLoads:
    """Chip thickness, depth, S and l of every insert at cutter rotation angles ``theta_rad``."""
    table = tool_table(tool)
    th = np.asarray(theta_rad, float)
    fz = np.asarray(cut.fz_mm, float)
    depth = np.asarray(cut.depth_mm, float)
    if np.any(fz < 0) or np.any(depth < 0):
        raise AnalysisError(
            f"fz_mm = {cut.fz_mm!r}, depth_mm = {cut.depth_mm!r}: feed per tooth and depth must "
            "be >= 0 (mm)"
        )
    if np.any(depth > tool.depth_limit_mm + 1e-9):
        raise AnalysisError(
            f"depth_mm = {float(np.max(depth)):.4g}: deeper than the insert allows "
            f"({tool.depth_limit_mm:.4g} mm for this face mill)"
        )
    radius = tool.radius_mm
    a, share, d_radius, ecc = _insert_layout(tool)
    # Broadcast everything to (..., inserts).
    thk = (th[..., None] + a) % (2 * np.pi)
    fk = fz[..., None] * share
    h = chip_thickness(thk, fk, radius, cut.exact_chip) + d_radius
    h = np.maximum(h, 0.0)
    dk = np.broadcast_to(depth[..., None], thk.shape)
    if cut.tilt_deg:
        drop = radius * np.sin(np.radians(cut.tilt_deg))
        dk = np.maximum(dk - drop * (1 - np.cos(thk - np.radians(cut.tilt_low_deg))), 0.0)
    S, l = chip_section(table, h, dk)
    if cut.entry_deg is not None and cut.exit_deg is not None:
        # Given angles: the whole insert in or out at once, at them.
        entry, exit_ = cut.engagement_rad(radius)
        engaged = (thk >= np.asarray(entry)[..., None]) & (thk <= np.asarray(exit_)[..., None])
        engaged &= dk > 0
        return InsertLoads(thk, h, dk, np.where(engaged, S, 0.0), np.where(engaged, l, 0.0),
                           engaged)  # fmt: skip
    # The workpiece's edges: each height of the chip enters and leaves on its own ray (the top
    # of a 2 mm cut with a 15 deg lead 0.54 mm further out than the nose, and behind it by the
    # rake), over up to a degree, where the nose's radius alone takes it all in at once.
    off = np.asarray(cut.center_offset_mm, float)[..., None]
    half = np.asarray(cut.width_mm, float)[..., None] / 2
    y_lo, y_hi = np.broadcast_to(off - half, thk.shape), np.broadcast_to(off + half, thk.shape)
    r0 = radius + ecc
    c = np.cos(thk)
    # Bounds of where the chip can be: radii r0 - h .. r0 + x_right(d), angles within the rake's
    # lag (rays within LAG_RAD of thk), so the rest is wholly in or wholly out.
    r_top = r0 + np.interp(dk, table.z_mm, table.x_right_mm)
    lag = np.abs(np.interp(dk, table.z_mm, table.t_right_mm)) / (r0 - h) + 1e-9
    y_min = np.minimum(np.cos(thk - lag), np.cos(thk + lag))
    y_max = np.maximum(np.cos(thk - lag), np.cos(thk + lag))
    y_ext = np.stack([y_min * (r0 - h), y_min * r_top, y_max * (r0 - h), y_max * r_top])
    ahead = np.sin(thk) > 0
    live = ahead & (dk > 0)  # h = 0 (a feed hold): the edge still rubs, ploughing P l
    inside = (y_ext.min(axis=0) >= y_lo) & (y_ext.max(axis=0) <= y_hi)
    outside = (y_ext.max(axis=0) <= y_lo) | (y_ext.min(axis=0) >= y_hi)
    full = live & inside
    part = live & ~inside & ~outside & (np.abs(c) < 1.0)
    S_out, l_out = np.where(full, S, 0.0), np.where(full, l, 0.0)
    if part.any():
        share, lp = partial_fraction(table, h[part], dk[part], np.broadcast_to(r0, thk.shape)[part],
                                     thk[part], y_lo[part], y_hi[part])  # fmt: skip
        S_out[part] = S[part] * share
        l_out[part] = lp
    engaged = full | (part & (S_out > 0))
    return InsertLoads(thk, h, dk, S_out, l_out, engaged)


def facemill_design(theta_rad: ArrayLike, tool: FaceMill, cut: FaceMillCut) -> np.ndarray:
    """Regressors of the model: forces = design @ p with p ordered as :data:`PARAMETERS`.

    Returns an array of shape (..., 3, 6): for each rotation angle, the dynamometer-axis force
    (X', Y', Z', N) produced by a unit value of each parameter, summed over the inserts.
    """
    loads = insert_loads(theta_rad, tool, cut)
    m_inv = tool_table(tool).m_inv
    c, s = np.cos(loads.theta_rad), np.sin(loads.theta_rad)
    # DYNO_FROM_TOOL @ E(theta) = rotation about Z' by theta: [[c, s, 0], [-s, c, 0], [0, 0, 1]].
    de = np.zeros(loads.theta_rad.shape + (3, 3))
    de[..., 0, 0], de[..., 0, 1], de[..., 1, 0], de[..., 1, 1] = c, s, -s, c
    de[..., 2, 2] = 1.0
    g = de @ m_inv  # (..., k, 3 dyno, 3 insert axes)
    design = np.empty(loads.theta_rad.shape[:-1] + (3, 6))
    design[..., 0::2] = np.einsum("...kij,...k->...ij", g, loads.l_mm)
    design[..., 1::2] = np.einsum("...kij,...k->...ij", g, loads.S_mm2)
    return design


def coefficient_vector(coef: FaceMillCoefficients) -> np.ndarray:
    """The parameter vector (6,) of :data:`PARAMETERS` for a set of coefficients."""
    return np.array(
        [
            coef.P_T_n_mm,
            coef.K_T_n_mm2,
            coef.P_R_n_mm,
            coef.K_R * coef.K_T_n_mm2,
            coef.P_A_n_mm,
            coef.K_A * coef.K_T_n_mm2,
        ]
    )


def coefficients_from_vector(p: ArrayLike) -> FaceMillCoefficients:
    """Inverse of :func:`coefficient_vector` (K_R and K_A as ratios to K_T)."""
    p = np.asarray(p, float)
    return FaceMillCoefficients(
        K_T_n_mm2=float(p[1]),
        K_R=float(p[3] / p[1]),
        P_T_n_mm=float(p[0]),
        P_R_n_mm=float(p[2]),
        K_A=float(p[5] / p[1]),
        P_A_n_mm=float(p[4]),
    )


def facemill_forces(
    theta_rad: ArrayLike, tool: FaceMill, coef: FaceMillCoefficients, cut: FaceMillCut
) -> np.ndarray:
    """Forces on the workpiece in dynamometer axes, shape (..., 3) (X', Y', Z'), N.

    ``theta_rad`` (shape (...)) is the cutter rotation angle (insert 0's position, see module
    docstring); ``cut``'s fields broadcast with it.
    """
    out: NDArray[np.float64] = facemill_design(theta_rad, tool, cut) @ coefficient_vector(coef)
    return out
