"""End-milling forces: the linear edge-force model (Altintas), flat, ball and bull-nose end mills.

Per edge element of width db (chip width, mm) at local chip thickness h (mm)::

    dF_t = K_tc h db + K_te db,   dF_r = K_rc h db + K_re db,   dF_a = K_ac h db + K_ae db

h = (f_z sin(phi) + runout change) sin(kappa), where phi is the tooth's angular position and
kappa the axial immersion angle of the edge (90 deg on the cylinder; on a ball or a bull-nose
corner the angle between the tool axis and the surface normal, after Lee & Altintas 1996). The
cutter is cut into axial discs; the helix (constant lead) delays each disc by z tan(helix) / R.

Conventions (shared with :mod:`analysis.forces.facemill` so the rig and the identification agree):

- ``phi`` is tooth 0's angular position at the tool tip, radians, measured from +Y towards +X
  (the feed direction) — clockwise seen from above, the sense of an M3 spindle; the tooth sits at
  (R sin(phi), R cos(phi)) and its chip is f sin(phi) thick for 0 < phi < pi.
- The returned forces are those the tool exerts on the workpiece (what a table dynamometer
  measures), in the model frame X = feed direction, Y, Z = tool axis up; with ``feed_angle_deg``
  they are rotated about Z into machine axes (feed direction at that angle from +X).
- Up (conventional) milling: the tool engages the workpiece on its +Y side, entry at phi = 0;
  down (climb) milling: on its -Y side, exit at phi = pi. ``immersion_angles`` gives both.
- Runout: the tool axis is offset by ``runout_mm`` (amplitude, from the tool config or the cut)
  towards ``runout_angle_deg``; tooth k's radius is R + e cos(runout_angle - k 2 pi / N) and its
  chip changes by its radius minus that of the tooth that passed before it, k + 1 (tooth k sits
  at phi + k 2 pi / N, so tooth k + 1 leads it by a pitch). A tooth whose chip becomes <= 0 does not
  cut (no multi-tooth skipping beyond that).

Public API (shapes: ``phi_rad`` any shape ``(...)``; conditions broadcast with it):
``EndMillCut``, ``immersion_angles``, ``endmill_design`` ((..., 3, 6) regressors),
``endmill_forces`` ((..., 3) N), ``mean_force_design`` (per-revolution mean, (..., 3, 6);
closed forms for flat end mills), ``PARAMETERS``, ``coefficient_vector``,
``coefficients_from_vector``, ``peak_force`` (largest resultant over a revolution, N).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, TypedDict, Unpack

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.config import EndMill, EndMillCoefficients
from analysis.errors import AnalysisError

__all__ = [
    "PARAMETERS",
    "EndMillCut",
    "coefficient_vector",
    "coefficients_from_vector",
    "element_forces",
    "endmill_design",
    "endmill_forces",
    "immersion_angles",
    "mean_force_design",
    "peak_force",
]

#: Linear parameters, in the column order of :func:`endmill_design`.
PARAMETERS = ("Ktc_n_mm2", "Krc_n_mm2", "Kac_n_mm2", "Kte_n_mm", "Kre_n_mm", "Kae_n_mm")


def immersion_angles(
    ae_mm: ArrayLike, diameter_mm: float, mode: Literal["up", "down", "slot"] = "down"
) -> tuple[np.ndarray, np.ndarray]:
    """Entry and exit angles (rad) for radial width of cut ``ae_mm`` (0 < ae <= D)."""
    ae = np.asarray(ae_mm, float)
    if np.any(ae <= 0) or np.any(ae > diameter_mm * (1 + 1e-9)):
        raise AnalysisError(
            f"ae_mm = {ae_mm!r}: radial width of cut must be in (0, {diameter_mm}] mm (diameter)"
        )
    span = np.arccos(np.clip(1 - 2 * ae / diameter_mm, -1.0, 1.0))
    if mode == "slot":
        return np.zeros_like(ae), np.full_like(ae, np.pi)
    if mode == "up":
        return np.zeros_like(ae), span
    if mode == "down":
        return np.pi - span, np.full_like(ae, np.pi)
    raise AnalysisError(f"milling mode {mode!r}: expected 'up', 'down' or 'slot'")


class CutExtras(TypedDict, total=False):
    """The fields of :class:`EndMillCut` besides the engagement (:meth:`EndMillCut.from_width`)."""

    feed_angle_deg: ArrayLike
    runout_mm: float | None
    runout_angle_deg: float


@dataclass(frozen=True)
class EndMillCut:
    """Conditions of an end-milling cut; fields broadcast with the rotation angles.

    ``fz_mm`` feed per tooth, ``depth_mm`` axial depth from the tool tip, ``entry_deg``/
    ``exit_deg`` the engagement (see :func:`immersion_angles`), ``feed_angle_deg`` the feed
    direction in the machine XY plane, ``runout_mm``/``runout_angle_deg`` override the tool's.
    """

    fz_mm: ArrayLike
    depth_mm: ArrayLike
    entry_deg: ArrayLike = 0.0
    exit_deg: ArrayLike = 180.0
    feed_angle_deg: ArrayLike = 0.0
    runout_mm: float | None = None
    runout_angle_deg: float = 0.0

    @classmethod
    def from_width(
        cls, tool: EndMill, fz_mm: ArrayLike, depth_mm: ArrayLike, ae_mm: ArrayLike,
        mode: Literal["up", "down", "slot"] = "down", **kw: Unpack[CutExtras],
    ) -> EndMillCut:  # fmt: skip
        st, ex = immersion_angles(ae_mm, tool.diameter_mm, mode)
        return cls(fz_mm, depth_mm, np.degrees(st), np.degrees(ex), **kw)


def _check_tool(tool: EndMill) -> None:
    # What the model reads of the tool (its class is tested in analysis.forces.models only).
    if getattr(tool, "flutes", None) is None or getattr(tool, "corner_radius_mm", None) is None:
        raise AnalysisError(
            f"the end-mill model needs a flat, ball or bull end mill, got kind {tool.kind!r} "
            "(use analysis.forces.facemill for face mills)"
        )


def _discs(
    tool: EndMill, depth: NDArray[np.float64], n_discs: int
) -> tuple[NDArray[np.float64], ...]:  # z, db, rho, sin kappa, cos kappa
    """Disc mid-heights z, chip widths db, radii rho and sin/cos kappa, each (..., n_discs)."""
    R, rc = tool.radius_mm, tool.corner_radius_mm
    frac = np.linspace(0.0, 1.0, n_discs + 1)
    z_lo = depth[..., None] * frac[:-1]
    z_hi = depth[..., None] * frac[1:]
    z = 0.5 * (z_lo + z_hi)
    if rc > 0:
        # Exact arc length of the corner inside each disc (db = rc dkappa), cylinder above it.
        k_lo = np.arccos(np.clip((rc - np.minimum(z_lo, rc)) / rc, -1, 1))
        k_hi = np.arccos(np.clip((rc - np.minimum(z_hi, rc)) / rc, -1, 1))
        db = rc * (k_hi - k_lo) + np.maximum(z_hi - np.maximum(z_lo, rc), 0.0)
        zc = np.minimum(z, rc)
        cos_k = (rc - zc) / rc
        sin_k = np.sqrt(np.clip(1 - cos_k**2, 0, 1))
        rho = R - rc + rc * sin_k
    else:
        db = z_hi - z_lo
        sin_k, cos_k = np.ones_like(z), np.zeros_like(z)
        rho = np.full_like(z, R)
    return z, db, rho, sin_k, cos_k


def endmill_design(
    phi_rad: ArrayLike, tool: EndMill, cut: EndMillCut, n_discs: int = 24
) -> np.ndarray:
    """Regressors: forces = design @ p, p ordered as :data:`PARAMETERS`.

    Returns shape (..., 3, 6): workpiece force in machine axes (N) per unit coefficient, summed
    over teeth and discs. Memory is (...) x flutes x n_discs floats per intermediate.
    """
    _check_tool(tool)
    phi = np.asarray(phi_rad, float)
    fz = np.asarray(cut.fz_mm, float)
    depth = np.asarray(cut.depth_mm, float)
    if np.any(fz < 0) or np.any(depth < 0):
        raise AnalysisError(f"fz_mm = {cut.fz_mm!r}, depth_mm = {cut.depth_mm!r}: must be >= 0 mm")
    if np.any(depth > tool.flute_length_mm + 1e-9):
        raise AnalysisError(
            f"depth_mm = {float(np.max(depth)):.4g}: deeper than the flute length "
            f"({tool.flute_length_mm} mm)"
        )
    shape = np.broadcast_shapes(phi.shape, fz.shape, depth.shape)
    phi, fz, depth = (np.broadcast_to(a, shape) for a in (phi, fz, depth))
    n = tool.flutes
    pitch = 2 * np.pi / n
    z, db, rho, sin_k, cos_k = _discs(tool, depth, n_discs)  # (..., m)
    lag = z * np.tan(np.radians(tool.helix_deg)) / tool.radius_mm
    k = np.arange(n)
    ang = (phi[..., None, None] + k[:, None] * pitch - lag[..., None, :]) % (2 * np.pi)
    e = tool.runout_mm if cut.runout_mm is None else cut.runout_mm
    lam = np.radians(cut.runout_angle_deg)
    radius_k = e * np.cos(lam - k * pitch)
    # The tooth that cut the surface tooth k now meets is the one a pitch ahead, k + 1 (it
    # reached this angle a tooth period earlier): its radius, not tooth k - 1's, sets the chip.
    d_radius = radius_k - np.roll(radius_k, -1)
    sk, ck = sin_k[..., None, :], cos_k[..., None, :]
    h = (fz[..., None, None] * np.sin(ang) + d_radius[:, None]) * sk
    st = np.radians(np.asarray(cut.entry_deg, float))
    ex = np.radians(np.asarray(cut.exit_deg, float))
    st = np.broadcast_to(st, shape)[..., None, None]
    ex = np.broadcast_to(ex, shape)[..., None, None]
    on = (ang >= st) & (ang <= ex) & (h > 0)
    w = np.where(on, db[..., None, :], 0.0)
    hw = w * h
    sp, cp = np.sin(ang), np.cos(ang)
    # Unit force directions on the workpiece (minus the force on the tool, Lee & Altintas).
    dir_t = np.stack([cp, -sp, np.zeros_like(sp)], axis=-1)
    dir_r = np.stack([sk * sp, sk * cp, -np.broadcast_to(ck, sp.shape)], axis=-1)
    dir_a = np.stack([ck * sp, ck * cp, np.broadcast_to(sk, sp.shape)], axis=-1)
    design = np.empty(shape + (3, 6))
    for j, d in enumerate((dir_t, dir_r, dir_a)):
        design[..., :, j] = np.einsum("...km,...kmi->...i", hw, d)
        design[..., :, 3 + j] = np.einsum("...km,...kmi->...i", w, d)
    return _rotate_feed(design, cut.feed_angle_deg)


def element_forces(
    theta_rad: ArrayLike, h_mm: ArrayLike, dz_mm: ArrayLike, kappa_rad: ArrayLike,
    coef: EndMillCoefficients,
) -> np.ndarray:  # fmt: skip
    """Force of one edge element on the workpiece, model frame (X feed, Y, Z up), shape (..., 3) N.

    ``theta_rad`` the element's angular position, ``h_mm`` its chip thickness (normal to the edge,
    already including sin(kappa)), ``dz_mm`` the slice height, ``kappa_rad`` the axial immersion
    (pi/2 on a flat flank). Chip width db = dz / sin(kappa); an element with h <= 0 gives 0.
    """
    th, h, dz, k = np.broadcast_arrays(
        *(np.asarray(a, float) for a in (theta_rad, h_mm, dz_mm, kappa_rad))
    )
    sk, ck = np.sin(k), np.cos(k)
    cut = h > 0
    db = np.where(cut, dz / np.where(sk > 1e-12, sk, 1.0), 0.0)
    hh = np.where(cut, h, 0.0)
    ft = coef.Ktc_n_mm2 * hh * db + coef.Kte_n_mm * db
    fr = coef.Krc_n_mm2 * hh * db + coef.Kre_n_mm * db
    fa = coef.Kac_n_mm2 * hh * db + coef.Kae_n_mm * db
    sp, cp = np.sin(th), np.cos(th)
    return np.stack(
        [
            ft * cp + fr * sk * sp + fa * ck * sp,
            -ft * sp + fr * sk * cp + fa * ck * cp,
            -fr * ck + fa * sk,
        ],
        axis=-1,
    )


def _rotate_feed(design: np.ndarray, feed_angle_deg: ArrayLike) -> np.ndarray:
    a = np.radians(np.asarray(feed_angle_deg, float))
    if not np.any(a):
        return design
    c, s = np.cos(a)[..., None], np.sin(a)[..., None]
    x, y = design[..., 0, :].copy(), design[..., 1, :].copy()
    out = design.copy()
    out[..., 0, :] = c * x - s * y
    out[..., 1, :] = s * x + c * y
    return out


def coefficient_vector(coef: EndMillCoefficients) -> np.ndarray:
    """Parameter vector (6,) in the order of :data:`PARAMETERS`."""
    return np.array([getattr(coef, name) for name in PARAMETERS], float)


def coefficients_from_vector(p: ArrayLike) -> EndMillCoefficients:
    return EndMillCoefficients(**{name: float(v) for name, v in zip(PARAMETERS, np.asarray(p))})


def endmill_forces(
    phi_rad: ArrayLike, tool: EndMill, coef: EndMillCoefficients, cut: EndMillCut,
    n_discs: int = 24,
) -> np.ndarray:  # fmt: skip
    """Workpiece forces in machine axes, shape (..., 3), N, at tool rotation angles ``phi_rad``."""
    design = endmill_design(phi_rad, tool, cut, n_discs)
    out: NDArray[np.float64] = design @ coefficient_vector(coef)
    return out


def mean_force_design(tool: EndMill, cut: EndMillCut, n_phi: int = 720) -> np.ndarray:
    """Per-revolution mean force per unit coefficient, shape (..., 3, 6) over the cut's fields.

    Flat end mills without runout use Altintas' closed forms (valid for any immersion and helix:
    the helix only delays discs, which a whole-revolution mean does not see); other tools average
    :func:`endmill_design` over ``n_phi`` angles of one revolution.
    """
    _check_tool(tool)
    e = tool.runout_mm if cut.runout_mm is None else cut.runout_mm
    fz, a = np.broadcast_arrays(np.asarray(cut.fz_mm, float), np.asarray(cut.depth_mm, float))
    st = np.broadcast_to(np.radians(np.asarray(cut.entry_deg, float)), fz.shape)
    ex = np.broadcast_to(np.radians(np.asarray(cut.exit_deg, float)), fz.shape)
    if tool.kind == "flat" and e == 0:
        n = tool.flutes
        def c2(f: Callable[[NDArray[np.float64]], NDArray[np.float64]]) -> NDArray[np.float64]:
            return f(ex) - f(st)

        kc = n * a * fz / (8 * np.pi)
        ke = n * a / (2 * np.pi)
        d = np.zeros(fz.shape + (3, 6))
        # Workpiece force = minus Altintas' tool-force averages.
        d[..., 0, 0] = -kc * c2(lambda p: np.cos(2 * p))
        d[..., 0, 1] = kc * c2(lambda p: 2 * p - np.sin(2 * p))
        d[..., 1, 0] = -kc * c2(lambda p: 2 * p - np.sin(2 * p))
        d[..., 1, 1] = -kc * c2(lambda p: np.cos(2 * p))
        d[..., 2, 2] = -ke * fz * c2(np.cos)
        d[..., 0, 3] = ke * c2(np.sin)
        d[..., 0, 4] = -ke * c2(np.cos)
        d[..., 1, 3] = ke * c2(np.cos)
        d[..., 1, 4] = ke * c2(np.sin)
        d[..., 2, 5] = ke * c2(lambda p: p)
        return _rotate_feed(d, cut.feed_angle_deg)
    phi = np.linspace(0.0, 2 * np.pi, n_phi, endpoint=False)
    phi = phi.reshape((n_phi,) + (1,) * fz.ndim)
    out: NDArray[np.float64] = endmill_design(phi, tool, cut).mean(axis=0)
    return out


def peak_force(
    tool: EndMill, coef: EndMillCoefficients, cut: EndMillCut, n_phi: int = 360
) -> np.ndarray:
    """Largest resultant force over one revolution, N, shape of the cut's broadcast fields."""
    shape = np.broadcast_shapes(np.shape(cut.fz_mm), np.shape(cut.depth_mm))
    phi = np.linspace(0.0, 2 * np.pi / tool.flutes, n_phi, endpoint=False)
    phi = phi.reshape((n_phi,) + (1,) * len(shape))
    f = endmill_forces(phi, tool, coef, cut)
    out: NDArray[np.float64] = np.linalg.norm(f, axis=-1).max(axis=0)
    return out
