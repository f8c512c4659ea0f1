"""Which cutting edges are in the workpiece at each sample, and how deep and how thick they cut.

Angles follow the force models' convention: ``theta`` is the immersion angle of an edge measured
from the direction perpendicular to the feed on the side where a clockwise (M3) cutter enters, so
the uncut chip is ``h = fz sin(theta)`` and ``theta = pi/2`` points along the feed. An edge is in
the cut when it is on the leading half of the cutter (``0 < theta < pi``) and below the stock top
at its position. On a straight path the leading half circle lies outside every earlier position of
the cutter, so the stock seen there is uncut; the stock is looked up a small ``margin_mm`` outside
the edge so a Z-map's grid cells on the boundary of the last cut are not mistaken for the cut.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from analysis.config import EndMill, FaceMill
from rig.sim._machine_timeline import TimelineState


class Stock(Protocol):
    def top_z(self, x_mm: np.ndarray, y_mm: np.ndarray) -> np.ndarray:
        """Top of the material at (x, y), mm; -inf where there is none."""
        ...


@dataclass(frozen=True)
class FaceMillEngagement:
    """Per sample and insert, arrays of shape (n, inserts).

    theta_rad immersion angle, depth_mm axial depth at the insert (0 when out of the cut),
    engaged bool; fz_mm (n,) the feed per tooth actually executing; feed_angle_rad (n,) the feed
    direction in the machine XY plane.
    """

    theta_rad: np.ndarray
    depth_mm: np.ndarray
    engaged: np.ndarray
    fz_mm: np.ndarray
    feed_angle_rad: np.ndarray


@dataclass(frozen=True)
class EndMillEngagement:
    """Per sample, tooth and axial slice, arrays of shape (n, teeth, slices).

    theta_rad immersion angle, h_mm uncut chip thickness normal to the edge (0 out of the cut),
    engaged bool; dz_mm (slices,) slice heights, z_mm (slices,) slice centres above the tip,
    kappa_rad (slices,) axial immersion angle of the edge (pi/2 on a flat flank); fz_mm (n,),
    feed_angle_rad (n,); edge_rad (n, teeth, slices) the edge's absolute angle in machine XY (its
    outward normal is (cos, sin)).
    """

    theta_rad: np.ndarray
    engaged: np.ndarray
    dz_mm: np.ndarray
    z_mm: np.ndarray
    kappa_rad: np.ndarray
    fz_mm: np.ndarray
    feed_angle_rad: np.ndarray
    edge_rad: np.ndarray

    @property
    def h_mm(self) -> np.ndarray:
        """Nominal chip (n, teeth, slices) mm (the regenerative twin does without it)."""
        h = self.fz_mm[:, None, None] * np.sin(self.theta_rad) * np.sin(self.kappa_rad)
        return np.where(self.engaged, h, 0.0)


def _feed_frame(state: TimelineState, teeth: int) -> tuple[np.ndarray, np.ndarray]:
    """Feed per tooth (n,) mm (from the executing XY speed) and feed angle (n,) rad."""
    v_xy = np.hypot(state.velocity_mm_s[:, 0], state.velocity_mm_s[:, 1])
    rev_s = np.abs(state.spindle_rpm) / 60.0
    with np.errstate(divide="ignore", invalid="ignore"):
        fz = np.where(rev_s > 0, v_xy / (rev_s * teeth), 0.0)
    beta = np.arctan2(state.direction[:, 1], state.direction[:, 0])
    return fz, beta


def _theta(edge_angle: np.ndarray, beta: np.ndarray, spindle_rpm: np.ndarray) -> np.ndarray:
    """Immersion angle from an edge's absolute angle (machine XY) and the feed angle."""
    alpha = edge_angle - beta[:, None]  # counter-clockwise from the feed direction
    # M3 turns clockwise: entry at +90 deg from the feed; M4 mirrors it.
    sgn = np.where(spindle_rpm >= 0, 1.0, -1.0)[:, None]
    return np.mod(np.pi / 2 - sgn * alpha + np.pi, 2 * np.pi) - np.pi


