"""Face-milling forces simulated in the time domain from seed 003's equations, written apart from
cutlab's model code: it shares nothing with ``analysis.forces`` or ``analysis.identify`` (it
imports neither, nor their helpers; tests/test_layers.py holds it to that), so a mistake made in
both the model and the fit cannot hide behind the data this module makes.

What it computes, for each insert at each sample:

- The insert (seed 003 2.2.2): the projected tool angles gamma_L (lead), gamma_R (radial rake),
  gamma_A (axial rake) fix the insert axes T' (rake-face normal), R' (minor edge), A' (major edge)
  in the tool's T, R, A axes through the column form of eq 9; the rotation angles theta_1..3 are
  found here by solving the three orthogonality conditions numerically (not from eqs 5-7). The
  edge of a square insert (minor edge, nose arc of radius r, major edge) is drawn on the rake face
  and swept about the spindle axis: each edge point gives a swept radius rho(z) and a small angular
  lead (its T offset over the radius), on the inner (minor-edge) and outer (major-edge) branches of
  the cup the edge makes in the RA plane.
- The undeformed chip, sliced axially (graded slices, fine near the floor where the nose makes the
  cusp): along the ray of each slice from the cutter axis, the chip is the current insert's swept
  interval [rho_in(z), rho_out(z)] inside the workpiece (its width across the feed, its start and
  end along the feed, its top) less what the earlier passes swept: each of the previous ``2 Z``
  passes, its cutter centre D = (feed per revolution x angle gap / 2 pi) behind, sweeps the points
  at distance t with rho_in <= |t u + D e_x| <= rho_out (exact circles, so eq 1's chip thickness
  R + f sin - sqrt(R^2 - f^2 cos^2) comes out of it, not in). Radial runout moves an insert's
  radii, axial runout its heights, both per insert; the cutter's height may change with time
  (plunge, retract) and each pass is taken at its own height.
- Forces per slice by seed 003 eqs 3-4 with the axial pair cutlab adds: on the rake face,
  dF_T' = P_T dl + K_T dS, dF_R' = P_R dl + K_R K_T dS, dF_A' = P_A dl + K_A K_T dS, with dS the
  slice's chip area projected on the rake face (the RA-plane area over cos nu, nu the angle
  between the RA and R'A' planes: eq 13) and dl the true length of the edge in contact with the
  chip in the slice (outer branch wherever the slice cuts; inner branch where no earlier pass
  covers it, i.e. under the cusp: eq 16). Each slice's force is turned into T, R, A with its
  insert axes and into the dynamometer's X' (feed), Y', Z' with eqs 14 and 2 at the slice's own
  angle, and summed over slices and inserts; an insert may carry a force factor (scatter).
- Optionally the dynamometer's modes (1-DOF per axis, unit static gain), offset, drift, noise.

Angles: an insert at angle phi sits at X' = R sin(phi), Y' = R cos(phi) from the cutter axis (phi
from +Y' towards +X', the feed; M3 turns it clockwise seen from above, phi grows with time). This is
what eqs 2 and 14 say: X' = F_T cos + F_R sin, Y' = -F_T sin + F_R cos, Z' = F_A.

Entry points: :func:`simulate` (a whole run: air, entry into the block, steady cut, retract, air),
:func:`insert_forces` (the digital twin's per-insert forces at given angles, depths and feeds).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
from scipy import signal

from rig.sim._facemill_edge import Edge, edge_of
from rig.sim._facemill_edge import insert_axes as insert_axes  # the tests' axes check

__all__ = ["COEFFICIENTS", "Edge", "Record", "Run", "edge_of", "insert_forces", "simulate"]

#: The coefficient names (K_R, K_A ratios to K_T; P in N/mm; K_T in N/mm^2).
COEFFICIENTS = ("K_T_n_mm2", "K_R", "P_T_n_mm", "P_R_n_mm", "K_A", "P_A_n_mm")


def _coef(coef: Any) -> dict[str, float]:
    if isinstance(coef, dict):
        return {k: float(coef[k]) for k in COEFFICIENTS}
    return {k: float(getattr(coef, k)) for k in COEFFICIENTS}


def _interp_or(z: np.ndarray, zb: np.ndarray, vb: np.ndarray, above: float) -> np.ndarray:
    """Branch value at heights z; ``above`` above the branch's top (the edge ends), first value
    below its bottom."""
    out = np.interp(z, zb, vb)
    return np.where(z > zb[-1], above, out)


def _ray_reach(rho: np.ndarray, d_mm: np.ndarray, s: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distance t along the ray (sin, cos of its angle: s, c) from the current cutter axis to the
    circle of radius rho about a centre ``d_mm`` behind it (along -X'): |t u + D e_x| = rho, the
    root t > 0; rho <= -_FAR (no edge there) stays as it is."""
    disc = rho**2 - (d_mm * c) ** 2
    return np.where(rho > -_FAR / 2, -d_mm * s + np.sqrt(np.maximum(disc, 0.0)), rho)


