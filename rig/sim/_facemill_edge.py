"""The insert's edge for :mod:`rig.sim.facemill_independent` (seed 003 2.2.2): the insert axes
T', R', A' from the projected tool angles, and the square insert's edge (minor edge, nose arc,
major edge) swept about the spindle axis and tabulated against height. Like its user it shares
nothing with ``analysis.forces`` or ``analysis.identify``."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import optimize

_EDGE_POINTS = 3000  # per straight edge
_ARC_POINTS = 2000


def insert_axes(lead_deg: float, radial_rake_deg: float, axial_rake_deg: float) -> np.ndarray:
    """Columns T', R', A' in T, R, A (3, 3): the projections of A' on RA, R' on TR and T' on TA
    make the angles gamma_L, gamma_R, gamma_A with A, R and T (seed 003 2.2.2, the column form of
    eq 9), and the three are orthogonal; theta_1..3 solved numerically."""
    gl, gr, ga = np.radians([lead_deg, radial_rake_deg, axial_rake_deg])

    def axes(th: np.ndarray) -> np.ndarray:
        t1, t2, t3 = th
        tp = [np.cos(ga) * np.cos(t1), -np.sin(t1), np.sin(ga) * np.cos(t1)]
        rp = [np.sin(gr) * np.cos(t2), np.cos(gr) * np.cos(t2), -np.sin(t2)]
        ap = [-np.sin(t3), np.sin(gl) * np.cos(t3), np.cos(gl) * np.cos(t3)]
        return np.array([tp, rp, ap]).T

    def ortho(th: np.ndarray) -> list[float]:
        m = axes(th)
        return [m[:, 0] @ m[:, 1], m[:, 1] @ m[:, 2], m[:, 2] @ m[:, 0]]

    th, _, _, msg = optimize.fsolve(ortho, np.zeros(3), xtol=1e-13, full_output=True)
    m = axes(th)
    if np.abs(m.T @ m - np.eye(3)).max() > 1e-9:
        raise ValueError(f"insert axes for lead {lead_deg}, rakes {radial_rake_deg}/"
                         f"{axial_rake_deg} deg: no orthonormal solution ({msg})")  # fmt: skip
    return m


@dataclass(frozen=True)
class Edge:
    """An insert's edge swept about the spindle axis, tabulated against the height z above its
    lowest point (mm): per branch ('in' the minor-edge side, 'out' the major-edge side) the swept
    radius rho (mm), the arc length s along the true edge from the lowest point (mm) and the
    angular lead (rad, + ahead in the turning direction); ``axes`` T', R', A' in T, R, A;
    ``cos_nu`` between the RA plane and the rake face."""

    z_in: np.ndarray
    rho_in: np.ndarray
    s_in: np.ndarray
    lead_in: np.ndarray
    z_out: np.ndarray
    rho_out: np.ndarray
    s_out: np.ndarray
    lead_out: np.ndarray
    axes: np.ndarray
    cos_nu: float

    @property
    def max_depth_mm(self) -> float:
        return float(self.z_out[-1])


@lru_cache(maxsize=16)
def edge_of(radius_mm: float, lead_deg: float, radial_rake_deg: float, axial_rake_deg: float,
            nose_radius_mm: float, edge_length_mm: float) -> Edge:  # fmt: skip
    """The swept edge of a square insert (SPGN-like): corner with nose radius r, the major edge
    along A', the minor edge along -R' (the insert body lies on the -R', +A' side); its lowest
    point at ``radius_mm`` from the axis."""
    m = insert_axes(lead_deg, radial_rake_deg, axial_rake_deg)
    r, length = nose_radius_mm, edge_length_mm
    # rake-face coordinates (u along R', v along A') from the sharp corner: minor edge from its
    # inner end, the nose arc about (-r, r), the major edge up to its end
    u_min = np.linspace(-length, -r, _EDGE_POINTS)
    a = np.linspace(np.pi / 2, 0.0, _ARC_POINTS)[1:]
    u_arc, v_arc = -r + r * np.cos(a), r - r * np.sin(a)
    v_maj = np.linspace(r, length, _EDGE_POINTS)[1:]
    u = np.concatenate([u_min, u_arc, np.zeros_like(v_maj)])
    v = np.concatenate([np.zeros_like(u_min), v_arc, v_maj])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(u), np.diff(v)))])
    p = u[:, None] * m[:, 1] + v[:, None] * m[:, 2]  # (n, 3) in T, R, A
    i0 = int(np.argmin(p[:, 2] + 1e-12 * np.arange(len(u))))  # the lowest; the later on a flat
    t_off, r_off, z = p[:, 0] - p[i0, 0], p[:, 1] - p[i0, 1], p[:, 2] - p[i0, 2]
    rho = np.hypot(radius_mm + r_off, t_off)
    lead = np.arctan2(t_off, radius_mm + r_off)
    out = slice(i0, None)
    inn = slice(i0, None, -1)
    branches = []
    for sl in (inn, out):
        zb, keep = z[sl], np.ones(len(z[sl]), bool)
        keep[1:] = np.diff(np.maximum.accumulate(zb)) > 1e-12  # strictly rising part
        zb = zb[keep]
        branches.append((zb, rho[sl][keep], np.abs(s[sl] - s[i0])[keep], lead[sl][keep]))
    if len(branches[1][0]) < 2 or np.any(np.diff(branches[1][1]) < -1e-9):
        raise ValueError(f"lead {lead_deg} deg: the major edge leans inwards (undercut)")
    return Edge(*branches[0], *branches[1], axes=m, cos_nu=float(abs(m[0, 0])))
