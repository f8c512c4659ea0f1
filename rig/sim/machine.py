"""The simulated machine: executed motion -> edge engagement -> cutting forces -> dynamometer
volts, as a signal source for the simulated DAQ.

The simulated controller reports every segment it executes on the shared :class:`SimClock`
(:meth:`SimMachine.on_segment`); the simulated DAQ asks for volts over a span of that same clock
(:meth:`SimMachine.source`). For each sample the machine finds where the cutter is, its feed and
spindle angle (:mod:`rig.sim._machine_timeline`), which inserts or flute elements are in the stock
(:mod:`rig.sim._machine_engagement`), the forces of those edges from the ``analysis`` force models
with the material's *true* coefficients, and passes the summed force through the dynamometer's
modes and the charge amplifier (:mod:`rig.sim._machine_signal`).

The stock is the test block (:class:`planning.stock.block.SteppedBlock`) for a face mill's single
pass, or a ``planning.stock.zmap.ZMap`` lowered by every completed segment for end mills, so a later
pass sees what an earlier one left.

Notes
-----
How the twin differs from a real machine and dynamometer:

- Engagement is the leading half of the cutter in uncut stock; a reversing path inside one DAQ
  read (0.1 s) sees the stock as it was at the start of that read.
- An end mill with tool modes (the twin's own structure, :mod:`rig.sim.structure`, or the
  campaign's ``[[sim.tool_modes]]``; never the catalogue's ``[[tools.NAME.modes]]``, which are
  measured on the twin by a tap test) cuts regeneratively (:mod:`rig.sim._regen`: tool
  deflection, the chip left by the earlier teeth, chatter where the stability lobes say);
  without modes, and for face mills, forces are quasi-static and only the dynamometer's modes
  add dynamics. An end mill's ``max_chip_mm`` limits the feed: above it the chip jams in the
  chip breaker and the force rises sharply (:func:`rig.sim._regen.overload_factor`). Runout,
  tool wear and built-up edge are not modelled.
- Noise is white and Gaussian, drift linear, hum one sinusoid; the amplifier never saturates here
  (the simulated DAQ's ``sim_`` knobs do that).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from analysis.config import Dynamometer, EndMill, FaceMill, Material, ToolMode
from analysis.forces import ENDMILL, FACEMILL, model_for
from rig.errors import RigError
from rig.sim._machine_engagement import (
    EndMillEngagement,
    FaceMillEngagement,
    endmill_engagement,
    facemill_engagement,
)
from rig.sim._machine_signal import DynoChain
from rig.sim._machine_timeline import ExecutedSegment, MotionTimeline
from rig.sim._regen import RegenEndMill, overload_factor
from rig.sim.structure import twin_modes


@dataclass(frozen=True)
class SignalSettings:
    """Disturbances at the amplifier output (N, N/s, Hz) and the rng seed."""

    noise_n: float = 1.0
    drift_n_s: float = 0.05
    hum_n: float = 0.5
    hum_hz: float = 50.0
    seed: int = 2003
    modes: bool = True


class _Sideless:
    """A block seen without its sides across the feed (the force model takes those)."""

    def __init__(self, block: Any) -> None:
        self.block = block

    def top_z(self, x_mm: np.ndarray, y_mm: np.ndarray) -> np.ndarray:
        b = self.block
        return b.top_z(x_mm, np.clip(y_mm, b.y_min_mm, b.y_max_mm))


class BlockStock:
    """An analytic block (``SteppedBlock``-like: anything with ``top_z(x, y)``) as the stock."""

    def __init__(self, block: object) -> None:
        self.block = block

    def top_z(self, x_mm: np.ndarray, y_mm: np.ndarray) -> np.ndarray:
        return self.block.top_z(x_mm, y_mm)  # type: ignore[attr-defined]

    def advance(self, t_s: float, timeline: MotionTimeline) -> None:
        """A single pass never meets its own cut on the leading half: nothing to update."""

    def pending_ends_s(self, t_s: float, timeline: MotionTimeline) -> list[float]:
        return []

    @property
    def z_max_mm(self) -> float:
        return float(max(self.block.step_top_mm))  # type: ignore[attr-defined]


class ZMapStock:
    """A ``planning.stock.zmap.ZMap`` lowered by each segment once the clock has passed its end."""

    def __init__(self, zmap: object, tool: EndMill) -> None:
        from planning.stock import Cutter

        self.zmap = zmap
        self.cutter = Cutter.from_tool(tool)
        self._applied = 0
        self._from_mm: tuple[float, float, float] | None = None  # a split line's first start
        self.removed_mm3: list[float] = []

    def top_z(self, x_mm: np.ndarray, y_mm: np.ndarray) -> np.ndarray:
        h = self.zmap.height_at(x_mm, y_mm)  # type: ignore[attr-defined]
        return np.where(np.isnan(h), -np.inf, h)

    def advance(self, t_s: float, timeline: MotionTimeline) -> None:
        segs = timeline.segments
        while self._applied < len(segs) and segs[self._applied].t_end_s <= t_s:
            g = segs[self._applied]
            nxt = segs[self._applied + 1] if self._applied + 1 < len(segs) else None
            start = self._from_mm or g.start_mm
            self._applied += 1
            if nxt is not None and _continues(g, nxt):
                # a line split where it runs (a GRBL override): cutting the first part's whole
                # envelope would take the stock in front of the tool (a false dip of about 20 %
                # for a revolution); the line is cut once, whole, when its last part ends
                self._from_mm = start
                self.removed_mm3.append(0.0)
                continue
            self._from_mm = None
            self.removed_mm3.append(self.zmap.cut(self.cutter, start, g.end_mm))  # type: ignore[attr-defined]

    def pending_ends_s(self, t_s: float, timeline: MotionTimeline) -> list[float]:
        """End times of the segments not yet cut that end by ``t_s``, s."""
        segs = timeline.segments
        out = []
        for g in segs[self._applied :]:
            if g.t_end_s > t_s:
                break
            out.append(g.t_end_s)
        return out

    @property
    def z_max_mm(self) -> float:
        return float(np.nanmax(self.zmap.heights_mm))  # type: ignore[attr-defined]


def _continues(a: ExecutedSegment, b: ExecutedSegment) -> bool:
    """``b`` goes on with the straight feed move ``a`` without a stop: the same block's line
    from where and when ``a`` ended, in the same direction (a part of no length and no time
    between them, several override bytes taken at once, is no stop)."""
    from planning.nc import LINE

    if a.kind != LINE or b.kind != LINE or a.block != b.block:
        return False
    if abs(b.t_start_s - a.t_end_s) > 1e-9 or not np.allclose(a.end_mm, b.start_mm, atol=1e-9):
        return False
    da = np.subtract(a.end_mm, a.start_mm)
    db = np.subtract(b.end_mm, b.start_mm)
    na, nb = float(np.linalg.norm(da)), float(np.linalg.norm(db))
    if (na == 0 and a.t_end_s - a.t_start_s < 1e-12) or (nb == 0 and b.t_end_s == b.t_start_s):
        return True
    return na > 0 and nb > 0 and float(np.dot(da, db)) / (na * nb) > 1 - 1e-9


def _rotate_xy(f: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Rotate forces (n, 3) given in a frame with the feed along +X into machine axes."""
    c, s = np.cos(beta), np.sin(beta)
    out = f.copy()
    out[:, 0] = c * f[:, 0] - s * f[:, 1]
    out[:, 1] = s * f[:, 0] + c * f[:, 1]
    return out


