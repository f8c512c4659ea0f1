"""Tool geometry for 5-axis orientation (seed 002 sections 2 and 4).

* The local frame (b, f, n) at a CC point, the advance angle alpha about b and the tilt angle beta
  about f, and from them the tool axis u and the cutter position (seed 002 Fig. 1-2).
* Szende's curvature K of the tool's swept surface in the plane normal to the feed (eq 8).
* The tool system (cutter, holder, spindle nose) as a solid of revolution about u, with the exact
  signed distance of any point to it (used by the energy's inside test and by the independent
  collision check).

Angle conventions (radians inside, degrees in configs): ``u = R_f(beta) R_b(alpha) n``, so
``u = cos(alpha) (cos(beta) n - sin(beta) b) + sin(alpha) f`` and ``u . n = cos(alpha) cos(beta)``,
``u . f = sin(alpha)``: a positive advance angle leans the tool forward along the feed.

Note on eq 8 as printed: ``K = X / (sign(sin a) R sin^2 a - r X)`` with
``X = (1 - (cos a cos b)^2)^(3/2)``. Taken literally with R the tool radius it does not give the
ball's 1/R (the check the paper itself states, "r = R: ball end mill"). The silhouette of a tilted
fillet cutter seen along f is its corner-centre circle (radius R - r) projected to an ellipse,
offset by r; its radius of curvature at the lowest point is ``(R - r) sin^2 a / X + r``. So here

    K = X / ((R - r) sin^2 a + r X),

which is 1/R for a ball at any angles, sin(a)/R for a flat end mill at beta = 0 and
1/(R sin^2 a) at beta = 90 deg; the tests check it against a numerically projected silhouette.
Sign: K and the part curvature kappa are both measured against the part normal n (kappa > 0 on a
concave floor), so the local no-overcut condition is K - kappa >= 0 -- the paper's
"kappa - K > 0" with both curvatures measured from inside the material.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from analysis.config import EndMill
from analysis.forces import ENDMILL
from planning.errors import PlanningError


def local_frame(normal: np.ndarray, tangent: np.ndarray) -> tuple[np.ndarray, ...]:
    """Unit (b, f, n), each shape (m, 3), from surface normals and feed tangents (m, 3).

    f is the feed tangent projected on the tangent plane; b = n x f (seed 002 Fig. 1).
    """
    n = normal / np.linalg.norm(normal, axis=-1, keepdims=True)
    f = tangent - (tangent * n).sum(-1, keepdims=True) * n
    fl = np.linalg.norm(f, axis=-1, keepdims=True)
    if np.any(fl < 1e-12):
        raise PlanningError("feed direction is parallel to the surface normal: no local frame")
    f = f / fl
    b: np.ndarray = np.cross(n, f)
    return b, f, n


def tool_axis(
    alpha: npt.ArrayLike, beta: npt.ArrayLike, b: np.ndarray, f: np.ndarray, n: np.ndarray
) -> np.ndarray:
    """Unit tool axis u for advance alpha and tilt beta (rad); broadcasts to shape (..., 3)."""
    ca, sa = np.cos(alpha)[..., None], np.sin(alpha)[..., None]
    cb, sb = np.cos(beta)[..., None], np.sin(beta)[..., None]
    u: npt.NDArray[np.float64] = ca * (cb * n - sb * b) + sa * f
    return u


def tool_axis_grad(
    alpha: npt.ArrayLike, beta: npt.ArrayLike, b: np.ndarray, f: np.ndarray, n: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(du/dalpha, du/dbeta), each shape (..., 3)."""
    ca, sa = np.cos(alpha)[..., None], np.sin(alpha)[..., None]
    cb, sb = np.cos(beta)[..., None], np.sin(beta)[..., None]
    return -sa * (cb * n - sb * b) + ca * f, ca * (-sb * n - cb * b)


def szende_K(alpha: npt.ArrayLike, beta: npt.ArrayLike, R_mm: float, r_mm: float) -> np.ndarray:
    """Curvature of the swept surface in the plane normal to the feed, 1/mm (eq 8, corrected).

    alpha, beta in rad (broadcast). Flat end mill at alpha = 0: 0 when beta = 0 too (the flat
    bottom sweeps a plane), +inf otherwise (the bottom edge is seen edge-on: a sharp corner).
    """
    alpha, beta = np.broadcast_arrays(np.asarray(alpha, float), np.asarray(beta, float))
    c = np.cos(alpha) * np.cos(beta)
    X = np.clip(1.0 - c * c, 0.0, None) ** 1.5
    s2 = np.sin(alpha) ** 2
    den = (R_mm - r_mm) * s2 + r_mm * X
    with np.errstate(divide="ignore", invalid="ignore"):
        K = X / den
    # 0/0 at alpha = beta = 0: a ball is still a ball (1/R); a flat or fillet bottom lies
    # parallel to the surface and sweeps a plane (0).
    K = np.where((den <= 0) & (X <= 1e-300), 1.0 / R_mm if r_mm == R_mm else 0.0, K)
    K = np.where((den <= 0) & (X > 1e-300), np.inf, K)
    return K


