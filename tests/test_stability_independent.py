"""cutlab's stability lobes against an independent implementation: Insperger & Stepan's original
semi-discretization (2002; zeroth order in the periodic coefficient, the delayed state averaged over
its interval) of the 1-DOF milling benchmark, written here from the paper's equations with none of
analysis.stability's code: x'' + 2 zeta wn x' + wn^2 x = -(a h(t) / m) (x(t) - x(t - tau)),
h(t) = sum_j g(phi_j) sin(phi_j) (Kt cos(phi_j) + Kn sin(phi_j)) (Insperger, Stepan et al. 2003,
the same parameters as Insperger & Stepan 2004: N = 2, Kt = 6e8, Kn = 2e8 N/m^2, 922 Hz,
zeta = 0.011, m = 0.03993 kg). Being zeroth order it converges slowly (its error is about 1 % at
160 steps per tooth period), so it is checked at two speeds of the slot, within 2 %.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from analysis.stability import load_case, stability_lobes

N_TEETH, KT, KN = 2, 6e8, 2e8
WN, ZETA, MASS = 922 * 2 * math.pi, 0.011, 0.03993


def _h(m: int, phi_in: float, phi_out: float, sub: int = 40) -> np.ndarray:
    """The specific-force variation averaged over each of the m intervals of a tooth period."""
    out = np.zeros(m)
    dphi = 2 * math.pi / N_TEETH / m
    for i in range(m):
        phi = i * dphi + (np.arange(sub) + 0.5) * dphi / sub
        for j in range(N_TEETH):
            p = np.mod(phi + j * 2 * math.pi / N_TEETH, 2 * math.pi)
            g = (p >= phi_in) & (p <= phi_out)
            out[i] += np.mean(g * (KT * np.cos(p) + KN * np.sin(p)) * np.sin(p))
    return out


def _spectral_radius(rpm: float, depth_m: float, h: np.ndarray) -> float:
    m = len(h)
    tau = 60.0 / (rpm * N_TEETH)
    dt = tau / m
    phi = np.eye(m + 2)
    for i in range(m):
        a = np.array([[0.0, 1.0], [-(WN**2) - depth_m * h[i] / MASS, -2 * ZETA * WN]])
        b = np.array([[0.0, 0.0], [depth_m * h[i] / MASS, 0.0]])
        p = expm(a * dt)
        r = (p - np.eye(2)) @ np.linalg.solve(a, b)
        d = np.zeros((m + 2, m + 2))
        d[0:2, 0:2] = p
        d[0:2, m] += 0.5 * r[:, 0]  # x(t_i - tau + dt)
        d[0:2, m + 1] += 0.5 * r[:, 0]  # x(t_i - tau)
        d[2, 0] = 1.0
        d[3:, 2:-1] = np.eye(m - 1)
        phi = d @ phi
    return float(max(abs(np.linalg.eigvals(phi))))


def _limit_mm(rpm: float, h: np.ndarray, start_mm: float) -> float:
    """The smallest unstable depth above ``start_mm`` (stable there): scan up in 5 % steps,
    then bisect the first bracket."""
    d = start_mm * 1e-3
    assert _spectral_radius(rpm, d, h) < 1
    while _spectral_radius(rpm, d * 1.05, h) <= 1:
        d *= 1.05
    lo, hi = d, d * 1.05
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _spectral_radius(rpm, mid, h) > 1 else (mid, hi)
    return 0.5 * (lo + hi) * 1e3


@pytest.mark.slow  # the reference converges slowly (160 steps: about 5 min)
@pytest.mark.parametrize("rpm", [5905.0, 10000.0])
def test_slot_lobes_agree_with_an_independent_semi_discretization(tmp_path, rpm):
    """The 1-DOF slot: at 40, 80 and 160 steps the reference gives 0.357, 0.327, 0.321 mm at
    5905 rpm (converging from above); at 160 steps it must agree with cutlab within 2 %."""
    cfg = tmp_path / "case.toml"
    cfg.write_text(
        f"[tool]\nteeth = {N_TEETH}\n[cut]\nmilling = \"down\"\nradial_immersion = 1.0\n"
        f"[coefficients]\nKtc_N_mm2 = {KT / 1e6}\nKrc_N_mm2 = {KN / 1e6}\n[[modes]]\n"
        f"axis = \"x\"\nf_hz = 922.0\nzeta = {ZETA}\nm_kg = {MASS}\n[spindle]\n"
        f"rpm_min = {rpm}\nrpm_max = {rpm + 1}\npoints = 2\n[search]\nsteps_per_period = 60\n"
    )
    ours = float(stability_lobes(load_case(cfg), "sd").depth_limit_mm[0])
    theirs = _limit_mm(rpm, _h(160, 0.0, math.pi), 0.25)
    assert ours == pytest.approx(theirs, rel=0.02)