def _truth(material: Material, tool: EndMill | FaceMill) -> Any:
    model = model_for(tool)
    coef = model.coefficients(material)
    if coef is None:
        raise RigError(f"material has no {model.name} coefficients: the simulator needs a truth")
    return coef


def _summed(
    eng: FaceMillEngagement | EndMillEngagement,
    forces_at: Callable[[tuple[np.ndarray, ...]], np.ndarray],
) -> np.ndarray:
    """Forces (n, 3) N in machine axes: ``forces_at(idx)`` (m, 3) for the engaged entries
    ``idx = np.nonzero(eng.engaged)`` (sample first), summed per sample."""
    f = np.zeros((eng.theta_rad.shape[0], 3))
    idx = np.nonzero(eng.engaged)
    if idx[0].size:
        np.add.at(f, idx[0], forces_at(idx))
    return _rotate_xy(f, eng.feed_angle_rad)


def twin_facemill_forces(
    eng: FaceMillEngagement, tool: FaceMill, material: Material,
    strip: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:  # fmt: skip
    """Summed insert forces (n, 3) N in machine axes (seed 003 model with ploughing).

    ``strip``: the block's sides across the feed (Y' low, high per sample, mm from the cutter
    axis); the model then takes each height of an insert's chip in and out on its own ray
    (issue 33) and ``eng`` need only say where the insert is over the block along the feed."""
    from analysis.forces import facemill

    coef = _truth(material, tool)
    # Engagement is decided here per insert, so the model sees one insert at a time over the
    # whole half turn (its own width-based engagement is switched off, or given the block's sides).
    one = tool.model_copy(update={"inserts": 1, "insert_angles_deg": None, "runout_mm": 0.0})

    def at(idx: tuple[np.ndarray, ...]) -> np.ndarray:
        if strip is None:
            cut = facemill.FaceMillCut(fz_mm=eng.fz_mm[idx[0]], depth_mm=eng.depth_mm[idx],
                                       entry_deg=0.0, exit_deg=180.0)  # fmt: skip
        else:
            lo, hi = strip[0][idx[0]], strip[1][idx[0]]
            mid = 0.5 * (hi + lo)
            cut = facemill.FaceMillCut(fz_mm=eng.fz_mm[idx[0]], depth_mm=eng.depth_mm[idx],
                                       width_mm=hi - lo, center_offset_mm=mid)  # fmt: skip
        return FACEMILL.forces(eng.theta_rad[idx], one, coef, cut)

    return _summed(eng, at)


def twin_facemill_forces_independent(
    eng: FaceMillEngagement, tool: FaceMill, material: Material,
    strip: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:  # fmt: skip
    """As :func:`twin_facemill_forces`, from :mod:`rig.sim.facemill_independent` (seed 003's
    equations written apart from ``analysis.forces``: the edge sliced axially, each slice's own
    radius and angle): ``[sim] force_model = "independent"``."""
    from rig.sim.facemill_independent import insert_forces

    coef = _truth(material, tool)
    return _summed(
        eng,
        lambda idx: insert_forces(
            eng.theta_rad[idx], idx[1], eng.fz_mm[idx[0]], eng.depth_mm[idx], tool, coef,
            sides_mm=None if strip is None else np.stack([strip[0][idx[0]], strip[1][idx[0]]], 1),
        ),
    )  # fmt: skip


#: Face mills: forces computed this many times per DAQ sample and passed through the
#: dynamometer's modes at that rate (the fit filters its model on a grid finer still).
DYNO_OVERSAMPLE = 4

#: ``[sim] force_model``: where the twin's face-milling forces come from.
FACEMILL_FORCE_MODELS = {
    "seed003": twin_facemill_forces, "independent": twin_facemill_forces_independent,
}  # fmt: skip


def twin_endmill_forces(eng: EndMillEngagement, tool: EndMill, material: Material) -> np.ndarray:
    """Summed edge-element forces (n, 3) N in machine axes (linear edge-force model)."""
    from analysis.forces import endmill

    coef = _truth(material, tool)
    # The chip-breaker overload scales the cutting pressures, i.e. the chip in the linear law.
    h = eng.h_mm * overload_factor(eng, tool)[:, :, None]
    return _summed(
        eng,
        lambda idx: endmill.element_forces(
            eng.theta_rad[idx], h[idx], eng.dz_mm[idx[2]], eng.kappa_rad[idx[2]], coef
        ),
    )


class SimMachine:
    """The twin's physics for one test: feed it executed segments, ask it for volts.

    Parameters
    ----------
    tool, material : the cutter and the work material (its coefficients are the truth).
    dyno : the dynamometer (channels, modes, cross-talk, amplifier ranges).
    stock : :class:`BlockStock` or :class:`ZMapStock`.
    rate_hz : the DAQ's sample rate, Hz.
    signal : disturbances; ``n_slices`` axial slices per flute for end mills.
    tool_modes : the tool's modes for the regenerative twin (default: the twin's own structure
        for the tool's assembly, :func:`rig.sim.structure.twin_modes`).
    force_model : face mills' forces from ``"seed003"`` (``analysis.forces.facemill``) or
        ``"independent"`` (:mod:`rig.sim.facemill_independent`).
    """

    def __init__(
        self,
        tool: EndMill | FaceMill,
        material: Material,
        dyno: Dynamometer,
        stock: BlockStock | ZMapStock,
        rate_hz: float,
        signal: SignalSettings = SignalSettings(),
        n_slices: int = 16,
        tool_modes: tuple[ToolMode, ...] | None = None,
        force_model: str = "seed003",
    ) -> None:
        if force_model not in FACEMILL_FORCE_MODELS:
            raise RigError(f"force_model = {force_model!r}: expected one of "
                           f"{', '.join(FACEMILL_FORCE_MODELS)}")  # fmt: skip
        self.facemill_forces = FACEMILL_FORCE_MODELS[force_model]
        self.tool = tool
        self.model = model_for(tool)
        self.material = material
        self.stock = stock
        self.rate_hz = float(rate_hz)
        self.timeline = MotionTimeline()
        self.chain = DynoChain(
            dyno, rate_hz, signal.noise_n, signal.drift_n_s, signal.hum_n, signal.hum_hz,
            signal.seed, signal.modes,
            # face mills: the dynamometer answers to an insert's entry between samples (issue 33)
            oversample=DYNO_OVERSAMPLE if self.model is FACEMILL else 1,
        )  # fmt: skip
        self.n_slices = n_slices
        # end mills cut regeneratively with modes; face mills quasi-statically (module docstring)
        regenerative = self.model is ENDMILL
        modes = tool_modes
        if modes is None and regenerative:
            modes = twin_modes(tool)  # the twin's physics, not the catalogue's measured modes
        self.regen = (
            RegenEndMill(cast(EndMill, tool), _truth(material, tool), modes, rate_hz, n_slices)
            if modes and regenerative
            else None
        )
        self._lock = threading.Lock()
        self.peak_force_n = 0.0

    @property
    def n_channels(self) -> int:
        return len(self.chain.channel_names)

    # -- from the controller ----------------------------------------------------------------

    def on_segment(self, seg: ExecutedSegment) -> None:
        """Listener for the simulated controller: one executed segment."""
        self.timeline.add(seg)

    def on_spindle(self, t_s: float, rpm: float) -> None:
        """Listener for spindle changes outside motion (M3/M4/M5), rpm signed."""
        self.timeline.add_spindle_breakpoint(t_s, rpm)

    # -- physics -----------------------------------------------------------------------------

    def cutting_force(self, t_s: np.ndarray) -> np.ndarray:
        """True cutting force (n, 3) N in machine axes at sample times ``t_s`` (n,) s."""
        t = np.asarray(t_s, dtype=float)
        if not t.size:
            return np.zeros((0, 3))
        if self.regen is not None:
            self.stock.advance(float(t[0]), self.timeline)
            return self.regen.forces(t, self.timeline, self.stock)
        # The stock is lowered at each segment's end inside the read, not once per read: on a
        # tight arc the cutter would otherwise meet, for up to a read's travel, stock it had
        # already removed (+20 % force on the demo part's 5 mm pocket corners at 0.1 s reads).
        ends = self.stock.pending_ends_s(float(t[-1]), self.timeline)
        cuts = [0, *np.unique(np.searchsorted(t, ends)).tolist(), t.size]
        out = np.zeros((t.size, 3))
        for a, b in zip(cuts[:-1], cuts[1:], strict=True):
            if b > a:
                self.stock.advance(float(t[a]), self.timeline)
                out[a:b] = self._quasi_static(t[a:b])
        return out

    def _quasi_static(self, t: np.ndarray) -> np.ndarray:
        st = self.timeline.state(t)
        tool = self.tool
        if FACEMILL.describes(tool):
            strip = self._block_sides(st)
            if strip is not None:
                # The block's sides to the force model (each height of the chip on its own ray),
                # its ends along the feed to the engagement.
                sideless = _Sideless(self.stock.block)  # type: ignore[union-attr]
                eng = facemill_engagement(st, tool, sideless)
                return self.facemill_forces(eng, tool, self.material, strip)
            eng = facemill_engagement(st, tool, self.stock)
            return self.facemill_forces(eng, tool, self.material)
        if not ENDMILL.describes(tool):
            raise RigError(f"the twin has no force model for tool kind {tool.kind!r}")
        depth = self.stock.z_max_mm - float(np.min(st.position_mm[:, 2]))
        if depth <= 0:
            return np.zeros((t.size, 3))
        em = endmill_engagement(st, tool, self.stock, depth, self.n_slices)
        return twin_endmill_forces(em, tool, self.material)

    def _block_sides(self, st: Any) -> tuple[np.ndarray, np.ndarray] | None:
        """The block's sides as Y' (mm from the cutter axis, the force model's frame) per sample,
        when the stock is a block with sides along X and the cutter feeds along X; else None."""
        if not isinstance(self.stock, BlockStock) or not hasattr(self.stock.block, "y_min_mm"):
            return None
        block = cast(Any, self.stock.block)  # duck-typed: a SteppedBlock-like block (y_min_mm)
        d = np.asarray(st.direction, float)
        if np.any(np.abs(d[:, 1]) > 1e-9):
            return None
        # Y' = n . (p - c), n the feed direction turned +90 deg, mirrored for M4
        sgn = np.where(st.spindle_rpm >= 0, 1.0, -1.0) * np.where(d[:, 0] < 0, -1.0, 1.0)
        cy = st.position_mm[:, 1]
        a, b = sgn * (block.y_min_mm - cy), sgn * (block.y_max_mm - cy)
        return np.minimum(a, b), np.maximum(a, b)

    def source(self, t0_s: float, n: int, rate_hz: float) -> np.ndarray:
        """Volts (channels, n) for the DAQ: samples at ``t0_s + k / rate_hz``, k = 0..n-1."""
        if abs(rate_hz - self.rate_hz) > 1e-9 * self.rate_hz:
            raise RigError(
                f"the DAQ samples at {rate_hz:g} Hz but the machine was built for "
                f"{self.rate_hz:g} Hz"
            )
        k = self.chain.oversample
        t = t0_s + np.arange(n * k) / (self.rate_hz * k)
        with self._lock:
            f = self.cutting_force(t)
            if n:
                self.peak_force_n = max(self.peak_force_n, float(np.max(np.linalg.norm(f, axis=1))))
            return self.chain.volts(f, t0_s)
