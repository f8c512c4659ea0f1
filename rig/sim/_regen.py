"""The regenerative end-milling twin: tool modes, chip thickness from the surface the earlier
teeth left, the linear edge-force law, and the chip-breaker overload limit.

Why hand-written: no maintained Python library simulates regenerative milling in the time domain
(stability libraries compute lobes, not force records), and the loop is inherently sequential
(each step's chip depends on the displacement the previous steps produced), so it is a numba
kernel (:func:`_kernel`) over the vectorised engagement geometry of
:mod:`rig.sim._machine_engagement`.

The model (Tlusty & Ismail's time-domain simulation, with Smith & Tlusty's surface memory):

- The tool's modes, per machine direction x or y (``analysis.config.ToolMode``: f_hz, zeta,
  k_N_m), are driven by minus the force on the workpiece and discretised exactly for a force held
  over each internal step (zero-order hold), so any step is stable.
- Internal steps are tied to the spindle: one step turns the spindle by one angular bin, with
  ``steps_per_tooth`` bins per tooth pitch (at least 40, 20 per period of the stiffest mode and one
  per DAQ sample), so every tooth lands on the bins the tooth before it left.
- The surface memory holds, per axial slice and bin of immersion angle, the position (projected
  on the edge's outward normal, mm) of the surface last cut there. A tooth at that bin with the
  tool deflected by d cuts ``h = (P + d) . n - memory`` (times sin kappa); for a steady cut that is
  ``f_z sin(phi) + (v(t) - v(t - T)) . n``, the regenerative chip. Where h <= 0 the tooth is out of
  the cut: no force, and the memory keeps the older surface, so the next tooth meets a thicker
  chip. A bin the geometry reports outside the stock is forgotten; its first visit in the stock
  cuts the nominal chip the stock presents.
- Forces are those of :func:`analysis.forces.endmill.element_forces` (Altintas' linear edge-force
  law) with the material's true coefficients; tests check the kernel against it.
- Chip-breaker overload (``EndMill.max_chip_mm``, ``EndMill.overload_gain``): catalogues give each
  edge a working range of chip thickness; above its upper end the chip no longer curls in the
  chip breaker but is jammed against its wall and crushed (obstruction-type chip breaking,
  Jawahir & van Luttervelt 1993). A tooth whose largest chip h_ex = f_z sin(kappa_max) (the
  catalogue's figure: the feed per tooth thinned by the deepest engaged edge's kappa) exceeds
  max_chip_mm has its cutting pressures (K_tc, K_rc, K_ac; not the edge terms) multiplied by
  ``1 + overload_gain (h_ex / max_chip_mm - 1)``. So the force rises sharply above that feed, and
  the stiffer process lowers the stability limit, where the tool modes bring it near.

Not modelled: axial (z) tool modes, the dynamometer's compliance in the loop (its modes filter the
measured force only, :mod:`rig.sim._machine_signal`), process damping, face mills (they stay
quasi-static), and a spindle speed change in mid-cut (it resets the memory).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from numba import njit

from analysis.config import EndMill, EndMillCoefficients, ToolMode
from rig.sim._machine_engagement import EndMillEngagement, endmill_engagement
from rig.sim._machine_timeline import MotionTimeline

#: Resolution of the internal time step (see the module docstring).
MIN_STEPS_PER_TOOTH = 40
STEPS_PER_MODE_PERIOD = 20


def overload_factor(eng: EndMillEngagement, tool: EndMill) -> np.ndarray:
    """Cutting-pressure factor (n, teeth) of the chip-breaker overload (module docstring)."""
    n, teeth = eng.engaged.shape[:2]
    if tool.max_chip_mm is None:
        return np.ones((n, teeth))
    sk = np.where(eng.engaged, np.sin(eng.kappa_rad)[None, None, :], 0.0).max(axis=2)
    excess = np.maximum(eng.fz_mm[:, None] * sk / tool.max_chip_mm - 1.0, 0.0)
    return 1.0 + tool.overload_gain * excess


def modal_zoh(modes: tuple[ToolMode, ...], dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Per mode, the exact zero-order-hold step: state (x mm, v mm/s) -> Ad (m, 2, 2) @ state +
    Bd (m, 2) * force N."""
    ad = np.empty((len(modes), 2, 2))
    bd = np.empty((len(modes), 2))
    for i, m in enumerate(modes):
        w = 2 * math.pi * m.f_hz
        a = np.array([[0.0, 1.0], [-(w**2), -2 * m.zeta * w]])
        b = np.array([0.0, w**2 * 1e3 / m.k_N_m])  # N -> mm of static deflection
        # expm of the augmented matrix gives Ad and the held input's response together.
        aug = np.zeros((3, 3))
        aug[:2, :2], aug[:2, 2] = a * dt_s, b * dt_s
        e = scipy.linalg.expm(aug)
        ad[i], bd[i] = e[:2, :2], e[:2, 2]
    return ad, bd