def _uncovered(lo: np.ndarray, hi: np.ndarray, plo: np.ndarray, phi_: np.ndarray) -> np.ndarray:
    """Length of [lo, hi] (...) not covered by the union of intervals [plo, phi_] (..., M)."""
    a = np.clip(plo, lo[..., None], hi[..., None])
    b = np.clip(phi_, lo[..., None], hi[..., None])
    order = np.argsort(a, axis=-1)
    a = np.take_along_axis(a, order, -1)
    b = np.take_along_axis(b, order, -1)
    covered = np.zeros_like(lo)
    reach = lo.copy()
    for j in range(a.shape[-1]):
        covered += np.maximum(b[..., j] - np.maximum(a[..., j], reach), 0.0)
        reach = np.maximum(reach, b[..., j])
    return np.maximum(hi - lo, 0.0) - covered


#: "no edge here" / "no bound": a radius far beyond any cutter, mm (finite: it enters differences)
_FAR = 1e6

#: Slice boundaries as fractions of the local depth: dense near the floor (the nose, the cusp).
_GRID = np.unique(np.concatenate([np.linspace(0, 1, 33) ** 3, np.linspace(0, 1, 21)]))


def _forces(edge: Edge, coef: dict[str, float], psi0: np.ndarray, depth: np.ndarray,
            d_prev: np.ndarray, dz_prev: np.ndarray, dr_prev: np.ndarray,
            window: tuple[np.ndarray, ...] | None, scale: np.ndarray) -> np.ndarray:  # fmt: skip
    """Forces (m, 3) N on the workpiece, dynamometer axes, of m insert positions.

    psi0 (m,) the insert's angle (its lowest point); depth (m,) the stock top above its lowest
    point (mm); d_prev (m, M) how far behind the cutter centre was at each earlier pass (mm);
    dz_prev (m, M) that pass's lowest point above this one's (mm); dr_prev (m, M) its radius
    minus this one's (mm); window: None (the whole ray is workpiece) or (y_lo, y_hi, x_lo, x_hi,
    x_c) (m,) the workpiece across and along the feed and the cutter centre, mm; scale (m,).
    """
    m = len(psi0)
    if m == 0:
        return np.zeros((0, 3))
    depth = np.clip(depth, 0.0, edge.max_depth_mm)
    # everything at the slice boundaries: the chip's width is integrated by trapezoids and an
    # edge's contact, where it starts or ends inside a slice, by the linear zero of its margin
    z = depth[:, None] * _GRID[None, :]  # (m, s+1)
    dz = np.diff(z, axis=1)
    rho_o = np.interp(z, edge.z_out, edge.rho_out)
    rho_i = _interp_or(z, edge.z_in, edge.rho_in, -_FAR)
    psi = psi0[:, None] + np.interp(z, edge.z_out, edge.lead_out)  # the ray at that height
    sn, cs = np.sin(psi), np.cos(psi)
    # earlier passes at this height (their own heights: z + this - theirs)
    zp = z[..., None] - dz_prev[:, None, :]
    below = zp < 0  # under that pass's lowest point: it swept nothing here
    dp = d_prev[:, None, :]
    rp_o = np.interp(zp, edge.z_out, edge.rho_out) + dr_prev[:, None, :]
    rp_i = _interp_or(zp, edge.z_in, edge.rho_in, -_FAR) + dr_prev[:, None, :]
    p_hi = np.where(below, -_FAR, _ray_reach(rp_o, dp, sn[..., None], cs[..., None]))
    p_lo = np.where(below, -_FAR, _ray_reach(rp_i, dp, sn[..., None], cs[..., None]))
    lo, hi = rho_i, rho_o
    w_lo = np.full_like(lo, -_FAR)
    w_hi = np.full_like(lo, _FAR)
    if window is not None:
        y_lo, y_hi, x_lo, x_hi, x_c = (np.asarray(w, float)[:, None] for w in window)
        # a ray along a window's edge never happens on the slices' angles; keep the sign
        c = np.where(np.abs(cs) < 1e-12, 1e-12, cs)
        s = np.where(np.abs(sn) < 1e-12, 1e-12, sn)
        ty = np.sort(np.stack([y_lo / c, y_hi / c]), axis=0)
        tx = np.sort(np.stack([(x_lo - x_c) / s, (x_hi - x_c) / s]), axis=0)
        w_lo, w_hi = np.maximum(ty[0], tx[0]), np.minimum(ty[1], tx[1])
        lo, hi = np.maximum(lo, w_lo), np.minimum(hi, w_hi)
    width = _uncovered(lo, hi, p_lo, p_hi)  # chip along the ray, mm (RA plane)
    dS = 0.5 * (width[:, 1:] + width[:, :-1]) * dz / edge.cos_nu

    def contact(t: np.ndarray) -> np.ndarray:
        """Share of each slice where the edge at t touches uncut material."""
        free = np.min(np.maximum(p_lo - t[..., None], t[..., None] - p_hi), axis=-1)
        g = np.minimum(np.minimum(free, width), np.minimum(t - w_lo, w_hi - t))
        g0, g1 = g[:, :-1], g[:, 1:]
        with np.errstate(invalid="ignore", divide="ignore"):
            part = np.where(g0 > 0, g0, g1) / (np.abs(g0) + np.abs(g1))
        return np.where((g0 > 0) & (g1 > 0), 1.0, np.where((g0 > 0) ^ (g1 > 0), part, 0.0))

    ds_o = np.diff(np.interp(z, edge.z_out, edge.s_out), axis=1)
    ds_i = np.diff(np.interp(np.minimum(z, edge.z_in[-1]), edge.z_in, edge.s_in), axis=1)
    dl = contact(rho_o) * ds_o + contact(rho_i) * ds_i
    psi = 0.5 * (psi[:, 1:] + psi[:, :-1])
    k = coef
    f_ins = np.stack([k["P_T_n_mm"] * dl + k["K_T_n_mm2"] * dS,
                      k["P_R_n_mm"] * dl + k["K_R"] * k["K_T_n_mm2"] * dS,
                      k["P_A_n_mm"] * dl + k["K_A"] * k["K_T_n_mm2"] * dS], axis=-1)  # fmt: skip
    f_tra = f_ins @ edge.axes.T  # (m, s, 3): F_T, F_R, F_A
    # eq 14 inverted (E is its own inverse), then eq 2: X' = c F_T + s F_R, Y' = -s F_T + c F_R
    c, s = np.cos(psi), np.sin(psi)
    fx = (c * f_tra[..., 0] + s * f_tra[..., 1]).sum(axis=1)
    fy = (-s * f_tra[..., 0] + c * f_tra[..., 1]).sum(axis=1)
    fz = f_tra[..., 2].sum(axis=1)
    return np.stack([fx, fy, fz], axis=-1) * scale[:, None]


