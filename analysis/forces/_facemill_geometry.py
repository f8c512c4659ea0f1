"""Insert geometry of seed 003: projected tool angles, [M]^-1, chip section with a nose radius.

Private helpers of :mod:`analysis.forces.facemill` (the public names are re-exported there).

Frames (seed 003 Fig. 1): T is the cutting-velocity direction at the insert, R the radial direction
(outwards), A the cutter axis (up, away from the machined floor). T', R', A' are the insert's own
axes: T' is the rake-face normal, A' runs along the major cutting edge and R' along the minor edge.
The tool angles gamma_L (lead), gamma_R (radial rake) and gamma_A (axial rake) are the angles of
the projections of A', R', T' on the RA, TR and TA planes (seed 003 2.2.2), not rotation angles.

Slip in the seed text (found while implementing, not in the seeds index): eqs 6 and 7 as printed
are not the solution of the orthogonality conditions and give a [M]^-1 that is not orthonormal
(0.8 % off for the seed's 15/0/7 deg tool). Eq 5 is right; eqs 6 and 7 follow from it by the cyclic
substitution (A, R, L) -> (R, L, A) -> (L, A, R), whose last numerator terms are
sin(gamma_R) tan(gamma_L) tan(gamma_R) and sin(gamma_L) tan(gamma_A) tan(gamma_L) (the text
prints tan(gamma_A) and tan(gamma_R) as the last factors). ``projected_angles`` uses the
corrected forms; ``tests/test_facemill_geometry.py`` shows they solve the orthogonality equations.

Chip section (eqs 11-13, 16): the text's eq 11 refers to points of a figure that the seed does not
include, so the section is computed here from first principles with the same decomposition: the
edge (minor edge, nose arc of radius r, major edge) is drawn on the rake face, projected on the RA
plane with [M]^-1 (the lead angle is the projected angle by construction), and the chip section is
the area between the current and the previous tooth path, which lie h = CI(theta) apart in R.
Slicing it horizontally (height z above the floor) gives, exactly for a convex edge,

    S_RA(h, d) = W(min(d, e)) + h * max(d - e, 0),   W(z) = int_0^z w(z') dz'

where w(z) is the width of the edge's cup at height z and e the cusp height (w(e) = h). Above the
cusp this is the paper's A2 = h (d - c) term, below it the nose term A1'. The area on the rake face
is S = S_RA / cos(nu) (eq 13) with cos(nu) = a11, the cosine between the RA and R'A' planes. The
engaged edge length l (eq 16) is the edge's true length from the cusp on the trailing side, round
the nose, up to the top of the cut on the major edge.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.errors import AnalysisError

_ARC_POINTS = 721
_EDGE_POINTS = 400
_TABLE_POINTS = 4001


def projected_angles(
    lead_rad: ArrayLike, radial_rake_rad: ArrayLike, axial_rake_rad: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """theta_1, theta_2, theta_3 of seed 003 eqs 5-7 (eqs 6-7 corrected, see module docstring).

    Parameters are arrays (any broadcastable shape), radians. Returns three arrays, radians.
    """
    gl, gr, ga = np.broadcast_arrays(
        np.asarray(lead_rad, float), np.asarray(radial_rake_rad, float),
        np.asarray(axial_rake_rad, float),
    )  # fmt: skip
    tl, tr, ta = np.tan(gl), np.tan(gr), np.tan(ga)
    den = 1.0 + tl * tr * ta
    t1 = np.arctan((np.cos(ga) * tr - np.sin(ga) * tl + np.sin(ga) * tr * ta) / den)
    t2 = np.arctan((np.cos(gr) * tl - np.sin(gr) * ta + np.sin(gr) * tl * tr) / den)
    t3 = np.arctan((np.cos(gl) * ta - np.sin(gl) * tr + np.sin(gl) * ta * tl) / den)
    return t1, t2, t3


def rotation_inverse(
    lead_rad: ArrayLike, radial_rake_rad: ArrayLike, axial_rake_rad: ArrayLike
) -> NDArray[np.float64]:
    """[M]^-1 of seed 003 eq 9: columns are T', R', A' expressed in T, R, A.

    ``[T, R, A]^T = M_inv @ [T', R', A']^T`` (eq 8); eq 15's [M'] is its transpose.
    Returns an array of shape (..., 3, 3) for broadcastable angle arrays in radians.
    """
    gl, gr, ga = np.broadcast_arrays(
        np.asarray(lead_rad, float), np.asarray(radial_rake_rad, float),
        np.asarray(axial_rake_rad, float),
    )  # fmt: skip
    t1, t2, t3 = projected_angles(gl, gr, ga)
    m = np.empty(gl.shape + (3, 3))
    m[..., 0, 0] = np.cos(ga) * np.cos(t1)
    m[..., 0, 1] = np.sin(gr) * np.cos(t2)
    m[..., 0, 2] = -np.sin(t3)
    m[..., 1, 0] = -np.sin(t1)
    m[..., 1, 1] = np.cos(gr) * np.cos(t2)
    m[..., 1, 2] = np.sin(gl) * np.cos(t3)
    m[..., 2, 0] = np.sin(ga) * np.cos(t1)
    m[..., 2, 1] = -np.sin(t2)
    m[..., 2, 2] = np.cos(gl) * np.cos(t3)
    return m


@dataclass(frozen=True)
class EdgeTable:
    """The insert edge projected on the RA plane, tabulated against height above the floor.

    All arrays have shape (n,) over ``z_mm`` (0 at the lowest point of the edge, increasing).
    ``width_mm`` is the cup width w(z), ``area_mm2`` W(z), ``s_left_mm``/``s_right_mm`` the arc
    length along the true edge (on the rake face) at height z on the trailing (inner) and leading
    (major-edge) sides, measured from the inner end of the minor edge.
    """

    z_mm: np.ndarray
    width_mm: np.ndarray
    area_mm2: np.ndarray
    s_left_mm: np.ndarray
    s_right_mm: np.ndarray
    m_inv: np.ndarray
    cos_nu: float
    tangent_height_mm: float  # c of eq 16: where the nose arc meets the major edge
    # Where the edge sits at height z, from its lowest point: radially (R, + out) on the trailing
    # and leading sides, and along T (+ ahead) on the leading side (a rake puts the upper edge
    # behind or ahead of the nose). They place each height's chip for the entry and exit.
    x_left_mm: np.ndarray
    x_right_mm: np.ndarray
    t_right_mm: np.ndarray

    @property
    def max_depth_mm(self) -> float:
        return float(self.z_mm[-1])


def _interp_branch(
    zt: NDArray[np.float64], zb: NDArray[np.float64], vb: NDArray[np.float64], last: bool
) -> NDArray[np.float64]:
    """Interpolate a branch quantity at heights zt; on flat runs of zb keep the point nearest the
    nose (last=False) or farthest from it (last=True)."""
    keep = np.ones(len(zb), bool)
    same = np.diff(zb) <= 1e-12
    if last:
        keep[:-1] &= ~same
    else:
        keep[1:] &= ~same
    return np.interp(zt, zb[keep], vb[keep])


@lru_cache(maxsize=32)
def edge_table(
    lead_deg: float, radial_rake_deg: float, axial_rake_deg: float, nose_radius_mm: float,
    edge_length_mm: float,
) -> EdgeTable:  # fmt: skip
    """Tabulate the projected edge of a square-cornered insert (SPGN-like, minor edge at 90 deg).

    Raises :class:`AnalysisError` for a geometry the model cannot describe (edge not rising on
    both sides of the nose once projected, i.e. the cup is not convex).
    """
    r = nose_radius_mm
    m = rotation_inverse(*np.radians([lead_deg, radial_rake_deg, axial_rake_deg]))
    straight = edge_length_mm - r
    # Edge on the rake face (u along R', v along A'): minor edge, nose arc, major edge.
    u_minor = np.linspace(-straight, 0.0, _EDGE_POINTS)
    v_minor = np.full_like(u_minor, -r)
    phi = np.linspace(0.0, np.pi / 2, _ARC_POINTS)[1:]
    u_arc, v_arc = r * np.sin(phi), -r * np.cos(phi)
    v_major = np.linspace(0.0, straight, _EDGE_POINTS)[1:]
    u_major = np.full_like(v_major, r)
    u = np.concatenate([u_minor, u_arc, u_major])
    v = np.concatenate([v_minor, v_arc, v_major])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(u), np.diff(v)))])
    x = m[1, 1] * u + m[1, 2] * v
    tt = m[0, 1] * u + m[0, 2] * v
    z = m[2, 1] * u + m[2, 2] * v
    # The lowest point; with a flat wiper on the floor take its end at the nose.
    i0 = int(np.flatnonzero(z <= z.min() + 1e-12 * max(1.0, r))[-1])
    z, x, tt = z - z[i0], x - x[i0], tt - tt[i0]
    zl, xl, sl = z[: i0 + 1][::-1], x[: i0 + 1][::-1], s[: i0 + 1][::-1]
    zr, xr, sr, tr = z[i0:], x[i0:], s[i0:], tt[i0:]
    bad = i0 == len(z) - 1 or np.any(np.diff(zl) < -1e-12) or np.any(np.diff(zr) < -1e-12)
    if not bad and zl[-1] < zr[-1]:
        # A minor edge that never rises (zero lead: a wiper on the floor) ends at the insert's
        # next corner, which bounds the cup from the inside.
        zl, xl, sl = np.append(zl, zr[-1]), np.append(xl, xl[-1]), np.append(sl, sl[-1])
    top = min(zl[-1], zr[-1])
    if bad or top <= 0:
        raise AnalysisError(
            f"face-mill insert lead {lead_deg} deg, radial rake {radial_rake_deg} deg, axial rake "
            f"{axial_rake_deg} deg: the projected edge does not rise on both sides of the nose; "
            "the seed 003 model needs a convex cutting corner"
        )
    # Dense near the floor, where the nose makes w(z) grow like sqrt(z) (the cusp lives there).
    t = np.linspace(0.0, 1.0, _TABLE_POINTS)
    zt = np.unique(np.concatenate([top * t**3, top * t]))
    xlz = _interp_branch(zt, zl, xl, last=True)
    xrz = _interp_branch(zt, zr, xr, last=False)
    slz = _interp_branch(zt, zl, sl, last=False)
    srz = _interp_branch(zt, zr, sr, last=False)
    trz = _interp_branch(zt, zr, tr, last=False)
    w = xrz - xlz
    if np.any(np.diff(w) < -1e-9):
        raise AnalysisError(
            f"face-mill insert lead {lead_deg} deg, radial rake {radial_rake_deg} deg, axial rake "
            f"{axial_rake_deg} deg: the major edge leans inwards (undercut) in projection; the "
            "seed 003 chip model needs a lead angle that opens the cut (lead >= 0 deg)"
        )
    area = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(zt))])
    tangent = float(z[_EDGE_POINTS + _ARC_POINTS - 2])
    return EdgeTable(zt, w, area, slz, srz, m, float(m[0, 0]), tangent, xlz, xrz, trz)


def chip_section(
    table: EdgeTable, h_mm: ArrayLike, depth_mm: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Chip area on the rake face S (eq 13) and engaged edge length l (eq 16).

    Parameters
    ----------
    table : EdgeTable of the insert.
    h_mm : array, chip thickness CI(theta) in R (mm), >= 0.
    depth_mm : array broadcastable with h_mm, local axial depth of cut (mm), >= 0.

    Returns
    -------
    (S_mm2, l_mm) : arrays of the broadcast shape. Both are 0 where depth is 0.
    """
    h, d = np.broadcast_arrays(np.asarray(h_mm, float), np.asarray(depth_mm, float))
    h = np.maximum(h, 0.0)
    d = np.maximum(d, 0.0)
    if np.any(d > table.max_depth_mm + 1e-9):
        raise AnalysisError(
            f"depth of cut {float(d.max()):.4g} mm exceeds the insert's usable edge "
            f"({table.max_depth_mm:.4g} mm in projection)"
        )
    # Cusp height e: w(e) = h (w increases with z for a convex cup).
    e = np.interp(h, table.width_mm, table.z_mm)
    lo = np.minimum(d, e)
    s_rra = np.interp(lo, table.z_mm, table.area_mm2) + h * np.maximum(d - e, 0.0)
    l_mm = np.interp(d, table.z_mm, table.s_right_mm) - np.interp(lo, table.z_mm, table.s_left_mm)
    l_mm = np.where(d > 0, l_mm, 0.0)
    return s_rra / table.cos_nu, l_mm


#: Heights (fractions of the depth) at which a partly engaged chip is integrated: dense near the
#: floor, where the nose makes the cusp.
_PART_GRID = np.unique(np.concatenate([np.linspace(0.0, 1.0, 49) ** 3, np.linspace(0.0, 1.0, 97)]))


def partial_fraction(
    table: EdgeTable, h_mm: ArrayLike, depth_mm: ArrayLike, radius_mm: ArrayLike,
    theta_rad: ArrayLike, y_lo_mm: ArrayLike, y_hi_mm: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:  # fmt: skip
    """Share of the chip area, and the engaged edge length (mm), of inserts that are partly in
    the workpiece (across the feed it spans Y' in [y_lo, y_hi]): each height z of the chip lies
    on its own ray, at the angle theta + (its T offset over its radius) and between the radii
    radius + max(x_left, x_right - h) and radius + x_right (the current edge and the previous
    pass's), so a leaning edge enters and leaves over a fraction of a degree, the nose first.
    Arrays (m,) in, (area share, l_mm) (m,) out; the area is integrated by trapezoids on
    :data:`_PART_GRID`, the edge's contact by the linear zero of its margin in a slice."""
    h, d, r0, th, lo, hi = (np.asarray(a, float)[:, None] for a in np.broadcast_arrays(
        h_mm, depth_mm, radius_mm, theta_rad, y_lo_mm, y_hi_mm))  # fmt: skip
    z = d * _PART_GRID[None, :]
    xr = np.interp(z, table.z_mm, table.x_right_mm)
    xl = np.interp(z, table.z_mm, table.x_left_mm)
    lag = np.interp(z, table.z_mm, table.t_right_mm) / (r0 + xr)
    c = np.cos(th + lag)
    c = np.where(np.abs(c) < 1e-12, 1e-12, c)  # a ray along the block's edge: keep the sign
    t_lo, t_hi = np.minimum(lo / c, hi / c), np.maximum(lo / c, hi / c)
    inner, outer = r0 + np.maximum(xl, xr - h), r0 + xr
    full = np.maximum(outer - inner, 0.0)
    part = np.maximum(np.minimum(outer, t_hi) - np.maximum(inner, t_lo), 0.0)
    dz = np.diff(z, axis=1)
    area_full = (0.5 * (full[:, 1:] + full[:, :-1]) * dz).sum(axis=1)
    area_part = (0.5 * (part[:, 1:] + part[:, :-1]) * dz).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(area_full > 0, area_part / area_full, 0.0)

    def contact(radius: np.ndarray) -> np.ndarray:
        g = np.minimum(radius - t_lo, t_hi - radius)
        g0, g1 = g[:, :-1], g[:, 1:]
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.where(g0 > 0, g0, g1) / (np.abs(g0) + np.abs(g1))
        return np.where((g0 > 0) & (g1 > 0), 1.0, np.where((g0 > 0) ^ (g1 > 0), f, 0.0))

    # The trailing side touches uncut material below the cusp only (w(e) = h).
    e = np.interp(h, table.width_mm, table.z_mm)
    ds_r = np.diff(np.interp(z, table.z_mm, table.s_right_mm), axis=1)
    ds_l = -np.diff(np.interp(np.minimum(z, e), table.z_mm, table.s_left_mm), axis=1)
    l_mm = (contact(outer) * ds_r + contact(r0 + xl) * ds_l).sum(axis=1)
    return share, l_mm
