"""Several modes per FRF: LSCF poles over model orders, a stabilisation diagram, automatic pole
selection, and modal constants by LSFD (both from sdypy-EMA).

sdypy-EMA computes the poles of every model order (``Model.get_poles``) and the modal constants
of chosen poles (``Model.get_constants``). Its own choosing is interactive (``select_poles``, a
GUI) or needs the frequencies in advance (``select_closest_poles``, which also calls a pole
stable after agreeing with one lower order only). So the automatic choice is written here:

1. physical poles: positive frequency inside the band, 0 < zeta < ``MAX_DAMPING``;
2. a pole is stable at order n when a physical pole at order n - 1 is within ``FREQ_TOL``
   (relative) in frequency and ``DAMP_TOL`` in damping; its run is the number of consecutive
   orders it has been stable for, and it counts when the run reaches ``MIN_RUN``;
3. the counted poles, sorted by frequency, split into clusters where two neighbours are more than
   ``FREQ_TOL`` apart; a cluster of at least ``MIN_CLUSTER`` poles is a mode (a computational
   pole stays stable over a few orders only), represented by its member nearest the cluster's
   median frequency and damping.
"""

from __future__ import annotations

import contextlib
import io
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.errors import AnalysisError

__all__ = ["MAX_ORDER", "Stabilisation", "modal_constants", "plot_stabilisation", "stabilise"]

#: Highest LSCF model order / 2 (sdypy-EMA's ``pol_order_high``): orders 2, 4, ... 60.
MAX_ORDER = 30
FREQ_TOL = 0.01
DAMP_TOL = 0.05
MAX_DAMPING = 0.2
MIN_RUN = 4
MIN_CLUSTER = 5


@dataclass(frozen=True)
class Stabilisation:
    """One FRF's poles over model orders: ``orders`` (o,), per order the ``poles`` (complex,
    rad/s; of the FRF as given, e.g. windowed), their ``freq_hz``, ``damping`` and ``state``
    (0 not physical, 1 physical, 2 stable in frequency, 3 stable in frequency and damping,
    4 counted: stable for ``MIN_RUN`` orders); ``modes`` (order index, pole index) per selected
    cluster, ascending in frequency; ``band_hz``; ``model`` the sdypy-EMA model."""

    orders: np.ndarray
    poles: tuple[np.ndarray, ...]
    freq_hz: tuple[np.ndarray, ...]
    damping: tuple[np.ndarray, ...]
    state: tuple[np.ndarray, ...]
    modes: tuple[tuple[int, int], ...]
    band_hz: tuple[float, float]
    model: Any  # sdypy-EMA's Model: untyped

    def cluster_size(self, k: int) -> int:
        """How many counted poles the ``k``-th mode's cluster holds."""
        o, i = self.modes[k]
        f = self.freq_hz[o][i]
        return sum(int(np.sum((s == 4) & (np.abs(fr - f) <= FREQ_TOL * f)))
                   for fr, s in zip(self.freq_hz, self.state))  # fmt: skip


def stabilise(
    freq_hz: np.ndarray, frf: np.ndarray, band_hz: tuple[float, float], frf_form: str,
    max_order: int = MAX_ORDER,
) -> Stabilisation:  # fmt: skip
    """LSCF poles of ``frf`` (one FRF, receptance-like) for orders 2..2 ``max_order`` in
    ``band_hz``, their stability and the selected modes."""
    from sdypy import EMA

    lo, hi = band_hz
    h = np.nan_to_num(np.asarray(frf, complex))  # pyFRF leaves inf/nan at 0 Hz for accel
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")  # EMA warns about ill-conditioned high orders
        model = EMA.Model(frf=h[None, :], freq=freq_hz, lower=lo, upper=hi,
                          pol_order_high=max_order, frf_form=frf_form)  # fmt: skip
        model.get_poles(method="lscf", show_progress=False)
    poles = tuple(np.asarray(p, complex) for p in model.all_poles)
    fr = tuple(np.asarray(f, float) for f in model.pole_freq)
    xi = tuple(np.asarray(x, float) for x in model.pole_xi)
    states: list[NDArray[np.int_]] = []
    runs: list[NDArray[np.int_]] = []
    for o in range(len(poles)):
        phys = (fr[o] > lo) & (fr[o] < hi) & (xi[o] > 0) & (xi[o] < MAX_DAMPING)
        state = phys.astype(int)
        run = np.zeros(len(poles[o]), int)
        for i in np.flatnonzero(phys):
            if o == 0:
                continue
            prev = np.flatnonzero(states[o - 1] > 0)
            if len(prev) == 0:
                continue
            j = prev[np.argmin(np.abs(fr[o - 1][prev] - fr[o][i]))]
            if abs(fr[o][i] - fr[o - 1][j]) >= FREQ_TOL * fr[o - 1][j]:
                continue
            state[i] = 2
            if abs(xi[o][i] - xi[o - 1][j]) < DAMP_TOL * xi[o - 1][j]:
                state[i] = 3
                run[i] = runs[o - 1][j] + 1
        run_ok = run >= MIN_RUN - 1  # MIN_RUN orders = MIN_RUN - 1 agreements in a row
        state[run_ok] = 4
        states.append(state)
        runs.append(run)
    modes = _clusters(fr, xi, states)
    return Stabilisation(np.arange(2, 2 * len(poles) + 1, 2), poles, fr, xi, tuple(states),
                         modes, (float(lo), float(hi)), model)  # fmt: skip


