"""Semi-discretization family: full discretization (Ding, Zhu, Zhang & Ding 2010, IJMTM
50:502-509; third order as Quo, Sun & Jiang 2012, IJMTM 62:61-66) of the milling equation

    M q'' + C q' + K q = -w H(t) (q(t) - q(t - tau)),   H(t + tau) = H(t),

in modal state-space form x = (eta, eta'), q = C_p x (a direction's displacement is the sum of
its modes). Over a step [t_k, t_k + h] the free motion is exact and the cutting term is integrated
with q(t - tau) and q(t) interpolated by Lagrange polynomials through neighbouring nodes (degree
``order``: 1 is Ding's linear scheme, 3 the default) and H(t) taken exactly (Gauss quadrature):

    x_{k+1} = e^{A h} x_k + w sum_j W_j (q(t_j - tau) - q(t_j)),
    W_j = int_0^h e^{A (h - s)} E H(t_k + s) l_j(s) ds.

A tooth period has ``m`` steps; its cutting part gets its share of them (at least 2) with tooth
entry and exit as nodes (H jumps there), a free flight one exact step. The delay equals the tooth
period, so over one period every delayed value is one of the initial state's: the transition
matrix is built by m batched small products, for many speeds and depths at once. Stable where
its spectral radius is below 1 (Floquet). The error falls as m^-(order + 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from analysis.stability.case import StabilityCase

_F = npt.NDArray[np.float64]
_C = npt.NDArray[np.complex128]
_I = npt.NDArray[np.intp]

__all__ = [
    "Discretisation", "critical_depths", "critical_depths_near", "discretise", "spectral_radius",
]  # fmt: skip

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(4)


@dataclass(frozen=True)
class Discretisation:
    """One case's tooth period at speeds ``tau_s``: per step whether it cuts and its stencils
    (node indices; negative: the previous period's) of delayed and current positions with
    weights ``wd``/``wc`` (S, K, p + 1, 2n, n_dir) per unit depth, the free motion ``phi0``
    (S, K, 2n, 2n); ``entries``: nodes whose delayed position is part of the state."""

    cuts: np.ndarray
    stencil_d: np.ndarray
    stencil_c: np.ndarray
    entries: tuple[int, ...]
    cp: np.ndarray
    a: np.ndarray
    tau_s: np.ndarray
    phi0: np.ndarray
    wd: np.ndarray
    wc: np.ndarray

    @property
    def size(self) -> int:
        """Dimension of the transition matrix."""
        return int(self.a.shape[0] + self.cp.shape[0] * len(self.entries))


_Step = tuple[float, float, float, _I | None]


def _steps(case: StabilityCase, m: int) -> list[_Step]:
    """Steps of one tooth period starting at a tooth's entry: length (fraction of the period),
    start angle and angle span (rad), the teeth in cut (None: free flight)."""
    n = case.teeth
    pitch = 2 * math.pi / n
    a, b = case.cut_angles_rad
    # The other teeth enter or leave (b - a) mod pitch after the period's start; a cut as long
    # as a pitch (or several) has no such break: its round-off residue would be a step of
    # ~1e-13 of the period taken for a free flight (which gave a zero limit).
    r = (b - a) % pitch
    edges = [0.0, pitch] if min(r, pitch - r) < 1e-9 * pitch else [0.0, r, pitch]
    out: list[_Step] = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        mid = a + (lo + hi) / 2 + pitch * np.arange(n)
        act = np.flatnonzero((mid % (2 * math.pi) > a) & (mid % (2 * math.pi) < b))
        k = max(2, round(m * (hi - lo) / pitch)) if act.size else 1
        nodes = np.linspace(lo, hi, k + 1)
        out += [((e - s) / pitch, a + s, e - s, act if act.size else None)
                for s, e in zip(nodes[:-1], nodes[1:])]  # fmt: skip
    return out


def _lagrange(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Lagrange basis of ``nodes`` at ``x``: (len(x), len(nodes))."""
    out = np.ones((x.size, nodes.size))
    for i, ni in enumerate(nodes):
        for j, nj in enumerate(nodes):
            if i != j:
                out[:, i] *= (x - nj) / (ni - nj)
    return out


def discretise(case: StabilityCase, m: int | None = None, rpm: np.ndarray | None = None,
               order: int = 3) -> Discretisation:  # fmt: skip
    """The discretisation of ``case`` with ``m`` steps per tooth period (default the case's),
    interpolation of degree ``order`` (1 or 3), at the speeds ``rpm`` (default the case's)."""
    m = m or case.steps_per_period
    rpm = np.asarray(case.rpm if rpm is None else rpm, float)
    steps = _steps(case, m)
    k_n = len(steps)
    frac = np.array([s[0] for s in steps])
    cuts = np.array([s[3] is not None for s in steps])
    free = not cuts.all()
    t = np.r_[0.0, np.cumsum(frac)]  # node times, fraction of tau; node K = the next period's 0
    # stencils: delayed positions are known at nodes 0..K (0..K-1 with a free flight);
    # current ones at nodes <= k + 1 (the previous period's too, unless across a free flight)
    top = k_n - 1 if free else k_n
    p = min(order, top)
    sd, sc = [], []
    for k in range(k_n):
        start = min(max(k - (p - 1) // 2, 0), top - p)
        sd.append(np.arange(start, start + p + 1))
        sc.append(np.arange(k + 1 - p, k + 2) if not free else
                  np.arange(max(k + 1 - p, 0), k + 2))  # fmt: skip
    node_t = np.r_[t[-4:-1] - 1.0, t]  # node j at index j + 3
    idx = ["xy".index(d) for d in case.directions]
    wn = 2 * math.pi * case.f_hz
    nm, nd = wn.size, len(idx)
    a = np.block(
        [[np.zeros((nm, nm)), np.eye(nm)], [-np.diag(wn**2), -np.diag(2 * case.zeta * wn)]]
    )
    cp = np.hstack([case.position_matrix(), np.zeros((nd, nm))])
    e = np.vstack([np.zeros((nm, nd)), (wn**2 / case.k_n_m)[:, None] * cp[:, :nm].T])
    tau = 60.0 / (case.teeth * rpm)
    g = (1 + _GAUSS_X) / 2  # Gauss points as fractions of a step
    lengths, which = np.unique(np.round(frac, 12), return_inverse=True)
    h = tau[:, None] * lengths[None, :]  # (S, L)
    phi0 = _exponential(case, h)
    decay = _exponential(case, h[..., None] * (1 - g)) @ e  # e^{A (h - s)} E: (S, L, G, 2n, nd)
    wd = np.zeros((rpm.size, k_n, p + 1, 2 * nm, nd))
    wc = np.zeros_like(wd)
    for k, (f, ang0, span, act) in enumerate(steps):
        if act is None:
            continue
        hk = case.tooth_h(ang0 + span * g[:, None] + 2 * math.pi / case.teeth * act).sum(1)
        hk = hk[:, idx][:, :, idx] * _GAUSS_W[:, None, None] / 2  # (G, nd, nd) with weights
        sg = t[k] + f * g
        for w_out, st in ((wd, sd[k]), (wc, sc[k])):
            m_k = np.einsum("gi,gnm->ginm", _lagrange(node_t[st + 3], sg), hk)
            w_out[:, k, p + 1 - st.size :] = (
                np.einsum(  # a short stencil: zero weights first
                    "sgan,ginm->siam", decay[:, which[k]], m_k
                )
                * tau[:, None, None, None]
                * f
            )
    sc = [np.r_[np.full(p + 1 - st.size, st[0]), st] for st in sc]
    entries = tuple(range(k_n))
    return Discretisation(cuts, np.array(sd), np.array(sc), entries, cp, a, tau,
                          phi0[:, which], wd, wc)  # fmt: skip


def _exponential(case: StabilityCase, h: np.ndarray) -> np.ndarray:
    """e^{A h} of the modal state matrix for step lengths ``h`` (any shape): (..., 2n, 2n),
    per mode (a 2 x 2 block on eta_r, eta_r') by Sylvester's formula
    e^{A h} = (e^{l1 h} (A - l2) - e^{l2 h} (A - l1)) / (l1 - l2),
    l = -zeta w +- i w sqrt(1 - zeta^2)."""
    wn = 2 * math.pi * case.f_hz
    nm = wn.size
    l1 = wn * (-case.zeta + 1j * np.sqrt(1 - case.zeta**2))
    l2 = l1.conj()
    ar = np.zeros((nm, 2, 2))
    ar[:, 0, 1], ar[:, 1, 0], ar[:, 1, 1] = 1.0, -(wn**2), -2 * case.zeta * wn
    eye = np.eye(2)
    f1, f2 = np.exp(h[..., None] * l1), np.exp(h[..., None] * l2)
    blk = (
        f1[..., None, None] * (ar - l2[:, None, None] * eye)
        - f2[..., None, None] * (ar - l1[:, None, None] * eye)
    ) / (l1 - l2)[:, None, None]
    full = np.zeros((*h.shape, 2 * nm, 2 * nm))
    r = np.arange(nm)
    for i in range(2):
        for j in range(2):
            full[..., r + i * nm, r + j * nm] = blk[..., i, j].real
    return full


def transition_matrices(d: Discretisation, speed: np.ndarray, depth_m: np.ndarray) -> np.ndarray:
    """The transition matrix over one tooth period for each (speed index, depth in m) pair,
    (B, size, size). State: x at the period's start, then q(t_j - tau) at the entry nodes."""
    s2, nd = d.a.shape[0], d.cp.shape[0]
    size, nb, k_n = d.size, speed.size, d.cuts.size
    col = {j: s2 + nd * i for i, j in enumerate(d.entries)}
    y = np.zeros((nb, s2, size))
    y[:, :, :s2] = np.eye(s2)
    q = {0: np.broadcast_to(np.hstack([d.cp, np.zeros((nd, size - s2))]), (nb, nd, size))}
    wd_all = d.wd[speed] * depth_m[:, None, None, None, None]
    wc_all = d.wc[speed] * depth_m[:, None, None, None, None]
    eye_d = np.eye(nd)
    for k in range(k_n):
        rhs = d.phi0[speed, k] @ y
        if d.cuts[k]:
            for i, j in enumerate(d.stencil_d[k]):  # delayed positions: state entries
                wgt = wd_all[:, k, i]
                if j == k_n:  # q(t_K - tau) = q(t_0), the current start
                    rhs[:, :, :s2] += wgt @ d.cp
                else:
                    rhs[:, :, col[j] : col[j] + nd] += wgt
            v = wc_all[:, k, -1]  # the implicit one: q(t_{k+1})
            for i, j in enumerate(d.stencil_c[k][:-1]):
                wgt = wc_all[:, k, i]
                if j >= 0:
                    rhs -= wgt @ q[j]
                else:  # the previous period's position = this period's delayed value
                    rhs[:, :, col[k_n + j] : col[k_n + j] + nd] -= wgt
            # (I + v Cp)^-1 = I - v (I + Cp v)^-1 Cp: an n_dir x n_dir solve, not 2n x 2n
            y = rhs - v @ np.linalg.solve(eye_d + d.cp @ v, d.cp @ rhs)
        else:
            y = rhs
        q[k + 1] = d.cp @ y
    return np.concatenate([y, *(q[j] for j in d.entries)], axis=1)


def spectral_radius(d: Discretisation, speed: np.ndarray, depth_m: np.ndarray) -> tuple[_F, _C]:
    """Spectral radius and the critical multiplier (the largest; Im >= 0 of a pair) per pair."""
    mu = np.linalg.eigvals(transition_matrices(d, speed, depth_m))
    mod = np.abs(mu)
    i = np.argmax(mod - 1e-12 * (mu.imag < 0), axis=1)  # of a conjugate pair, Im >= 0
    rows = np.arange(mu.shape[0])
    return mod[rows, i], mu[rows, i]


def critical_depths(d: Discretisation, grid_m: np.ndarray, iterations: int = 3) -> tuple[_F, _C]:
    """The lowest unstable depth per speed (m; inf if stable over the whole ``grid_m``) and
    its critical multiplier: march up the ascending depth grid until the spectral radius
    reaches 1, then narrow the bracket by regula falsi on log(radius) (Illinois variant) and
    interpolate in it."""
    ns = d.tau_s.size
    lo = np.zeros(ns)
    # at depth 0 the radius is the free structure's e^{-zeta w tau}
    f_lo = np.max(-np.abs(np.linalg.eigvals(d.a).real)[None] * d.tau_s[:, None], 1)
    hi = np.full(ns, np.inf)
    f_hi = np.full(ns, np.nan)
    crit = np.full(ns, np.nan, complex)
    todo = np.arange(ns)
    for g in grid_m:
        if not todo.size:
            break
        r, c = spectral_radius(d, todo, np.full(todo.size, g))
        bad = r >= 1
        hi[todo[bad]], f_hi[todo[bad]], crit[todo[bad]] = g, np.log(r[bad]), c[bad]
        lo[todo[~bad]], f_lo[todo[~bad]] = g, np.log(r[~bad])
        todo = todo[~bad]
    return _narrow(d, lo, f_lo, hi, f_hi, crit, iterations)


def critical_depths_near(d: Discretisation, guess_m: np.ndarray, width: float = 0.15,
                         points: int = 7, iterations: int = 3) -> tuple[_F, _C]:  # fmt: skip
    """As :func:`critical_depths`, for limits known to lie near ``guess_m`` (finite; from a
    coarser discretisation of the same case): a local march over ``points`` depths from
    guess (1 - width) to guess (1 + width) (5 % apart: finer than the full march's 15 %, so
    an unstable island next to the guess is not stepped over), then the same narrowing.
    Speeds whose limit is not inside that range come back as nan (the caller marches)."""
    ns = d.tau_s.size
    levels = np.linspace(1 - width, 1 + width, points)
    lo, f_lo = np.full(ns, np.nan), np.full(ns, np.nan)
    hi, f_hi = np.full(ns, np.inf), np.full(ns, np.nan)
    crit = np.full(ns, np.nan, complex)
    below = np.zeros(ns, bool)  # unstable at the first level: the limit is further down
    todo = np.arange(ns)
    for k, level in enumerate(levels):
        if not todo.size:
            break
        g = guess_m[todo] * level
        r, c = spectral_radius(d, todo, g)
        bad = r >= 1
        below[todo[bad]] = k == 0
        hi[todo[bad]], f_hi[todo[bad]], crit[todo[bad]] = g[bad], np.log(r[bad]), c[bad]
        lo[todo[~bad]], f_lo[todo[~bad]] = g[~bad], np.log(r[~bad])
        todo = todo[~bad]
    hi[below] = np.inf  # not bracketed: leave to the caller's march
    out, crit = _narrow(d, lo, f_lo, hi, f_hi, crit, iterations)
    found = np.isfinite(hi)
    return np.where(found, out, np.nan), np.where(found, crit, np.nan)


def _narrow(d: Discretisation, lo: _F, f_lo: _F, hi: _F, f_hi: _F, crit: _C,
            iterations: int) -> tuple[_F, _C]:  # fmt: skip
    """Regula falsi (Illinois) on log(radius) inside [lo, hi] where hi is finite."""
    ns = d.tau_s.size
    idx = np.flatnonzero(np.isfinite(hi))
    side = np.zeros(ns, int)  # which end the last step moved: -1 lo, +1 hi
    for _ in range(iterations):
        if not idx.size:
            break
        t = np.clip(-f_lo[idx] / (f_hi[idx] - f_lo[idx]), 0.02, 0.98)
        mid = lo[idx] + t * (hi[idx] - lo[idx])
        r, c = spectral_radius(d, idx, mid)
        bad = r >= 1
        i_b, i_g = idx[bad], idx[~bad]
        f_lo[i_b[side[i_b] == 1]] /= 2  # Illinois: the end kept twice counts half
        f_hi[i_g[side[i_g] == -1]] /= 2
        hi[i_b], f_hi[i_b], crit[i_b], side[i_b] = mid[bad], np.log(r[bad]), c[bad], 1
        lo[i_g], f_lo[i_g], side[i_g] = mid[~bad], np.log(r[~bad]), -1
    out = hi.copy()
    t = -f_lo[idx] / (f_hi[idx] - f_lo[idx])
    out[idx] = lo[idx] + np.clip(t, 0, 1) * (hi[idx] - lo[idx])
    return out, crit
