"""Virtual machining of NC programs on a Z-map, and operation plans (seed 001 2.1 and 3).

Seed 001 manages one die as an operation plan: an ordered list of NC programs, each with its tool
and holder, machined on the same stock, so that the pencil or rest-roughing program meets what the
roughing left. :func:`simulate_motion` runs one program's canonical motion on a :class:`ZMap`
(arcs linearised within a chordal tolerance, long moves cut in pieces), returns the volume removed
per piece and per segment, and checks the holder and the spindle nose against the stock after
every move (any contact is reported with its block). :class:`OperationPlan` runs several in order.

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

Plan file (TOML, :func:`load_plan`): the stock table above plus::

    [plan]
    machine = "ace-h63"            # name in configs/machines or a path (optional)
    [[operations]]
    name = "roughing"
    program = "rough.nc"           # relative to the plan file
    tool = "phi50-bull"            # name in configs/tools.toml (or --tools), for one tool
    # tools = { T1 = "phi10-flat", T2 = "phi5-drill" }   # instead: a program that changes tools
    rule = "rules/rough.toml"      # optional: the feed rule of this operation

A program is cut with the tool in the spindle: each consecutive run of segments with its own T
number (after M6) is simulated with the end mill mapped to it (:func:`bind_tools`); a program
whose T numbers are not all mapped, or that changes tools under a single ``tool``, is refused.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from analysis.config import EndMill, MachineConfig, get_tool, load_machine
from analysis.forces import ENDMILL
from analysis.validation import JsonObject, Model, read_toml, validate
from planning.errors import PlanningError
from planning.nc import DWELL, LINE, RAPID, Motion, segment_time_s
from planning.nc.arcs import PLANE_AXES, arc_radius_mm, linearize, segment_length_mm
from planning.stock import _kernels as _k
from planning.stock._numba import MAX_ARCS, N_ARC
from planning.stock.starts import (
    _stock_from_model,
    _StockModel,
    default_stock,
    load_stock,
)
from planning.stock.zmap import Cutter, ZMap, split_pieces

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
    pts = np.concatenate([lin.start, lin.end])
    src = np.concatenate([lin.source, lin.source])

    def where(seg: int) -> str:
        return f"{file}:{int(motion.line[seg])}: block {int(motion.block[seg])}"

    turning = motion.has_rotary_travel
    if turning.any():
        i = int(np.argmax(turning))
        raise PlanningError(
            f"{where(i)}: the block turns a rotary axis (A/B/C); the Z-map is 3-axis, so a "
            "5-axis program cannot be simulated or post-processed"
        )
    feed_seg = motion.is_feed
    bad_feed = feed_seg & ~(motion.feed_mm_min > 0)
    if bad_feed.any():
        i = int(np.argmax(bad_feed))
        raise PlanningError(
            f"{where(i)}: feed move with F = {motion.feed_mm_min[i]}: needs a feed > 0 mm/min"
        )
    if machine is not None:
        for axis, name in enumerate("xyz"):
            travel = getattr(machine, name)
            out = (pts[:, axis] < travel.min_mm - 1e-9) | (pts[:, axis] > travel.max_mm + 1e-9)
            if out.any():
                i = int(np.argmax(out))
                raise PlanningError(
                    f"{where(int(src[i]))}: {name.upper()} = {pts[i, axis]:.4f} mm is outside "
                    f"machine '{machine.name}' travel [{travel.min_mm}, {travel.max_mm}] mm"
                )
        arcs = np.nonzero(motion.is_arc)[0]
        if len(arcs):
            r0 = arc_radius_mm(motion)[arcs]
            ax = np.array([PLANE_AXES[int(p)] for p in motion.plane[arcs]])
            ea = motion.end[arcs, ax[:, 0]] - motion.center[arcs, ax[:, 0]]
            eb = motion.end[arcs, ax[:, 1]] - motion.center[arcs, ax[:, 1]]
            r1 = np.hypot(ea, eb)
            small = r0 < machine.min_arc_radius_mm
            if small.any():
                i = int(arcs[np.argmax(small)])
                raise PlanningError(
                    f"{where(i)}: arc radius {r0[np.argmax(small)]:.4f} mm is below machine "
                    f"'{machine.name}' min_arc_radius_mm = {machine.min_arc_radius_mm} mm"
                )
            mismatch = np.abs(r1 - r0) > machine.arc_radius_tolerance_mm
            if mismatch.any():
                j = int(np.argmax(mismatch))
                raise PlanningError(
                    f"{where(int(arcs[j]))}: arc end radius {r1[j]:.4f} mm differs from its start "
                    f"radius {r0[j]:.4f} mm by more than machine '{machine.name}' "
                    f"arc_radius_tolerance_mm = {machine.arc_radius_tolerance_mm} mm"
                )
    if stock is not None:
        xmin, xmax, ymin, ymax = stock.extent_mm
        r = cutter.radius_mm if cutter is not None else 0.0
        p0, p1 = lin.start, lin.end
        # Part of each feed move over the stock (plus the cutter radius), Liang-Barsky clipping.
        t0, t1 = np.zeros(len(p0)), np.ones(len(p0))
        over = feed_seg[lin.source].copy()
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
                f"{where(int(lin.source[i]))}: Z = {zlow[i]:.4f} mm leaves the stock: below "
                f"its underside at {stock.bottom_mm} mm (the tool would cut the fixture)"
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
    # The stock never rises, so its highest point now bounds it for the whole program: pieces
    # whose holder underside stays above it need no check.
    if check_holder and len(move):
        lowest_holder = np.minimum(p0[:, 2], p1[:, 2]) + tool.length_mm
        check = np.nonzero(lowest_holder < float(stock.heights_mm.max()) - _CONTACT_TOL_MM)[0]
    else:
        check = np.zeros(0, np.int64)
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
        for name, over in _holder_contacts(stock, tool, p0[k].tolist(), p1[k].tolist()):
            s = int(seg[k])
            key = (int(motion.block[s]), name)
            prev = contacts.get(key)
            if prev is None or over > prev.overlap_mm:
                contacts[key] = HolderContact(
                    block=int(motion.block[s]),
                    line=int(motion.line[s]),
                    part=name,
                    overlap_mm=over,
                    position_mm=(float(p1[k, 0]), float(p1[k, 1]), float(p1[k, 2])),
                )
    # float with weights (numpy's stubs say int); no copy
    per_seg = np.bincount(seg, weights=removed, minlength=len(motion)).astype(
        np.float64, copy=False
    )
    rapid_cut = np.nonzero((motion.kind == RAPID) & (per_seg > 1e-9))[0]
    ordered = tuple(sorted(contacts.values(), key=lambda c: (c.block, c.part)))
    return Simulation(motion, seg, p0, p1, removed, per_seg, depth, ordered, rapid_cut, arcs)


# ---------------------------------------------------------------------------------- plans


#: T number -> (tool name, end mill) of every tool a program uses (0: the program has no M6)
ToolMap = dict[int, tuple[str, EndMill]]


def parse_tool_spec(text: str) -> str | dict[str, str]:
    """``NAME`` or ``T1=NAME,T2=NAME`` (the ``--tool`` of a program that changes tools)."""
    if "=" not in text:
        return text
    out = {}
    for item in text.split(","):
        key, _, name = item.partition("=")
        out[key.strip().upper()] = name.strip()
    return out


def bind_tools(
    motion: Motion, spec: str | Mapping[str, str], file: str = "<program>", what: str = "--tool"
) -> ToolMap:
    """The end mill of each T number the program loads (M6), from one tool name (a program that
    does not change tools) or a map ``{"T1": name, ...}``; refuse, naming the block, a tool change
    under one name or a T number the map lacks. Segments before the first M6 are cut with the
    first tool loaded."""
    used = list(dict.fromkeys(int(t) for t in motion.tool if t != 0))

    def block(t: int) -> str:
        i = int(np.argmax(motion.tool == t))
        return f"{file}:{int(motion.line[i])}: block {int(motion.block[i])}"

    if isinstance(spec, str):
        if len(used) > 1:
            a, b = used[:2]
            hint = (f"--tool T{a}=NAME,T{b}=NAME" if what.startswith("--")
                    else f'tools = {{ T{a} = "NAME", T{b} = "NAME" }}')  # fmt: skip
            raise PlanningError(
                f"{block(b)}: the program changes from T{a} to T{b} (M6), but {what} = {spec!r} "
                f"is one end mill: map each tool ({hint})"
            )
        return {used[0] if used else 0: (spec, end_mill(spec, what))}
    numbers = {}
    for key, name in spec.items():
        if not (key[:1] in "Tt" and key[1:].isdigit()) or not name:
            raise PlanningError(
                f"{file}: {what}: {key}={name!r}: expected T<number>=TOOL, e.g. T1=phi10-flat"
            )
        numbers[int(key[1:])] = name
    if not used:
        if len(numbers) != 1:
            raise PlanningError(f"{file}: the program loads no tool (no T M6): {what} needs one")
        used = list(numbers)
    for t in used:
        if t not in numbers:
            raise PlanningError(
                f"{block(t)}: T{t} (M6) is not in {what} ({', '.join(f'T{n}' for n in numbers)}):"
                f" map it to a tool, e.g. T{t}=NAME"
            )
    return {t: (numbers[t], end_mill(numbers[t], f"{what} T{t}")) for t in used}


def end_mill(name: str | None, what: str = "--tool") -> EndMill:
    """The end mill ``name`` of the tool catalogues (the Z-map models end mills only)."""
    from analysis.config import load_tools

    if not name:
        known = ", ".join(sorted(k for k, t in load_tools().items() if ENDMILL.describes(t)))
        raise PlanningError(f"{what} is required (an end mill of the tool catalogue): {known}")
    tool = get_tool(name)
    if not ENDMILL.describes(tool):
        raise PlanningError(f"{what} = {name!r} is a {tool.kind}: the Z-map models end mills only")
    return tool


@dataclass(frozen=True)
class Operation:
    """One program of a plan: its motion, its tools (with holders) and optional feed rule path."""

    name: str
    motion: Motion
    tools: ToolMap
    file: str = "<program>"
    rule_path: str | None = None

    @property
    def tool(self) -> EndMill:
        """The first tool the program loads."""
        return next(iter(self.tools.values()))[1]

    @property
    def tool_name(self) -> str:
        if len(self.tools) == 1:
            return next(iter(self.tools.values()))[0]
        return ",".join(f"T{t}={n}" for t, (n, _) in self.tools.items())

    def runs(self) -> list[tuple[int, int, int]]:
        """(first segment, end segment, T number) of each consecutive run of one tool; segments
        before the first M6 go with the first tool."""
        first = next(iter(self.tools))
        t = np.where(self.motion.tool == 0, first, self.motion.tool)
        if len(self.tools) == 1:
            t[:] = first  # one tool named: it cuts everything (bind_tools refused a change)
        cut = np.flatnonzero(np.diff(t)) + 1
        bounds = [0, *cut.tolist(), len(t)]
        return [(a, b, int(t[a])) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


@dataclass(frozen=True)
class OperationResult:
    operation: Operation
    simulation: Simulation
    time_s: float
    removed_mm3: float
    stock_volume_after_mm3: float
    #: per tool run: (T number, tool name, segments, removed mm^3, time s)
    tool_runs: tuple[tuple[int, str, int, float, float], ...] = ()


@dataclass
class OperationPlan:
    """Ordered programs machined on one stock (seed 001's operation plan).

    ``run`` lowers ``stock`` in place; keep ``stock.copy()`` if the start is needed again.
    """

    stock: ZMap
    operations: list[Operation]
    machine: MachineConfig | None = None

    def check(self) -> None:
        """Refuse the whole plan before anything is cut if one program cannot run."""
        for op in self.operations:
            widest = max((m for _, m in op.tools.values()), key=lambda m: m.diameter_mm)
            check_motion(op.motion, self.machine, self.stock, Cutter.from_tool(widest), op.file)

    def run(
        self,
        piece_mm: float = math.inf,
        check_holder: bool = True,
        progress: Callable[[str, int, int], None] | None = None,
    ) -> list[OperationResult]:
        self.check()
        out = []
        for op in self.operations:
            cb = None if progress is None else (lambda d, t, n=op.name: progress(n, d, t))
            time_s = segment_time_s(op.motion, self.machine)
            parts, runs = [], []
            for lo, hi, t in op.runs():  # each tool cuts its own blocks (seed 001 2.1)
                name, tool = op.tools[t]
                sim = simulate_motion(
                    self.stock, tool, op.motion[lo:hi], piece_mm=piece_mm,
                    check_holder=check_holder, progress=cb,
                )  # fmt: skip
                parts.append((lo, sim))
                runs.append((t, name, hi - lo, sim.removed_total_mm3, float(time_s[lo:hi].sum())))
            sim = _join(op.motion, parts)
            out.append(
                OperationResult(
                    operation=op,
                    simulation=sim,
                    time_s=float(time_s.sum()),
                    removed_mm3=sim.removed_total_mm3,
                    stock_volume_after_mm3=self.stock.volume_mm3(),
                    tool_runs=tuple(runs),
                )
            )
        return out


def _join(motion: Motion, parts: list[tuple[int, Simulation]]) -> Simulation:
    """One simulation of ``motion`` from those of its consecutive slices (first segment, sim)."""
    if len(parts) == 1:
        return parts[0][1]

    def cat(name: str, shift: int = 0) -> NDArray[Any]:  # each field's own dtype
        return np.concatenate([getattr(s, name) + (lo if shift else 0) for lo, s in parts])

    return Simulation(
        motion, cat("piece_segment", 1), cat("piece_start_mm"), cat("piece_end_mm"),
        cat("piece_removed_mm3"), cat("removed_mm3"), cat("piece_depth_mm"),
        tuple(c for _, s in parts for c in s.contacts), cat("rapid_cut_segments", 1),
        cat("piece_arcs") if all(s.piece_arcs is not None for _, s in parts) else None,
    )  # fmt: skip


def summary(result: OperationResult) -> JsonObject:
    """Plain-data summary of one operation's virtual machining (for JSON and tables)."""
    sim = result.simulation
    m = sim.motion
    length = segment_length_mm(m)
    return {
        "operation": result.operation.name,
        "file": result.operation.file,
        "tool": result.operation.tool_name,
        "segments": len(m),
        "feed_path_mm": float(length[m.is_feed].sum()),
        "cutting_path_mm": float(length[m.is_feed & (sim.removed_mm3 > 1e-9)].sum()),
        "removed_mm3": result.removed_mm3,
        "time_s": result.time_s,
        "stock_volume_after_mm3": result.stock_volume_after_mm3,
        "holder_contacts": [
            {"block": c.block, "line": c.line, "part": c.part, "overlap_mm": c.overlap_mm}
            for c in sim.contacts
        ],
        "rapid_cut_blocks": [int(m.block[i]) for i in sim.rapid_cut_segments],
        "tools": [
            {"T": t, "tool": name, "segments": n, "removed_mm3": v, "time_s": ts}
            for t, name, n, v, ts in result.tool_runs
        ],
    }


# ---------------------------------------------------------------------------------- files


class _OperationModel(Model):
    name: str = Field(min_length=1)
    program: str = Field(min_length=1, description="NC file, relative to the plan file")
    tool: str | None = Field(
        None, min_length=1, description="tool name in the tool catalogue: a one-tool program"
    )
    tools: dict[str, str] | None = Field(
        None, description="T number -> tool name, e.g. { T1 = \"phi10-flat\" }, for a program "
        "that changes tools (M6)"
    )  # fmt: skip

    @model_validator(mode="after")
    def _one_of(self) -> _OperationModel:
        if (self.tool is None) == (self.tools is None):
            raise ValueError("give tool = NAME (one tool) or tools = { T1 = NAME, ... }")
        return self

    rule: str | None = Field(None, description="feed rule file or rule-base name")


class _PlanHeader(Model):
    machine: str | None = None
    description: str = ""


class _PlanModel(Model):
    plan: _PlanHeader = _PlanHeader()
    stock: _StockModel
    operations: tuple[_OperationModel, ...] = Field(min_length=1)


def load_plan(
    path: str | Path, spacing_mm: float | None = None, strict: bool = True
) -> tuple[OperationPlan, list[str | None]]:
    """An operation plan from its TOML file; returns the plan and each operation's rule spec.

    Every program is read and interpreted now, so a bad program or tool is reported before
    anything is cut.
    """
    from planning.nc import interpret_file

    p = Path(path)
    data, raw = read_toml(p)
    model = validate(_PlanModel, data, str(p), raw)
    machine = load_machine(model.plan.machine) if model.plan.machine else None
    stock = _stock_from_model(model.stock, str(p), p.parent, spacing_mm)
    ops = []
    for i, o in enumerate(model.operations):
        prog = Path(o.program) if Path(o.program).is_absolute() else p.parent / o.program
        motion = interpret_file(
            prog, machine, strict=strict, cutter_comp="refuse", probing="refuse"
        )
        what = f"{p}: operations[{i}].{'tool' if o.tools is None else 'tools'}"
        # arg-type: _OperationModel's validator guarantees one of tool and tools is set
        tools = bind_tools(motion, o.tools or o.tool, str(prog), what)  # type: ignore[arg-type]
        ops.append(Operation(o.name, motion, tools, str(prog), o.rule))
    return OperationPlan(stock, ops, machine), [o.rule for o in model.operations]


__all__ = [
    "HolderContact",
    "LINE",
    "Operation",
    "OperationPlan",
    "OperationResult",
    "Simulation",
    "ToolMap",
    "bind_tools",
    "check_motion",
    "end_mill",
    "default_stock",
    "load_plan",
    "load_stock",
    "parse_tool_spec",
    "plunge_mask",
    "simulate_motion",
    "summary",
]