def _edge(tool: Any) -> Edge:
    return edge_of(float(tool.diameter_mm) / 2, float(tool.lead_angle_deg),
                   float(tool.radial_rake_deg), float(tool.axial_rake_deg),
                   float(tool.nose_radius_mm), float(tool.insert_edge_length_mm))  # fmt: skip


def _insert_angles(tool: Any) -> np.ndarray:
    z = int(tool.inserts)
    if getattr(tool, "insert_angles_deg", None) is None:
        return 2 * np.pi * np.arange(z) / z
    return np.radians(np.asarray(tool.insert_angles_deg, float)) % (2 * np.pi)


def _direct(theta: np.ndarray, insert: np.ndarray, fz: np.ndarray, depth: np.ndarray, tool: Any,
            coef: dict[str, float], sides: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    a = _insert_angles(tool)
    win = None
    if sides is not None:  # the block's sides across the feed, Y' (m, 2); no ends along it
        m = len(theta)
        win = (sides[:, 0], sides[:, 1], np.full(m, -_FAR), np.full(m, _FAR), np.zeros(m))
    z = len(a)
    e = float(getattr(tool, "runout_mm", 0.0) or 0.0) * np.cos(a)
    # angle gaps back to the earlier inserts (over two turns) and who they are
    back = (a[None, :] - a[:, None]) % (2 * np.pi)  # [k, j]: insert j was here that much earlier
    back[back == 0] = 2 * np.pi
    both = np.concatenate([back, back + 2 * np.pi], axis=1)
    order = np.argsort(both, axis=1)[:, : 2 * z]
    gaps = np.take_along_axis(both, order, 1)
    d_prev = (fz * z)[:, None] * gaps[insert] / (2 * np.pi)
    dr = e[order[insert] % z] - e[insert][:, None]
    edge = _edge(tool)
    if e.any():
        out = np.zeros((len(theta), 3))
        for k in np.unique(insert):
            i = insert == k
            wi = None if win is None else tuple(w[i] for w in win)
            out[i] = _forces_offset(edge, coef, theta[i], depth[i], d_prev[i],
                                    np.zeros_like(d_prev[i]), dr[i], wi, np.ones(i.sum()),
                                    float(e[k]))  # fmt: skip
        return out
    return _forces(edge, coef, theta, depth, d_prev, np.zeros_like(d_prev), dr, win,
                   np.ones(len(theta)))  # fmt: skip


#: The twin's tables: forces over the front half turn every 0.1 deg, per insert, feed per tooth
#: (to 1e-5 mm) and depth (to 1e-4 mm); linear in between (measured against the direct
#: computation: 0.01 % of the peak).
_TABLE_STEP_DEG = 0.1
_TABLE_KEYS_PER_CALL = 8


@lru_cache(maxsize=256)
def _table(tool_key: tuple, coef_key: tuple, insert: int, fz: float, depth: float,
           sides: tuple[float, float] | None = None) -> np.ndarray:  # fmt: skip
    tool, coef = _ToolKey(*tool_key), dict(zip(COEFFICIENTS, coef_key))
    th = np.radians(np.arange(0.0, 180.0 + _TABLE_STEP_DEG / 2, _TABLE_STEP_DEG))
    n = len(th)
    sd = None if sides is None else np.tile(np.asarray(sides, float), (n, 1))
    return _direct(th, np.full(n, insert), np.full(n, fz), np.full(n, depth), tool, coef, sd)


@dataclass(frozen=True)
class _ToolKey:
    diameter_mm: float
    inserts: int
    lead_angle_deg: float
    radial_rake_deg: float
    axial_rake_deg: float
    nose_radius_mm: float
    insert_edge_length_mm: float
    insert_angles_deg: tuple | None
    runout_mm: float

    @classmethod
    def of(cls, tool: Any) -> tuple:
        ang = getattr(tool, "insert_angles_deg", None)
        return (float(tool.diameter_mm), int(tool.inserts), float(tool.lead_angle_deg),
                float(tool.radial_rake_deg), float(tool.axial_rake_deg),
                float(tool.nose_radius_mm), float(tool.insert_edge_length_mm),
                None if ang is None else tuple(float(x) for x in ang),
                float(getattr(tool, "runout_mm", 0.0) or 0.0))  # fmt: skip


def insert_forces(
    theta_rad: np.ndarray,
    insert: np.ndarray,
    fz_mm: np.ndarray,
    depth_mm: np.ndarray,
    tool: Any,
    coef: Any,
    exact: bool = False,
    sides_mm: np.ndarray | None = None,
) -> np.ndarray:
    """Forces (m, 3) N of single inserts (the digital twin's call): insert number ``insert`` (m,)
    at immersion angle ``theta_rad`` (m,), the stock top ``depth_mm`` (m,) above its lowest point,
    the cutter at ``fz_mm`` (m,) per tooth; dynamometer axes with the feed along X'. The earlier
    passes are the other inserts at the same depth; ``tool.runout_mm`` (an eccentricity: insert k
    at radius R + e cos a_k) moves the radii. The workpiece is everywhere along the ray (the twin
    decides which inserts are in it), or between the block's sides ``sides_mm`` (m, 2): Y' low
    and high, mm from the cutter axis, each slice entering and leaving on its own ray. Steady
    conditions are tabulated over the angle (see ``_table``) unless ``exact`` or a call holds
    more than a few distinct conditions."""
    th = np.asarray(theta_rad, float)
    k_ins = np.asarray(insert, int)
    fz = np.asarray(fz_mm, float)
    depth = np.asarray(depth_mm, float)
    k = _coef(coef)
    sd = None if sides_mm is None else np.asarray(sides_mm, float).reshape(-1, 2)
    if exact or not th.size:
        return _direct(th, k_ins, fz, depth, tool, k, sd)
    fq, dq = np.round(fz, 5), np.round(depth, 4)
    cols = [k_ins, fq, dq] + ([] if sd is None else [np.round(sd[:, 0], 4), np.round(sd[:, 1], 4)])
    keys, inv = np.unique(np.stack(cols, axis=1), axis=0, return_inverse=True)
    if len(keys) > _TABLE_KEYS_PER_CALL:
        return _direct(th, k_ins, fz, depth, tool, k, sd)
    out = np.zeros((len(th), 3))
    tkey, ckey = _ToolKey.of(tool), tuple(k[c] for c in COEFFICIENTS)
    grid = np.radians(np.arange(0.0, 180.0 + _TABLE_STEP_DEG / 2, _TABLE_STEP_DEG))
    for j, key in enumerate(keys):
        i = inv.ravel() == j
        ins, f, d = key[:3]
        sides = None if sd is None else (float(key[3]), float(key[4]))
        tab = _table(tkey, ckey, int(ins), float(f), float(d), sides)
        for c in range(3):
            out[i, c] = np.interp(th[i], grid, tab[:, c])
    if sd is not None:
        # an insert crossing a side enters over a fraction of a degree: the table's steps would
        # cut its corners, so those angles are computed directly (1 mm and the lag as margins)
        edge = _edge(tool)
        radius = float(tool.diameter_mm) / 2
        lag = float(np.abs(edge.lead_out).max()) + 1e-3
        top = np.interp(depth, edge.z_out, edge.rho_out) + 1
        yy = np.stack([np.cos(th + s_) * r_ for s_ in (-lag, lag) for r_ in (radius - 1, top)])
        lo, hi = yy.min(axis=0), yy.max(axis=0)
        near = ((lo < sd[:, 0]) & (hi > sd[:, 0])) | ((lo < sd[:, 1]) & (hi > sd[:, 1]))
        if near.any():
            out[near] = _direct(th[near], k_ins[near], fz[near], depth[near], tool, k, sd[near])
    return out


@dataclass(frozen=True)
class Run:
    """A face-milling pass: the cutter crosses the edge of a block (X' >= 0, Y' across
    ``width_mm`` centred ``center_offset_mm`` from the cutter's path), cuts ``steady_s``
    after it is fully in, and lifts out at ``retract_mm_s``. Per insert: ``runout_mm`` radial,
    ``axial_runout_mm`` height (+ lower, cuts deeper) and ``scale`` a force factor."""

    fz_mm: float
    depth_mm: float
    spindle_rpm: float = 600.0
    width_mm: float = 100.0
    center_offset_mm: float = 0.0
    runout_mm: Sequence[float] = ()
    axial_runout_mm: Sequence[float] = ()
    scale: Sequence[float] = ()
    steady_s: float = 3.0
    retract_mm_s: float = 20.0


@dataclass(frozen=True)
class Record:
    """How the run is recorded: rate (Hz), air before and after (s), the dynamometer's modes
    ((Hz, zeta) per axis X', Y', Z'), offset (N), drift (N/s), white noise (N rms), rng seed,
    the cutter's angle at t = 0 (rad); ``oversample``: forces and modes are computed that many times
    faster than the record and every so many-th sample kept (the modes respond to the force
    between samples, e.g. an insert's entry between two samples)."""

    rate_hz: float = 10_000.0
    air_s: float = 0.5
    modes: Sequence[tuple[float, float]] = field(default_factory=tuple)
    offset_n: Sequence[float] = (0.0, 0.0, 0.0)
    drift_n_s: Sequence[float] = (0.0, 0.0, 0.0)
    noise_n: float = 0.0
    seed: int = 0
    phase_rad: float = 0.0
    oversample: int = 1


def _per_insert(values: Sequence[float], z: int, default: float) -> np.ndarray:
    return np.full(z, default) if len(values) == 0 else np.asarray(values, float)


def _mode(x: np.ndarray, freq_hz: float, zeta: float, rate_hz: float) -> np.ndarray:
    wn = 2 * np.pi * freq_hz
    # scipy-stubs 1.17 types a transfer function's numerator 2-D only; SciPy takes it 1-D
    b, a, _ = signal.cont2discrete(  # type: ignore[call-overload]
        ([wn**2], [1, 2 * zeta * wn, wn**2]), 1 / rate_hz, "foh"
    )
    return signal.lfilter(np.ravel(b), a, x)


def _earlier_passes(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per insert at angles ``a`` (rad), its 2 Z earlier passes: the angle gap back to each
    (rad, (Z, 2Z), nearest first) and which insert made it."""
    z = len(a)
    back = (a[None, :] - a[:, None]) % (2 * np.pi)  # [k, j]: insert j was here that much earlier
    back[back == 0] = 2 * np.pi
    both = np.concatenate([back, back + 2 * np.pi], axis=1)
    order = np.argsort(both, axis=1)[:, : 2 * z]
    return np.take_along_axis(both, order, 1), order % z


def simulate(tool: Any, coef: Any, run: Run, rec: Record = Record()) -> tuple[np.ndarray, ...]:
    """(time_s (n,), force_n (n, 3) X' Y' Z', steady (n,) bool: the cutter fully in the block at
    full depth) of a whole run: air, the cutter feeding into the block's edge at full depth, the
    steady cut, a retract, air."""
    edge = _edge(tool)
    k = _coef(coef)
    a = _insert_angles(tool)
    z = len(a)
    rad = _per_insert(run.runout_mm, z, 0.0)
    dz_k = _per_insert(run.axial_runout_mm, z, 0.0)
    sc = _per_insert(run.scale, z, 1.0)
    radius = float(tool.diameter_mm) / 2
    omega = 2 * np.pi * run.spindle_rpm / 60.0
    v = run.fz_mm * z * run.spindle_rpm / 60.0  # table feed, mm/s
    y_lo = run.center_offset_mm - run.width_mm / 2
    y_hi = run.center_offset_mm + run.width_mm / 2
    # the cutter's first touch (the top of its front at the block edge) and when the whole arc
    # is in (the arc's ends, on the nose's radius, past the edge)
    reach = float(np.interp(run.depth_mm + max(dz_k.max(), 0.0), edge.z_out, edge.rho_out))
    yy = np.clip([y_lo, y_hi], -radius, radius)
    full_in = -radius * float(np.sqrt(1 - (yy / radius) ** 2).min()) + 0.2
    x_start = -reach - 0.1
    t_in = (full_in - x_start) / v
    t_ret = t_in + run.steady_s
    t_air0 = rec.air_s
    t_end = t_ret + run.depth_mm / run.retract_mm_s + 2 * 60 / run.spindle_rpm + rec.air_s
    os_ = max(1, int(rec.oversample))
    fine_hz = rec.rate_hz * os_
    n = int(round((t_air0 + t_end) * rec.rate_hz)) * os_
    t = np.arange(n) / fine_hz
    tc = t - t_air0  # the cutter moves from tc = 0

    def centre(tt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = x_start + v * np.clip(tt, 0.0, None)
        lowest = -run.depth_mm + run.retract_mm_s * np.clip(tt - t_ret, 0.0, None)
        return x, np.minimum(lowest, 0.5)  # the insert's lowest point, stock top at 0

    x_c, z_c = centre(tc)
    theta = rec.phase_rad + omega * t
    f = np.zeros((n, 3))
    gaps, who = _earlier_passes(a)
    for j in range(z):
        psi = (theta + a[j]) % (2 * np.pi)
        # only where the insert can be in the block: ahead half, below the top
        lowest = z_c - dz_k[j]
        maybe = (psi > 0) & (psi < np.pi) & (lowest < 0) & (tc > 0)
        # and near the block (1 mm margins on the radii the edge spans)
        # the upper slices' rays lag or lead the nose's by up to lag_max
        lag_max = float(np.abs(edge.lead_out).max()) + 1e-3
        yy4 = np.stack([np.cos(psi + s_) * r_ for s_ in (-lag_max, lag_max)
                        for r_ in (radius - 1, reach + 1)])  # fmt: skip
        maybe &= yy4.max(axis=0) >= y_lo
        maybe &= yy4.min(axis=0) <= y_hi
        maybe &= x_c + (reach + 1) >= 0
        idx = np.flatnonzero(maybe)
        if not idx.size:
            continue
        dt_back = gaps[j][None, :] / omega  # (1, M) s
        xb, zb_ = centre(tc[idx, None] - dt_back)
        d_prev = x_c[idx, None] - xb
        dz_prev = (zb_ - dz_k[who[j]][None, :]) - lowest[idx, None]
        dr_prev = rad[who[j]][None, :] - rad[j] + np.zeros_like(d_prev)
        win = (np.full(idx.size, y_lo), np.full(idx.size, y_hi), np.zeros(idx.size),
               np.full(idx.size, np.inf), x_c[idx])  # fmt: skip
        # the ray's radii are measured from the axis; this insert's own radius offset moves them
        f[idx] += _forces_offset(edge, k, psi[idx], -lowest[idx], d_prev, dz_prev, dr_prev,
                                 win, np.full(idx.size, sc[j]), rad[j])  # fmt: skip
    for axis, (freq_hz, zeta) in enumerate(rec.modes):
        f[:, axis] = _mode(f[:, axis], freq_hz, zeta, fine_hz)
    t, f, tc = t[::os_], f[::os_], tc[::os_]
    rng = np.random.default_rng(rec.seed)
    f += np.asarray(rec.offset_n, float) + t[:, None] * np.asarray(rec.drift_n_s, float)
    if rec.noise_n:
        f += rng.normal(0.0, rec.noise_n, f.shape)
    steady = (tc >= t_in + 2 * 60 / run.spindle_rpm) & (tc <= t_ret)
    return t, f, steady


def _forces_offset(edge: Edge, coef: dict[str, float], psi, depth, d_prev, dz_prev, dr_prev,
                   window, scale, r_own: float) -> np.ndarray:  # fmt: skip
    """:func:`_forces` for an insert whose radius is ``r_own`` mm off the nominal: the edge
    table is shifted (the earlier passes' offsets are relative to it)."""
    if r_own == 0.0:
        return _forces(edge, coef, psi, depth, d_prev, dz_prev, dr_prev, window, scale)
    shifted = dataclasses.replace(edge, rho_in=edge.rho_in + r_own, rho_out=edge.rho_out + r_own)
    return _forces(shifted, coef, psi, depth, d_prev, dz_prev, dr_prev, window, scale)