def szende_K_grad(alpha: float, beta: float, R_mm: float, r_mm: float) -> np.ndarray:
    """(dK/dalpha, dK/dbeta) of :func:`szende_K` in 1/mm per rad, scalar angles (0 at the
    singular 0/0 point)."""
    c = np.cos(alpha) * np.cos(beta)
    q = max(1.0 - c * c, 0.0)
    X = q**1.5
    s2 = np.sin(alpha) ** 2
    D = (R_mm - r_mm) * s2 + r_mm * X
    if D <= 1e-150:  # the singular 0/0 corner (or D^2 would underflow)
        return np.zeros(2)
    dc = np.array([-np.sin(alpha) * np.cos(beta), -np.cos(alpha) * np.sin(beta)])
    dX = -3.0 * np.sqrt(q) * c * dc
    dD = np.array([(R_mm - r_mm) * np.sin(2 * alpha), 0.0]) + r_mm * dX
    grad: npt.NDArray[np.float64] = (dX * D - X * dD) / (D * D)
    return grad


def cutter_position(
    p: np.ndarray, n: np.ndarray, u: np.ndarray, R_mm: float, r_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """Tool tip (bottom centre on the axis) and cutter centre for contact at p, shape (..., 3).

    The contact point is where the cutter's outward normal is -n: the corner-circle centre is
    q = p + r n, and the ring centre sits (R - r) from q towards the axis. The cutter centre is
    tip + r u (the ball centre for a ball end mill). When u is parallel to n the flat bottom is
    centred on p.
    """
    q = p + r_mm * n
    radial = (n * u).sum(-1, keepdims=True) * u - n
    rl = np.linalg.norm(radial, axis=-1, keepdims=True)
    w = np.where(rl > 1e-12, radial / np.where(rl > 1e-12, rl, 1.0), 0.0)
    centre = q - (R_mm - r_mm) * w
    return centre - r_mm * u, centre


# ----------------------------------------------------------------------------------------------
# Tool system as a solid of revolution
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ToolSystem:
    """Cutter, holder and spindle nose as coaxial solids of revolution about the tool axis.

    Heights z are measured from the tool tip along u (mm). The cutter is a fillet cylinder of
    radius R and corner radius r from z = 0 to ``cutter_length_mm``; the holder and the spindle
    nose are cylinders stacked above it.
    """

    R_mm: float
    r_mm: float
    cutter_length_mm: float
    holder_radius_mm: float
    holder_length_mm: float
    nose_radius_mm: float
    nose_length_mm: float
    name: str = "tool"

    def __post_init__(self) -> None:
        if not self.R_mm > 0:
            raise PlanningError(f"{self.name}: tool radius R = {self.R_mm} mm must be > 0 mm")
        if not 0 <= self.r_mm <= self.R_mm:
            raise PlanningError(
                f"{self.name}: corner radius r = {self.r_mm} mm with tool radius R = "
                f"{self.R_mm} mm: need 0 <= r <= R (R < r is not a cutter)"
            )
        for field in ("cutter_length_mm", "holder_radius_mm", "holder_length_mm"):
            if not getattr(self, field) > 0:
                raise PlanningError(f"{self.name}: {field} = {getattr(self, field)} must be > 0 mm")

    @classmethod
    def from_endmill(cls, tool: EndMill, name: str = "tool") -> ToolSystem:
        """From a validated tool config (configs/tools.toml); face mills are not for 5-axis."""
        if not ENDMILL.describes(tool):
            raise PlanningError(f"{name}: 5-axis orientation needs an end mill, got {tool.kind}")
        h = tool.holder
        return cls(
            R_mm=tool.radius_mm,
            r_mm=tool.corner_radius_mm,
            cutter_length_mm=tool.length_mm,
            holder_radius_mm=h.diameter_mm / 2,
            holder_length_mm=h.length_mm,
            nose_radius_mm=h.spindle_nose_diameter_mm / 2,
            nose_length_mm=h.spindle_nose_length_mm,
            name=name,
        )

    @property
    def total_length_mm(self) -> float:
        return self.cutter_length_mm + self.holder_length_mm + self.nose_length_mm

    @property
    def gauge_length_mm(self) -> float:
        """Tool tip to spindle nose face, mm (cutter + holder)."""
        return self.cutter_length_mm + self.holder_length_mm

    def parts(self) -> tuple[tuple[str, float, float, float], ...]:
        """(name, z0_mm, z1_mm, radius_mm) of cutter, holder and spindle nose."""
        z1 = self.cutter_length_mm
        z2 = z1 + self.holder_length_mm
        return (
            ("cutter", 0.0, z1, self.R_mm),
            ("holder", z1, z2, self.holder_radius_mm),
            ("spindle nose", z2, z2 + self.nose_length_mm, self.nose_radius_mm),
        )

    def signed_distance(self, rho: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (mm, < 0 inside) to the tool system, and which part is nearest.

        rho : distance from the axis, z : height above the tip, same shapes (mm). Exact outside
        the solid (distance to a union = min of distances); inside it is the depth below the
        nearest part's surface. Part index: 0 cutter, 1 holder, 2 spindle nose.
        """
        d_cut = self.cutter_distance(rho, z)
        parts = self.parts()
        d_h = _sd_cylinder(rho, z, parts[1][3], parts[1][1], parts[1][2])
        d_n = _sd_cylinder(rho, z, parts[2][3], parts[2][1], parts[2][2])
        stack = np.stack([d_cut, d_h, d_n])
        which = np.argmin(stack, axis=0)
        return np.take_along_axis(stack, which[None], 0)[0], which

    def cutter_distance(self, rho: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Signed distance (mm, < 0 inside) to the cutter alone; rho, z as signed_distance."""
        R, r, L = self.R_mm, self.r_mm, self.cutter_length_mm
        # Cutter = cylinder R on [r, L] U cylinder (R - r) on [0, L] U torus tube (R - r, r).
        d_cyl = _sd_cylinder(rho, z, R, r, L)
        d_core = _sd_cylinder(rho, z, R - r, 0.0, L) if R > r else np.full_like(rho, np.inf)
        d_tor = np.hypot(rho - (R - r), z - r) - r if r > 0 else np.full_like(rho, np.inf)
        d: npt.NDArray[np.float64] = np.minimum(np.minimum(d_cyl, d_core), d_tor)
        return d

    def stations(self, step_frac: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
        """Spheres covering the tool system: heights z (k,) mm and radii (k,) mm.

        Each part of radius a is covered by spheres centred on the axis every ``step_frac * a``
        with radius sqrt(a^2 + (step/2)^2), so every point of the solid lies in some sphere.
        """
        zs, rs = [], []
        for _, z0, z1, a in self.parts():
            step = max(step_frac * a, 1e-3)
            k = max(1, int(np.ceil((z1 - z0) / step)))
            h = (z1 - z0) / k
            zs.append(z0 + h * (np.arange(k) + 0.5))
            rs.append(np.full(k, np.hypot(a, h / 2)))
        return np.concatenate(zs), np.concatenate(rs)

    def profile(self, n_arc: int = 12) -> np.ndarray:
        """The meridian outline (rho, z) from the tip up, shape (m, 2) mm, for drawing."""
        R, r, L = self.R_mm, self.r_mm, self.cutter_length_mm
        t = np.linspace(-np.pi / 2, 0, n_arc)
        arc = np.stack([R - r + r * np.cos(t), r + r * np.sin(t)], 1)
        pts = [[0.0, 0.0], *arc.tolist(), [R, L]]
        for _, z0, z1, a in self.parts()[1:]:
            pts += [[a, z0], [a, z1]]
        pts.append([0.0, self.total_length_mm])
        return np.asarray(pts)


def _sd_cylinder(
    rho: npt.NDArray[np.float64], z: npt.NDArray[np.float64], a: float, z0: float, z1: float
) -> npt.NDArray[np.float64]:
    """Signed distance to the solid cylinder of radius a between heights z0 < z1."""
    dx = rho - a
    dz = np.maximum(z0 - z, z - z1)
    out = np.hypot(np.maximum(dx, 0), np.maximum(dz, 0))
    return out + np.minimum(np.maximum(dx, dz), 0)


def meridian(points: np.ndarray, tip: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rho, z) of points (m, 3) relative to an axis through ``tip`` along unit ``u``, mm."""
    d = points - tip
    z = d @ u
    rho = np.sqrt(np.maximum((d * d).sum(1) - z * z, 0.0))
    return rho, z