def facemill_engagement(
    state: TimelineState, tool: FaceMill, stock: Stock, margin_mm: float = 0.0
) -> FaceMillEngagement:
    """Engagement of each insert tip (on the cutter's outer radius) at each sample."""
    n_ins = tool.inserts
    if tool.insert_angles_deg is not None:
        offs = np.radians(np.asarray(tool.insert_angles_deg, dtype=float))
    else:
        offs = 2 * np.pi * np.arange(n_ins) / n_ins
    fz, beta = _feed_frame(state, n_ins)
    edge = state.spindle_angle_rad[:, None] + offs[None, :]  # (n, k) absolute angle
    r = tool.radius_mm
    cx = state.position_mm[:, 0:1]
    cy = state.position_mm[:, 1:2]
    xr = cx + (r + margin_mm) * np.cos(edge)
    yr = cy + (r + margin_mm) * np.sin(edge)
    top = stock.top_z(xr, yr)
    depth = top - state.position_mm[:, 2:3]
    theta = _theta(edge, beta, state.spindle_rpm)
    spinning = (state.spindle_rpm != 0)[:, None]
    engaged = (theta > 0) & (theta < np.pi) & (depth > 0) & np.isfinite(depth) & spinning
    depth = np.where(engaged, np.minimum(depth, tool.depth_limit_mm), 0.0)
    return FaceMillEngagement(theta, depth, engaged, fz, beta)


def slice_profile(tool: EndMill, depth_mm: float, n_slices: int) -> tuple[np.ndarray, ...]:
    """Axial slices of an end mill from its tip to ``depth_mm``.

    Returns z_mm (s,) slice centres above the tip, dz_mm (s,) slice heights (on a corner: the
    exact edge length in the slice times sin kappa), radius_mm (s,) edge radius at z, kappa_rad
    (s,) angle between the tool axis and the edge normal (pi/2 on the flank).
    """
    depth = min(depth_mm, tool.flute_length_mm)
    edges = np.linspace(0.0, depth, n_slices + 1)
    z = 0.5 * (edges[1:] + edges[:-1])
    dz = np.diff(edges)
    r, rc = tool.radius_mm, tool.corner_radius_mm
    radius = np.full_like(z, r)
    kappa = np.full_like(z, np.pi / 2)
    if rc > 0:
        # Corner (torus) part: a circle of radius rc centred at (r - rc, rc) in (rho, z).
        low = z < rc
        dzc = rc - z[low]
        rho = np.sqrt(np.maximum(rc**2 - dzc**2, 0.0))
        radius[low] = (r - rc) + rho
        kappa[low] = np.arctan2(rho, dzc)
        # Slice height as the force model sees it (dz = db sin kappa) from the exact edge arc
        # length db in the slice, so the slices near the tip (kappa -> 0) are not mis-weighted.
        k_lo = np.arccos(np.clip((rc - np.minimum(edges[:-1], rc)) / rc, -1, 1))
        k_hi = np.arccos(np.clip((rc - np.minimum(edges[1:], rc)) / rc, -1, 1))
        db = rc * (k_hi - k_lo) + np.maximum(edges[1:] - np.maximum(edges[:-1], rc), 0.0)
        dz = db * np.sin(kappa)
    return z, dz, radius, kappa


def endmill_engagement(
    state: TimelineState,
    tool: EndMill,
    stock: Stock,
    max_depth_mm: float,
    n_slices: int = 12,
    margin_mm: float = 0.0,
) -> EndMillEngagement:
    """Engagement of every tooth on ``n_slices`` axial slices up to ``max_depth_mm`` above the tip.

    The helix lags a slice at height z by ``z tan(helix) / R`` behind the tip's angle.
    """
    teeth = tool.flutes
    fz, beta = _feed_frame(state, teeth)
    z, dz, radius, kappa = slice_profile(tool, max(max_depth_mm, 1e-6), n_slices)
    lag = z * np.tan(np.radians(tool.helix_deg)) / tool.radius_mm  # (s,)
    sgn = np.where(state.spindle_rpm >= 0, 1.0, -1.0)
    tooth = 2 * np.pi * np.arange(teeth) / teeth
    # Right-hand helix, clockwise cutter: higher slices trail the tip, i.e. lie ahead in angle.
    edge = (
        state.spindle_angle_rad[:, None, None]
        + tooth[None, :, None]
        + sgn[:, None, None] * lag[None, None, :]
    )  # (n, t, s)
    n = state.position_mm.shape[0]
    theta = _theta(edge.reshape(n, -1), beta, state.spindle_rpm).reshape(edge.shape)
    spinning = (state.spindle_rpm != 0)[:, None, None]
    engaged = (theta > 0) & (theta < np.pi) & spinning
    # The stock is looked up on the leading half only (the other half never cuts).
    i, k, s = np.nonzero(engaged)
    rr = radius[s] + margin_mm
    top = stock.top_z(
        state.position_mm[i, 0] + rr * np.cos(edge[i, k, s]),
        state.position_mm[i, 1] + rr * np.sin(edge[i, k, s]),
    )
    engaged[i, k, s] = state.position_mm[i, 2] + z[s] < top
    return EndMillEngagement(theta, engaged, dz, z, kappa, fz, beta, edge)