@functools.lru_cache(maxsize=8)
def _free_zoh(modes: tuple[ToolMode, ...], dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    return modal_zoh(modes, dt_s)


@njit(cache=True)
def _kernel(
    engaged, theta, edge, px, py, fz_mm, offset, bins_per_rev, over, sin_k, cos_k, db, coef,
    sense, memory, valid, state, ad, bd, axis, half_dt, force,
):  # fmt: skip
    """March the steps of one chunk (module docstring); writes ``force`` (J, 3) N on the
    workpiece, machine axes, and updates ``memory``, ``valid`` and the modal ``state``."""
    n_steps, teeth, slices = engaged.shape
    n_modes = state.shape[0]
    to_bin = bins_per_rev / (2 * np.pi)
    for j in range(n_steps):
        dx = 0.0
        dy = 0.0
        for m in range(n_modes):
            # The deflection half a step ahead: the force is then held over the step it acts
            # in, centred, instead of lagging it by half a step (which costs stability margin).
            d = state[m, 0] + half_dt * state[m, 1]
            if axis[m] == 0:
                dx += d
            else:
                dy += d
        fx = 0.0
        fy = 0.0
        fz = 0.0
        for k in range(teeth):
            for s in range(slices):
                b = int(np.rint(theta[j, k, s] * to_bin - offset[s])) % bins_per_rev
                if not engaged[j, k, s]:
                    valid[s, b] = False
                    continue
                c = np.cos(edge[j, k, s])
                si = np.sin(edge[j, k, s])
                p_n = px[j] * c + py[j] * si
                pos = p_n + dx * c + dy * si
                if not valid[s, b]:
                    memory[s, b] = p_n - fz_mm[j] * np.sin(theta[j, k, s])
                    valid[s, b] = True
                h = (pos - memory[s, b]) * sin_k[s]
                if h <= 0.0:
                    continue
                memory[s, b] = pos
                w = db[s]
                o = over[j, k]
                ft = (o * coef[0] * h + coef[3]) * w
                fr = (o * coef[1] * h + coef[4]) * w
                fa = (o * coef[2] * h + coef[5]) * w
                fn = fr * sin_k[s] + fa * cos_k[s]
                fx += sense * ft * si + fn * c
                fy += -sense * ft * c + fn * si
                fz += -fr * cos_k[s] + fa * sin_k[s]
        force[j, 0] = fx
        force[j, 1] = fy
        force[j, 2] = fz
        # The tool feels minus the workpiece force.
        for m in range(n_modes):
            f = -fx if axis[m] == 0 else -fy
            x0 = state[m, 0]
            v0 = state[m, 1]
            state[m, 0] = ad[m, 0, 0] * x0 + ad[m, 0, 1] * v0 + bd[m, 0] * f
            state[m, 1] = ad[m, 1, 0] * x0 + ad[m, 1, 1] * v0 + bd[m, 1] * f


@dataclass
class _Grid:
    rpm: float
    dt_s: float
    bins_per_rev: int
    z_mm: np.ndarray
    offset: np.ndarray  # (slices,) fraction of a bin at which each slice's edges sit


def _bin_position(theta_rad: np.ndarray, bins_per_rev: int) -> np.ndarray:
    return theta_rad * (bins_per_rev / (2 * np.pi))


class RegenEndMill:
    """Stateful regenerative cutting of one end mill over consecutive DAQ reads.

    :meth:`forces` returns the force (n, 3) N on the workpiece, machine axes, at the DAQ sample
    times, interpolated from the internal steps; the modes, the surface memory and the step grid
    carry over from one call to the next.
    """

    def __init__(
        self, tool: EndMill, coef: EndMillCoefficients, modes: tuple[ToolMode, ...],
        rate_hz: float, n_slices: int = 16,
    ) -> None:  # fmt: skip
        self.tool = tool
        self.coef = np.array(
            [coef.Ktc_n_mm2, coef.Krc_n_mm2, coef.Kac_n_mm2, coef.Kte_n_mm, coef.Kre_n_mm,
             coef.Kae_n_mm]
        )  # fmt: skip
        self.modes = tuple(modes)
        self.axis = np.array([0 if m.axis == "x" else 1 for m in modes], dtype=np.int64)
        self.state = np.zeros((len(modes), 2))
        self.rate_hz = float(rate_hz)
        self.n_slices = n_slices
        self._grid: _Grid | None = None
        self._memory = np.zeros((0, 0))
        self._valid = np.zeros((0, 0), dtype=bool)
        self._t_next: float | None = None
        self._last: tuple[float, np.ndarray] | None = None

    def displacement_mm(self) -> np.ndarray:
        """The tool's present deflection (x, y), mm."""
        d = np.zeros(2)
        np.add.at(d, self.axis, self.state[:, 0])
        return d

    def _dt(self, rpm: float) -> tuple[float, int]:
        teeth = self.tool.flutes
        tooth_s = 60.0 / (abs(rpm) * teeth)
        f_max = max((m.f_hz for m in self.modes), default=0.0)
        per_tooth = max(
            MIN_STEPS_PER_TOOTH,
            math.ceil(STEPS_PER_MODE_PERIOD * f_max * tooth_s),
            math.ceil(self.rate_hz * tooth_s),
        )
        return tooth_s / per_tooth, per_tooth * teeth

    def forces(self, t_s: np.ndarray, timeline: MotionTimeline, stock: Any) -> np.ndarray:
        """``stock``: a ``BlockStock`` or ``ZMapStock`` (``top_z``, ``z_max_mm``)."""
        t = np.asarray(t_s, dtype=float)
        if t.size == 0:
            return np.zeros((0, 3))
        rpm = float(timeline.state(t[-1:]).spindle_rpm[0])
        if rpm == 0.0:
            dt, m_rev = 1.0 / self.rate_hz, 0
        else:
            dt, m_rev = self._dt(rpm)
        t_start = self._t_next
        if t_start is None or t_start > t[0] + 1e-12 or t[0] - t_start > 1.0:
            t_start, self._last = float(t[0]), None  # the first read, or a gap: start afresh
        n_steps = max(int(math.floor((t[-1] - t_start) / dt)) + 1, 1)
        tau = t_start + dt * np.arange(n_steps)
        force = np.zeros((n_steps, 3))
        st = timeline.state(tau)
        depth_mm = stock.z_max_mm - float(np.min(st.position_mm[:, 2]))
        if depth_mm > 0 and m_rev:
            eng = endmill_engagement(st, self.tool, stock, depth_mm, self.n_slices)
            self._prepare(rpm, dt, m_rev, eng)
            self._march(eng, st, m_rev, force)
        else:
            self._march_free(dt, n_steps)
        self._t_next = float(tau[-1] + dt)
        tt, ff = tau, force
        if self._last is not None:
            tt = np.concatenate([[self._last[0]], tau])
            ff = np.vstack([self._last[1][None, :], force])
        self._last = (float(tau[-1]), force[-1].copy())
        return np.stack([np.interp(t, tt, ff[:, i]) for i in range(3)], axis=1)

    def _prepare(self, rpm: float, dt: float, m_rev: int, eng: EndMillEngagement) -> None:
        """Keep the memory while the grid holds; a new speed, depth or feed direction (the edges
        no longer sit where the bins are) starts it afresh."""
        z = eng.z_mm
        # Each step turns every edge by exactly one bin, so an edge's fractional bin position
        # is constant; bins are counted from it, never rounded near a half.
        offset = np.mod(_bin_position(eng.theta_rad[0, 0, :], m_rev), 1.0)
        g = self._grid
        if (
            g is None or g.bins_per_rev != m_rev or g.rpm != rpm
            or g.z_mm.shape != z.shape or not np.allclose(g.z_mm, z)
            or np.any(np.abs(np.mod(offset - g.offset + 0.5, 1.0) - 0.5) > 0.25)
        ):  # fmt: skip
            self._grid = _Grid(rpm, dt, m_rev, z.copy(), offset)
            self._memory = np.zeros((z.size, m_rev))
            self._valid = np.zeros((z.size, m_rev), dtype=bool)
            self._zoh = modal_zoh(self.modes, dt)

    def _march(self, eng: EndMillEngagement, st, m_rev: int, force: np.ndarray) -> None:
        sense = 1.0 if st.spindle_rpm[-1] >= 0 else -1.0
        sk = np.sin(eng.kappa_rad)
        db = eng.dz_mm / np.where(sk > 1e-12, sk, 1.0)
        ad, bd = self._zoh
        p = np.ascontiguousarray(st.position_mm[:, :2].T)
        grid = self._grid
        assert grid is not None  # the caller set it up for this engagement
        _kernel(
            eng.engaged, eng.theta_rad, eng.edge_rad, p[0], p[1], eng.fz_mm, grid.offset,
            m_rev, overload_factor(eng, self.tool), sk, np.cos(eng.kappa_rad), db, self.coef,
            sense, self._memory, self._valid, self.state, ad, bd, self.axis,
            0.5 * grid.dt_s, force,
        )  # fmt: skip

    def _march_free(self, dt: float, n_steps: int) -> None:
        """No cut: the modes ring down (the memory stays for a later read)."""
        if not self.modes:
            return
        ad, _ = _free_zoh(self.modes, dt)
        p = np.stack([np.linalg.matrix_power(a, n_steps) for a in ad])
        self.state = np.einsum("mij,mj->mi", p, self.state)