def _clusters(
    fr: Sequence[NDArray[np.float64]],
    xi: Sequence[NDArray[np.float64]],
    states: Sequence[NDArray[np.int_]],
) -> tuple[tuple[int, int], ...]:
    """(order index, pole index) of the representative of each cluster of counted poles."""
    pts = [(fr[o][i], xi[o][i], o, i) for o, s in enumerate(states) for i in np.flatnonzero(s == 4)]
    if not pts:
        return ()
    pts.sort()
    groups, cur = [], [pts[0]]
    for p in pts[1:]:
        if p[0] - cur[-1][0] > FREQ_TOL * cur[-1][0]:
            groups.append(cur)
            cur = []
        cur.append(p)
    groups.append(cur)
    out = []
    for g in groups:
        if len(g) < MIN_CLUSTER:
            continue
        f = np.array([p[0] for p in g])
        z = np.array([p[1] for p in g])
        fm, zm = np.median(f), np.median(z)
        k = int(np.argmin(((f - fm) / (FREQ_TOL * fm)) ** 2 + ((z - zm) / (DAMP_TOL * zm)) ** 2))
        out.append((int(g[k][2]), int(g[k][3])))
    return tuple(out)


def modal_constants(
    stab: Stabilisation, modes: list[tuple[int, int]]
) -> NDArray[np.complex128]:
    """LSFD modal constants A_r (sdypy-EMA ``get_constants``, lower and upper residuals in the
    fit) of the chosen poles: H(w) = sum A_r / (i w - s_r) + conj(A_r) / (i w - conj(s_r))."""
    if not modes:
        return np.zeros(0, complex)
    model = stab.model
    model.pole_ind = np.asarray(modes, int)
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        try:
            _, a = model.get_constants(method="lsfd", whose_poles="own")
        except np.linalg.LinAlgError as exc:
            raise AnalysisError(f"LSFD of the modal constants failed: {exc}") from None
    out: NDArray[np.complex128] = np.asarray(a, complex)[0]
    return out


def plot_stabilisation(stabs: dict[str, Stabilisation], frf: dict[str, NDArray[np.complex128]],
                       freq_hz: NDArray[np.float64], chosen: dict[str, list[float]],
                       path: str | Path) -> Path:  # fmt: skip
    """PNG: per channel the stabilisation diagram (model order against pole frequency, by
    stability) over |H|, the chosen modes marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(stabs)
    if not names:
        raise AnalysisError("no channel to draw a stabilisation diagram of")
    fig, axes = plt.subplots(len(names), 1, figsize=(9, 3.2 * len(names)), squeeze=False,
                             constrained_layout=True)  # fmt: skip
    styles = {
        1: ("o", "0.75", "physical"), 2: ("d", "C1", "stable f"), 3: ("s", "C2", "stable f, zeta"),
        4: ("x", "C3", f"stable {MIN_RUN} orders"),
    }  # fmt: skip
    for ax, name in zip(axes[:, 0], names):
        st = stabs[name]
        lo, hi = st.band_hz
        for s, (mk, col, lab) in styles.items():
            xs = [f[st_ == s] for f, st_ in zip(st.freq_hz, st.state)]
            ys = [np.full(len(x), o) for x, o in zip(xs, st.orders)]
            ax.plot(np.concatenate(xs), np.concatenate(ys), mk, ms=3, color=col, mfc="none",
                    label=lab, ls="")  # fmt: skip
        for f in chosen.get(name, []):
            ax.axvline(f, color="k", ls=":", lw=0.8)
        ax.set_xlim(lo, hi)
        ax.set_ylabel(f"{name}: model order")
        a2 = ax.twinx()
        band = (freq_hz >= lo) & (freq_hz <= hi)
        a2.semilogy(freq_hz[band], np.abs(frf[name][band]), color="0.5", lw=0.8)
        a2.set_ylabel("|H|")
        ax.set_zorder(a2.get_zorder() + 1)  # the poles over the FRF
        ax.patch.set_visible(False)
        ax.legend(fontsize=7, loc="upper left")
    axes[-1, 0].set_xlabel("frequency, Hz")
    out = Path(path)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
