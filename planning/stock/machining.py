"""Virtual machining of NC programs on a Z-map (seed 001 2.1 and 3).

Seed 001 manages one die as an operation plan: an ordered list of NC programs, each with its tool
and holder, machined on the same stock, so that the pencil or rest-roughing program meets what the
roughing left. :func:`simulate_motion` runs one program's canonical motion on a :class:`ZMap`
(arcs linearised within a chordal tolerance, long moves cut in pieces), returns the volume removed
per piece and per segment, and checks the holder and the spindle nose against the stock after
every move (any contact is reported with its block). :class:`planning.stock.plans.OperationPlan`
runs several in order.

Before anything is cut, :func:`check_motion` refuses a program the machine cannot run or that
leaves the stock: a point outside the machine's travel, a feed move below the stock's underside,
an arc smaller than the control's smallest radius or whose end radius differs from its start radius
by more than the machine's tolerance, a feed move with no feed.

Stock spec (:func:`load_stock`): ``box:XMIN,XMAX,YMIN,YMAX,BOTTOM,TOP`` (mm), an ``.stl`` /
``.obj`` / ``.ply`` mesh, a ``.npy`` height field with its corner and spacing in a TOML, or a TOML
file with a ``[stock]`` table::

    [stock]
    kind = "box"                   # box | mesh | heights
    xmin_mm = 0.0                  # box: xmin/xmax/ymin/ymax/bottom/top _mm
    spacing_mm = 0.25              # optional; --spacing overrides
    # mesh: path = "part.stl", margin_mm = 5, bottom_mm (optional)
    # heights: path = "top.npy" (ny x nx, mm), x0_mm, y0_mm, bottom_mm (optional)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from analysis.config import EndMill, MachineConfig
from planning.errors import PlanningError
from planning.nc import DWELL, LINE, RAPID, Motion
from planning.nc.arcs import PLANE_AXES, Linearized, arc_radius_mm, linearize
from planning.stock import _kernels as _k
from planning.stock._numba import MAX_ARCS, N_ARC
from planning.stock.pieces import split_pieces
from planning.stock.starts import (
    default_stock,
    load_stock,
)
from planning.stock.zmap import Cutter, ZMap

#: the engaged arcs (``Simulation.piece_arcs``): at most this many per piece, on this grid
ARC_STEP_RAD = math.pi / N_ARC
#: chordal tolerance for arcs, mm (the Z-map's own resolution is far coarser)
DEFAULT_CHORD_TOL_MM = 0.001
_CONTACT_TOL_MM = 1e-6


@dataclass(frozen=True)
class HolderContact:
    """The holder (or the spindle nose) touching the stock during one block."""

    block: int
    line: int
    part: str  # "holder" or "spindle nose"
    overlap_mm: float  # how far the stock reaches above the part's underside, mm
    position_mm: tuple[float, float, float]  # tool tip at the end of the touching move, mm

    def message(self, file: str = "<program>") -> str:
        x, y, z = self.position_mm
        return (
            f"{file}:{self.line}: block {self.block}: {self.part} touches the stock by "
            f"{self.overlap_mm:.3f} mm (tip at X{x:.3f} Y{y:.3f} Z{z:.3f})"
        )


@dataclass(frozen=True)
class Simulation:
    """Virtual machining of one program: what each piece of each segment removed.

    Attributes
    ----------
    motion : Motion, n segments
    piece_segment : ndarray (k,), int — the motion segment of each piece
    piece_start_mm, piece_end_mm : ndarray (k, 3), mm
    piece_removed_mm3 : ndarray (k,), mm^3
    removed_mm3 : ndarray (n,), mm^3 — per segment
    piece_depth_mm : ndarray (k,), mm — deepest height drop of each piece (axial depth met)
    piece_arcs : ndarray (k, 3 * MAX_ARCS) — the cutter's engaged arcs at each piece's middle
        before it cut: entry rad, exit rad, depth mm each (NaN: none; ``ZMap.cut_pieces``)
    contacts : tuple of HolderContact
    rapid_cut_segments : ndarray, int — rapid moves that removed material (a crash on a machine)
    """

    motion: Motion
    piece_segment: NDArray[np.int64]
    piece_start_mm: NDArray[np.float64]
    piece_end_mm: NDArray[np.float64]
    piece_removed_mm3: NDArray[np.float64]
    removed_mm3: NDArray[np.float64]
    piece_depth_mm: NDArray[np.float64]
    contacts: tuple[HolderContact, ...] = ()
    rapid_cut_segments: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    piece_arcs: NDArray[np.float32] | None = None

    @property
    def piece_length_mm(self) -> NDArray[np.float64]:
        length: NDArray[np.float64] = np.linalg.norm(
            self.piece_end_mm - self.piece_start_mm, axis=1
        )
        return length

    @property
    def removed_total_mm3(self) -> float:
        return float(self.removed_mm3.sum())


def plunge_mask(
    start_mm: NDArray[np.float64], end_mm: NDArray[np.float64], tol_mm: float = 1e-9
) -> NDArray[np.bool_]:
    """True for Z-only moves (seed 001's plunge formula applies to them)."""
    d = end_mm - start_mm
    return (np.hypot(d[:, 0], d[:, 1]) <= tol_mm) & (np.abs(d[:, 2]) > tol_mm)


def check_motion(
    motion: Motion,
    machine: MachineConfig | None,
    stock: ZMap | None = None,
    cutter: Cutter | None = None,
    file: str = "<program>",
    chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
) -> None:
    """Raise :class:`PlanningError` naming file, line, block, field, value and range if the
    program cannot run on ``machine`` or leaves ``stock``; return None when it can.
    """
    if len(motion) == 0:
        raise PlanningError(f"{file}: the program has no motion")
    lin = linearize(motion, chord_tol_mm)
    _check_rotary(motion, file)
    _check_feeds(motion, file)
    if machine is not None:
        _check_travel(motion, lin, machine, file)
        _check_arcs(motion, machine, file)
    if stock is not None:
        _check_stock_floor(motion, lin, stock, cutter, file)


def _where(motion: Motion, file: str, seg: int) -> str:
    return f"{file}:{int(motion.line[seg])}: block {int(motion.block[seg])}"


def _check_rotary(motion: Motion, file: str) -> None:
    """No block turns a rotary axis: the Z-map is 3-axis."""
    turning = motion.has_rotary_travel
    if turning.any():
        i = int(np.argmax(turning))
        raise PlanningError(
            f"{_where(motion, file, i)}: the block turns a rotary axis (A/B/C); the Z-map is "
            "3-axis, so a 5-axis program cannot be simulated or post-processed"
        )


def _check_feeds(motion: Motion, file: str) -> None:
    """Every feed move has a feed > 0."""
    bad_feed = motion.is_feed & ~(motion.feed_mm_min > 0)
    if bad_feed.any():
        i = int(np.argmax(bad_feed))
        raise PlanningError(
            f"{_where(motion, file, i)}: feed move with F = {motion.feed_mm_min[i]}: needs a "
            "feed > 0 mm/min"
        )


def _check_travel(motion: Motion, lin: Linearized, machine: MachineConfig, file: str) -> None:
    """Every point of the (linearised) path within the machine's X, Y and Z travel."""
    pts = np.concatenate([lin.start, lin.end])
    src = np.concatenate([lin.source, lin.source])
    for axis, name in enumerate("xyz"):
        travel = getattr(machine, name)
        out = (pts[:, axis] < travel.min_mm - 1e-9) | (pts[:, axis] > travel.max_mm + 1e-9)
        if out.any():
            i = int(np.argmax(out))
            raise PlanningError(
                f"{_where(motion, file, int(src[i]))}: {name.upper()} = {pts[i, axis]:.4f} mm is "
                f"outside machine '{machine.name}' travel [{travel.min_mm}, {travel.max_mm}] mm"
            )


def _check_arcs(motion: Motion, machine: MachineConfig, file: str) -> None:
    """Every arc's radius at least the control's smallest, its end radius within the
    machine's tolerance of its start radius."""
    arcs = np.nonzero(motion.is_arc)[0]
    if not len(arcs):
        return
    r0 = arc_radius_mm(motion)[arcs]
    ax = np.array([PLANE_AXES[int(p)] for p in motion.plane[arcs]])
    ea = motion.end[arcs, ax[:, 0]] - motion.center[arcs, ax[:, 0]]
    eb = motion.end[arcs, ax[:, 1]] - motion.center[arcs, ax[:, 1]]
    r1 = np.hypot(ea, eb)
    small = r0 < machine.min_arc_radius_mm
    if small.any():
        i = int(arcs[np.argmax(small)])
        raise PlanningError(
            f"{_where(motion, file, i)}: arc radius {r0[np.argmax(small)]:.4f} mm is below "
            f"machine '{machine.name}' min_arc_radius_mm = {machine.min_arc_radius_mm} mm"
        )
    mismatch = np.abs(r1 - r0) > machine.arc_radius_tolerance_mm
    if mismatch.any():
        j = int(np.argmax(mismatch))
        raise PlanningError(
            f"{_where(motion, file, int(arcs[j]))}: arc end radius {r1[j]:.4f} mm differs from "
            f"its start radius {r0[j]:.4f} mm by more than machine '{machine.name}' "
            f"arc_radius_tolerance_mm = {machine.arc_radius_tolerance_mm} mm"
        )


def _check_stock_floor(
    motion: Motion, lin: Linearized, stock: ZMap, cutter: Cutter | None, file: str
) -> None:
    """No feed move over the stock (plus the cutter radius) goes below its underside."""
    xmin, xmax, ymin, ymax = stock.extent_mm
    r = cutter.radius_mm if cutter is not None else 0.0
    p0, p1 = lin.start, lin.end
    # Part of each feed move over the stock (plus the cutter radius), Liang-Barsky clipping.
    t0, t1 = np.zeros(len(p0)), np.ones(len(p0))
    over = motion.is_feed[lin.source].copy()
    for axis, lo, hi in ((0, xmin - r, xmax + r), (1, ymin - r, ymax + r)):
        d = p1[:, axis] - p0[:, axis]
        still = d == 0
        over &= ~still | ((p0[:, axis] >= lo) & (p0[:, axis] <= hi))
        with np.errstate(divide="ignore", invalid="ignore"):
            ta = np.where(still, -np.inf, (lo - p0[:, axis]) / d)
            tb = np.where(still, np.inf, (hi - p0[:, axis]) / d)
        t0 = np.maximum(t0, np.minimum(ta, tb))
        t1 = np.minimum(t1, np.maximum(ta, tb))
    over &= t0 <= t1
    dz = p1[:, 2] - p0[:, 2]
    zlow = np.minimum(p0[:, 2] + t0 * dz, p0[:, 2] + t1 * dz)
    below = over & (zlow < stock.bottom_mm - 1e-6)
    if below.any():
        i = int(np.argmax(below))
        raise PlanningError(
            f"{_where(motion, file, int(lin.source[i]))}: Z = {zlow[i]:.4f} mm leaves the stock: "
            f"below its underside at {stock.bottom_mm} mm (the tool would cut the fixture)"
        )


def _holder_contacts(
    stock: ZMap,
    tool: EndMill,
    p0: Sequence[float],
    p1: Sequence[float],
) -> list[tuple[str, float]]:
    """Parts of the tool assembly above the flutes whose underside the stock reaches."""
    out = []
    holder = tool.holder
    parts = (
        ("holder", holder.diameter_mm / 2, tool.length_mm),
        ("spindle nose", holder.spindle_nose_diameter_mm / 2, tool.length_mm + holder.length_mm),
    )
    for name, radius, lift in parts:
        h = stock.max_height_near(p0, p1, radius)
        if h.size == 0:
            continue
        x0, y0, z0 = p0
        x1, y1, z1 = p1
        i0, i1, j0, j1 = stock._patch(  # noqa: SLF001 - same module family
            min(x0, x1) - radius, max(x0, x1) + radius, min(y0, y1) - radius, max(y0, y1) + radius
        )
        env = _k.envelope(
            _k.FLAT, radius, 0.0, stock.x_mm[i0:i1] - x0, stock.y_mm[j0:j1, None] - y0,
            x1 - x0, y1 - y0, z1 - z0, z0 + lift,
        )  # fmt: skip
        over = float(np.max(h - env))
        if over > _CONTACT_TOL_MM:
            out.append((name, over))
    return out


def _holder_check_pieces(
    stock: ZMap, tool: EndMill, p0: NDArray[np.float64], p1: NDArray[np.float64]
) -> NDArray[np.int64]:
    """The pieces after which the holder must be checked. The stock never rises, so its highest
    point now bounds it for the whole program: pieces whose holder underside stays above it
    need no check."""
    if not len(p0):
        return np.zeros(0, np.int64)
    lowest_holder = np.minimum(p0[:, 2], p1[:, 2]) + tool.length_mm
    check: NDArray[np.int64] = np.nonzero(
        lowest_holder < float(stock.heights_mm.max()) - _CONTACT_TOL_MM
    )[0]
    return check


def _record_contacts(
    contacts: dict[tuple[int, str], HolderContact], stock: ZMap, tool: EndMill, motion: Motion,
    s: int, p0: NDArray[np.float64], p1: NDArray[np.float64],
) -> None:  # fmt: skip
    """The holder's and spindle nose's contacts after the piece ``p0``-``p1`` of segment ``s``
    into ``contacts``: the deepest per block and part."""
    for name, over in _holder_contacts(stock, tool, p0.tolist(), p1.tolist()):
        key = (int(motion.block[s]), name)
        prev = contacts.get(key)
        if prev is None or over > prev.overlap_mm:
            contacts[key] = HolderContact(
                block=int(motion.block[s]),
                line=int(motion.line[s]),
                part=name,
                overlap_mm=over,
                position_mm=(float(p1[0]), float(p1[1]), float(p1[2])),
            )


def simulate_motion(
    stock: ZMap,
    tool: EndMill,
    motion: Motion,
    *,
    chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
    piece_mm: float = math.inf,
    check_holder: bool = True,
    track_depth: bool = False,
    until_block: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Simulation:
    """Machine ``motion`` with ``tool`` on ``stock`` (lowered in place).

    Parameters
    ----------
    piece_mm : float, mm
        Longest piece a linear move (or an arc chord) is cut in; the removed volume is reported per
        piece, so a long block's load is known along it.
    check_holder : bool
        Check the holder and spindle nose against the stock after each move that could reach it.
    track_depth : bool
        Record each piece's deepest height drop (``piece_depth_mm``; zeros otherwise) and its
        engaged arcs (``piece_arcs``; None otherwise).
    until_block : int, optional
        Stop after this block (0-based): ``stock`` is then the stock at that moment, and the
        result covers the segments up to it.
    progress : callable(done, total), optional
    """
    cutter = Cutter.from_tool(tool)
    if until_block is not None:
        motion = motion[motion.block <= until_block]
    lin = linearize(motion, chord_tol_mm)
    keep = lin.kind != DWELL
    src = lin.source[keep]
    move, p0, p1 = split_pieces(lin.start[keep], lin.end[keep], piece_mm)
    seg = src[move]
    removed = np.zeros(len(move))
    depth = np.zeros(len(move))
    # float32: 120 bytes a piece (a million-piece program: 120 MB)
    arcs = np.full((len(move), 3 * MAX_ARCS), np.nan, np.float32) if track_depth else None
    contacts: dict[tuple[int, str], HolderContact] = {}
    check = _holder_check_pieces(stock, tool, p0, p1) if check_holder else np.zeros(0, np.int64)
    done = 0
    total = len(move)

    def report(k: int) -> None:
        if progress is not None:
            progress(done + k, total)

    for k in [*check.tolist(), None]:
        stop = total if k is None else k + 1
        if stop > done:
            removed[done:stop] = stock.cut_pieces(
                cutter, p0[done:stop], p1[done:stop], report,
                depth[done:stop] if track_depth else None,
                None if arcs is None else arcs[done:stop],
            )  # fmt: skip
            done = stop
            if progress is not None:
                progress(done, total)
        if k is None:
            break
        _record_contacts(contacts, stock, tool, motion, int(seg[k]), p0[k], p1[k])
    # float with weights (numpy's stubs say int); no copy
    per_seg = np.bincount(seg, weights=removed, minlength=len(motion)).astype(
        np.float64, copy=False
    )
    rapid_cut = np.nonzero((motion.kind == RAPID) & (per_seg > 1e-9))[0]
    ordered = tuple(sorted(contacts.values(), key=lambda c: (c.block, c.part)))
    return Simulation(motion, seg, p0, p1, removed, per_seg, depth, ordered, rapid_cut, arcs)


__all__ = [
    "HolderContact",
    "LINE",
    "Simulation",
    "check_motion",
    "default_stock",
    "load_stock",
    "plunge_mask",
    "simulate_motion",
]
