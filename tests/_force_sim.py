"""An end-milling force record simulated in the time domain, written apart from the fitting path
(it imports neither ``analysis.forces`` nor ``analysis.identify``): a shared mistake in the model
and the fit cannot hide behind it.

The cutter: ``flutes`` teeth, radius R, a constant helix; the edge is cut into ``slices`` axial
slices and the slice at height z lags the tip by psi = z tan(helix) / R. Angles are measured from
+Y towards +X (the feed direction), the spindle turning clockwise seen from above (M3); a tooth at
angle phi sits at (R sin phi, R cos phi) and moves along (cos phi, -sin phi).

Chip thickness with radial runout (Altintas): tooth j at phi = theta + j p (p the pitch) meets the
surface that the tooth at that angle one tooth period earlier left, i.e. the one at theta - p + k p
= theta + j p, k = j + 1. That tooth's edge was at radius R + r_(j+1) and the table has moved f_z
since, so h_j = f_z sin(phi) + r_j - r_(j+1); h <= 0 does not cut.

Forces on the workpiece, per slice of height dz (chip width db = dz on a flat flank):

- linear edge-force model: F_t = (K_tc h + K_te) db, F_r = (K_rc h + K_re) db, F_a likewise;
- power law (Kienzle size effect): F_q = K_q h^(1 - m_c) db for q in t, r, a;

F_t along the tooth's motion (the tool drags the chip with it), F_r outward from the tool axis,
F_a up: workpiece X = F_t cos(phi) + F_r sin(phi), Y = -F_t sin(phi) + F_r cos(phi), Z = F_a.

A real record adds: spindle-speed wobble at a constant table feed (so the feed per tooth wobbles
against it), per-tooth force scatter, an entry and exit ramp of the engaged depth, air before and
after, each axis's dynamometer mode (1-DOF, unit static gain, bilinear discretisation), an
offset, drift and white noise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import signal

LINEAR = ("Ktc_n_mm2", "Krc_n_mm2", "Kac_n_mm2", "Kte_n_mm", "Kre_n_mm", "Kae_n_mm")


@dataclass(frozen=True)
class Cut:
    """An end-milling cut: the tool, the conditions and the engagement (rad, mm, rpm)."""

    diameter_mm: float = 10.0
    flutes: int = 3
    helix_deg: float = 30.0
    spindle_rpm: float = 3000.0
    fz_mm: float = 0.05
    depth_mm: float = 2.0
    entry_rad: float = 0.0  # slot: 0 .. pi; up milling 0 .. span; down milling pi - span .. pi
    exit_rad: float = np.pi
    runout_mm: Sequence[float] = ()  # per-tooth radius offsets r_j (default none)
    tooth_scale: Sequence[float] = ()  # per-tooth force factors (default 1)

    @staticmethod
    def immersion(ae_mm: float, diameter_mm: float, mode: str) -> tuple[float, float]:
        span = float(np.arccos(1 - 2 * ae_mm / diameter_mm))
        return {"slot": (0.0, np.pi), "up": (0.0, span), "down": (np.pi - span, np.pi)}[mode]


@dataclass(frozen=True)
class Law:
    """``kind`` 'linear' (``coef`` by :data:`LINEAR` names) or 'power' (``coef`` keys Kt, Kr,
    Ka in N/mm^(2 - mc) and the exponent ``mc``: F = K h^(1 - mc) b)."""

    kind: str
    coef: dict
    mc: float = 0.25


@dataclass(frozen=True)
class Record:
    """How the cut is recorded (s, N, Hz)."""

    rate_hz: float = 20_000.0
    air_revs: int = 10
    ramp_revs: int = 6
    steady_revs: int = 100
    slices: int = 12
    rpm_wobble: float = 0.0  # rms relative spindle-speed wobble (slow, a few Hz)
    noise_n: float = 0.0
    offset_n: Sequence[float] = (0.0, 0.0, 0.0)
    drift_n_s: Sequence[float] = (0.0, 0.0, 0.0)
    modes: Sequence[tuple[float, float]] = field(default_factory=tuple)  # (Hz, zeta) per axis
    seed: int = 0


def _forces_at(theta: np.ndarray, fz: np.ndarray, depth: np.ndarray, cut: Cut, law: Law,
               slices: int) -> np.ndarray:  # fmt: skip
    """Workpiece forces (n, 3) N at tool angles ``theta`` (n,), feed per tooth and depth (n,)."""
    n_t = cut.flutes
    radius = cut.diameter_mm / 2
    pitch = 2 * np.pi / n_t
    r = np.zeros(n_t) if len(cut.runout_mm) == 0 else np.asarray(cut.runout_mm, float)
    scale = np.ones(n_t) if len(cut.tooth_scale) == 0 else np.asarray(cut.tooth_scale, float)
    dr = r - np.roll(r, -1)  # r_j - r_(j+1)
    frac = (np.arange(slices) + 0.5) / slices  # slice mid-heights as fractions of the depth
    out = np.zeros((len(theta), 3))
    for j in range(n_t):
        for s in range(slices):
            z = frac[s] * depth
            db = depth / slices
            phi = (theta + j * pitch - z * np.tan(np.radians(cut.helix_deg)) / radius) % (
                2 * np.pi
            )
            h = fz * np.sin(phi) + dr[j]
            on = (phi >= cut.entry_rad) & (phi <= cut.exit_rad) & (h > 0)
            hh = np.where(on, h, 0.0)
            w = np.where(on, db, 0.0) * scale[j]
            if law.kind == "linear":
                c = law.coef
                ft = (c["Ktc_n_mm2"] * hh + c["Kte_n_mm"]) * w
                fr = (c["Krc_n_mm2"] * hh + c["Kre_n_mm"]) * w
                fa = (c["Kac_n_mm2"] * hh + c["Kae_n_mm"]) * w
            else:
                hp = hh ** (1 - law.mc)
                ft, fr, fa = (law.coef[k] * hp * w for k in ("Kt", "Kr", "Ka"))
            sp, cp = np.sin(phi), np.cos(phi)
            out[:, 0] += ft * cp + fr * sp
            out[:, 1] += -ft * sp + fr * cp
            out[:, 2] += fa
    return out


def mean_force(cut: Cut, law: Law, slices: int = 24, n_phi: int = 3600) -> np.ndarray:
    """Mean workpiece force (3,) N over one revolution, no noise (numeric average)."""
    theta = np.linspace(0, 2 * np.pi, n_phi, endpoint=False)
    n = np.ones(n_phi)
    return _forces_at(theta, cut.fz_mm * n, cut.depth_mm * n, cut, law, slices).mean(axis=0)


def _wobble(t: np.ndarray, rms: float, rng: np.random.Generator) -> np.ndarray:
    """A slow random relative speed deviation of the given rms: five sines, 0.3..3 Hz."""
    if not rms:
        return np.zeros_like(t)
    f = rng.uniform(0.3, 3.0, 5)
    ph = rng.uniform(0, 2 * np.pi, 5)
    w = np.sin(2 * np.pi * f[:, None] * t[None, :] + ph[:, None]).sum(axis=0)
    return rms * w / np.sqrt(5 / 2)


def _mode_filter(x: np.ndarray, freq_hz: float, zeta: float, rate_hz: float) -> np.ndarray:
    wn = 2 * np.pi * freq_hz
    b, a, _ = signal.cont2discrete(([wn**2], [1, 2 * zeta * wn, wn**2]), 1 / rate_hz, "bilinear")
    return signal.lfilter(np.ravel(b), a, x)


def simulate(cut: Cut, law: Law, rec: Record = Record()) -> tuple[np.ndarray, np.ndarray]:
    """(time_s (n,), force_n (n, 3)) of a whole run: air, entry ramp, steady cut, exit ramp, air
    (revolution counts at the nominal speed), in dynamometer axes X (feed), Y, Z (up)."""
    rng = np.random.default_rng(rec.seed)
    rev_s = 60.0 / cut.spindle_rpm
    plan = (rec.air_revs, rec.ramp_revs, rec.steady_revs, rec.ramp_revs, rec.air_revs)
    n = int(round(sum(plan) * rev_s * rec.rate_hz))
    t = np.arange(n) / rec.rate_hz
    speed = 1 + _wobble(t, rec.rpm_wobble, rng)
    theta = 2 * np.pi * cut.spindle_rpm / 60 * np.cumsum(speed) / rec.rate_hz
    fz = cut.fz_mm / speed  # the table feed stays constant
    # Engaged fraction of the depth: 0 in air, ramps in and out linearly.
    marks = np.cumsum((0,) + plan) * rev_s
    engaged = np.interp(t, marks[1:5], [0.0, 1.0, 1.0, 0.0], left=0.0, right=0.0)
    f = np.zeros((n, 3))
    on = engaged > 0
    f[on] = _forces_at(theta[on], fz[on], cut.depth_mm * engaged[on], cut, law, rec.slices)
    for axis, (freq_hz, zeta) in enumerate(rec.modes):
        f[:, axis] = _mode_filter(f[:, axis], freq_hz, zeta, rec.rate_hz)
    f += np.asarray(rec.offset_n, float) + t[:, None] * np.asarray(rec.drift_n_s, float)
    f += rng.normal(0.0, rec.noise_n, f.shape) if rec.noise_n else 0.0
    return t, f
