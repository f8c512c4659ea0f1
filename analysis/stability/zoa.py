"""Zero-order approximation (Altintas & Budak 1995): the directional factor replaced by its mean
over a tooth period, stability lobes in closed form.

With A0 the mean directional factor and G(i w) the tool's receptance (diagonal: x and y
uncoupled), the chatter boundary at frequency w is det(I + a A0 G (1 - exp(-i w tau))) = 0.
For an eigenvalue mu of A0 G: a (1 - exp(-i w tau)) = -1 / mu, so (real a > 0)

    a_lim = -1 / (2 Re mu)                      (only where Re mu < 0)
    w tau = pi + 2 arctan(Im mu / Re mu) + 2 pi k,   k = 0, 1, ... (lobe number)

Each (eigenvalue branch, lobe k) traces a curve (spindle speed, a_lim) as w sweeps; the limit at
a speed is the lowest curve over it.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from analysis.stability.case import StabilityCase

_F = npt.NDArray[np.float64]
_I = npt.NDArray[np.intp]

__all__ = ["zoa_lobes", "zoa_minimum"]

_FREQ_POINTS = 6000


def _branches(case: StabilityCase) -> tuple[np.ndarray, np.ndarray]:
    """Chatter frequencies (F,) rad/s and eigenvalues mu of A0 G (F, n_dir), sorted by real
    part so that a branch stays one curve."""
    f_hz = np.geomspace(0.3 * case.f_hz.min(), 3 * case.f_hz.max(), _FREQ_POINTS)
    idx = ["xy".index(d) for d in case.directions]
    a0 = case.mean_h()[np.ix_(idx, idx)]
    g = case.receptance(f_hz)  # (F, n_dir)
    mu = np.linalg.eigvals(a0[None] * g[:, None, :])
    mu = np.take_along_axis(mu, np.argsort(mu.real, axis=1), axis=1)
    return 2 * math.pi * f_hz, mu


def zoa_minimum(case: StabilityCase) -> float:
    """The lowest ZOA limit over all speeds, m: min over w of -1 / (2 Re mu)."""
    _, mu = _branches(case)
    neg = mu.real[mu.real < 0]
    return float(-1 / (2 * neg.min())) if neg.size else math.inf


def zoa_lobes(case: StabilityCase, rpm: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Depth limit (m, inf where no lobe passes) and chatter frequency (Hz) at each speed of
    ``rpm`` (default the case's), ascending."""
    rpm = np.asarray(case.rpm if rpm is None else rpm, float)
    w, mu = _branches(case)
    n_teeth = case.teeth
    ok = mu.real < 0
    depth = np.where(ok, -0.5 / np.where(ok, mu.real, -1.0), np.inf)  # (F, B)
    theta = math.pi + 2 * np.arctan(mu.imag / np.where(ok, mu.real, -1.0))  # (0, 2 pi)
    k_max = int(math.ceil(60 * w.max() / (n_teeth * rpm.min() * 2 * math.pi))) + 1
    # 20 lobes at a time: memory stays bounded for low speeds (many lobes)
    parts = [
        _on_speeds(rpm, w, depth, theta, ok, n_teeth, np.arange(k0, min(k0 + 20, k_max)))
        for k0 in range(0, k_max, 20)
    ]
    target, a_lim, chatter = (np.concatenate(x) for x in zip(*parts))
    out_d = np.full(rpm.shape, np.inf)
    out_f = np.full(rpm.shape, np.nan)
    order = np.lexsort((a_lim, target))
    target, a_lim, chatter = target[order], a_lim[order], chatter[order]
    first_of = np.r_[True, target[1:] != target[:-1]]
    out_d[target[first_of]] = a_lim[first_of]
    out_f[target[first_of]] = chatter[first_of]
    return out_d, out_f


def _on_speeds(rpm: _F, w: _F, depth: _F, theta: _F, ok: npt.NDArray[np.bool_],
               n_teeth: int, k: _I) -> tuple[_I, _F, _F]:  # fmt: skip
    """The lobes ``k`` at the speeds ``rpm``: (speed index, depth, chatter Hz) for every
    segment between neighbouring frequencies on one branch and lobe that passes over a speed."""
    k = k[:, None, None]
    speed = 60 * w[None, :, None] / (n_teeth * (theta[None] + 2 * math.pi * k))  # (K, F, B)
    n0, n1 = speed[:, :-1], speed[:, 1:]
    d0, d1 = np.broadcast_to(depth[:-1], n0.shape), np.broadcast_to(depth[1:], n0.shape)
    w0, w1 = np.broadcast_to(w[:-1, None], n0.shape), np.broadcast_to(w[1:, None], n0.shape)
    keep = (ok[:-1] & ok[1:] & (np.abs(theta[1:] - theta[:-1]) < 1.0))[None] & (
        np.maximum(n0, n1) >= rpm[0]) & (np.minimum(n0, n1) <= rpm[-1])  # fmt: skip
    n0, n1, d0, d1, w0, w1 = (a[keep] for a in (n0, n1, d0, d1, w0, w1))
    lo, hi = np.minimum(n0, n1), np.maximum(n0, n1)
    first = np.searchsorted(rpm, lo, "left")
    count = np.searchsorted(rpm, hi, "right") - first
    seg = np.repeat(np.arange(lo.size), count)
    target = first[seg] + np.arange(seg.size) - np.repeat(np.cumsum(count) - count, count)
    t = (rpm[target] - n0[seg]) / np.where(n1[seg] != n0[seg], n1[seg] - n0[seg], 1.0)
    a_lim = d0[seg] + t * (d1[seg] - d0[seg])
    chatter = (w0[seg] + t * (w1[seg] - w0[seg])) / (2 * math.pi)
    return target, a_lim, chatter
