"""Inverse kinematics of 5-axis machines, singularity handling, G93 feeds, CL data CSV, NC text.

Machines (``MachineConfig.five_axis.kind``):

* ``table-table-AC``: the spindle is fixed along machine +Z; the table tilts about machine X (A)
  and carries a rotary table about its own Z (C, mounted on the A cradle). A workpiece point p
  goes to ``M(p) = Rx(A) Rz(C) (p - pivot) + pivot`` (pivot = ``pivot_mm``, where the A and C
  axes meet). The tool axis u (workpiece frame) is brought to +Z: ``Rx(A) Rz(C) u = (0, 0, 1)``.
  X, Y, Z are the tool tip in machine coordinates (tool length compensated by the control, G43).
* ``head-table-AC``: the head tilts the spindle about X (A), the table turns about Z (C). The
  spindle direction is ``t(A) = Rx(A) (0, 0, 1) = (0, -sin A, cos A)``, and
  ``Rz(C) u = t(A)``. X, Y, Z are the head pivot, ``tip + (gauge length + head_pivot_length_mm)
  t(A)``, with the tip rotated by C about the pivot.
* ``head-head-BC``: the part stands still; the head turns about Z (C) and tilts about its own Y
  (B): ``u = t(B, C) = Rz(C) Ry(B) (0, 0, 1) = (sin B cos C, sin B sin C, cos B)``, and X, Y, Z
  are the head pivot ``tip + (gauge length + head_pivot_length_mm) u``.

A (B) and C are the angles by which the machine turns the workpiece (table) or the spindle
(head), right-handed, in degrees. Of the two solutions (A, C) and (-A, C + 180 deg) the one
inside the tilt limits is taken (preferring the one nearer the previous point), and C is unwrapped
to the turn nearest the previous C inside its limits; with the axis along +Z, C keeps its previous
value (the singular pose). Near that pose C swings fast for a small change of the axis;
:func:`hold_c` plans around it by holding C (interpolated across the cone) and tilting only.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.config import FiveAxis, MachineConfig, RotaryAxis
from planning.errors import PlanningError
from planning.nc import NumberStyle, Program
from planning.nc.program import BlockValue
from planning.orient._branch import solution_branches
from planning.orient.planner import OrientResult

KINDS = ("table-table-AC", "head-table-AC", "head-head-BC")
Z_HAT = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class AxisMoves:
    """Machine axis positions per CL point: x, y, z (m,) mm; a_deg (m,) deg the tilt axis (A, or
    B on a BC machine: see ``tilt``), c_deg (m,) deg."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    a_deg: np.ndarray
    c_deg: np.ndarray
    kind: str

    @property
    def tilt(self) -> str:
        """The tilt axis' letter: ``A``, or ``B`` on a BC machine."""
        return "B" if self.kind.endswith("BC") else "A"

    def as_array(self) -> np.ndarray:
        """(m, 5) X, Y, Z, A (or B), C."""
        return np.stack([self.x, self.y, self.z, self.a_deg, self.c_deg], 1)


def _rx(a: float | np.ndarray) -> np.ndarray:
    """Rotation(s) about +X by ``a`` rad: (3, 3), or (m, 3, 3) for an array of angles."""
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.moveaxis(np.array([[o, z, z], [z, c, -s], [z, s, c]]), (0, 1), (-2, -1))


def _ry(a: float | np.ndarray) -> np.ndarray:
    """Rotation(s) about +Y by ``a`` rad: (3, 3), or (m, 3, 3) for an array of angles."""
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.moveaxis(np.array([[c, z, s], [z, o, z], [-s, z, c]]), (0, 1), (-2, -1))


def _rz(a: float | np.ndarray) -> np.ndarray:
    """Rotation(s) about +Z by ``a`` rad: (3, 3), or (m, 3, 3) for an array of angles."""
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.moveaxis(np.array([[c, -s, z], [s, c, z], [z, z, o]]), (0, 1), (-2, -1))


def spindle_axis(kind: str, tilt_deg: float | np.ndarray, c_deg: float | np.ndarray) -> np.ndarray:
    """Unit tool axis in the workpiece frame, shape (..., 3), for tilt (A or B) and C in deg."""
    t, c = np.broadcast_arrays(np.radians(tilt_deg), np.radians(c_deg))
    if kind == "table-table-AC":  # Rz(-C) Rx(-A) z
        u = np.stack([np.sin(t) * np.sin(c), np.sin(t) * np.cos(c), np.cos(t)], -1)
    elif kind == "head-table-AC":  # Rz(-C) Rx(A) z
        u = np.stack([-np.sin(t) * np.sin(c), -np.sin(t) * np.cos(c), np.cos(t)], -1)
    else:  # head-head-BC: Rz(C) Ry(B) z
        u = np.stack([np.sin(t) * np.cos(c), np.sin(t) * np.sin(c), np.cos(t)], -1)
    return u


def forward(kind: str, machine: MachineConfig, moves: AxisMoves,
            gauge_length_mm: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Tool tip (m, 3) and unit axis (m, 3) in the workpiece frame from machine positions."""
    fa = _five(machine)
    pivot = np.asarray(fa.pivot_mm, float)
    P = np.stack([moves.x, moves.y, moves.z], 1).astype(float)
    A, C = np.radians(moves.a_deg), np.radians(moves.c_deg)
    if kind == "table-table-AC":
        Rt = np.swapaxes(_rx(A) @ _rz(C), -1, -2)  # workpiece <- machine
        tips = np.einsum("mij,mj->mi", Rt, P - pivot) + pivot
        return tips, Rt @ Z_HAT
    reach = gauge_length_mm + fa.head_pivot_length_mm
    if kind == "head-head-BC":
        t = (_rz(C) @ _ry(A)) @ Z_HAT
        return P - reach * t, t
    t = _rx(A) @ Z_HAT  # (m, 3) spindle direction
    Rt = np.swapaxes(_rz(C), -1, -2)
    tips = np.einsum("mij,mj->mi", Rt, P - reach * t - pivot) + pivot
    return tips, np.einsum("mij,mj->mi", Rt, t)


def _five(machine: MachineConfig) -> FiveAxis:
    if machine.five_axis is None:
        raise PlanningError(
            f"machine {machine.name!r} has no [five_axis] section: cannot post 5-axis motion"
        )
    fa = machine.five_axis
    if fa.kind not in KINDS:
        raise PlanningError(
            f"machine {machine.name!r}: five_axis.kind = {fa.kind!r} is not supported "
            f"(supported: {', '.join(KINDS)})"
        )
    return fa


def five_axis_kind(machine: MachineConfig) -> str:
    return _five(machine).kind  # one of KINDS; PlanningError without a [five_axis]


def tilt_limits(machine: MachineConfig) -> RotaryAxis:
    """The tilt axis' RotaryAxis (A, or B on a BC machine)."""
    fa = _five(machine)
    return fa.b if fa.kind.endswith("BC") else fa.a


def inverse(
    machine: MachineConfig,
    tip_mm: np.ndarray,
    axis: np.ndarray,
    gauge_length_mm: float = 0.0,
    check_limits: bool = True,
    start_c_deg: float = 0.0,
    line: np.ndarray | None = None,
) -> AxisMoves:
    """Machine X, Y, Z, tilt, C for tool tips (m, 3) mm and unit axes (m, 3) in the workpiece
    frame, each solution chosen nearest the previous one (the first nearest tilt 0 and
    ``start_c_deg``). With ``line`` (index of each point's path), C starts every path at its
    turn nearest ``start_c_deg`` (the retract between paths unwinds it).

    Raises PlanningError naming the first point whose axis has no solution inside the tilt
    limits or whose C, X, Y or Z leaves its travel (when ``check_limits``).
    """
    fa = _five(machine)
    kind = fa.kind
    tip_mm = np.asarray(tip_mm, float).reshape(-1, 3)
    axis = _unit_axes(axis)
    # The primary solution (tilt >= 0) for all points at once; the other is (-tilt, C + 180).
    rho = np.hypot(axis[:, 0], axis[:, 1])
    t0 = np.degrees(np.arctan2(rho, axis[:, 2]))  # = arccos(uz), without its loss near 0
    c0 = np.degrees(np.arctan2(*_c_plane_components(kind, axis)))
    A, C = _rotary_angles(machine, axis, rho, t0, c0, start_c_deg, line)
    P = _axis_positions(fa, tip_mm, A, C, gauge_length_mm)
    if check_limits:
        _check_linear_travel(machine, P)
    return AxisMoves(P[:, 0], P[:, 1], P[:, 2], A, C, kind)


def _unit_axes(axis: np.ndarray) -> np.ndarray:
    """The tool axes as (m, 3); an error naming the first that is not a unit vector."""
    axis = np.asarray(axis, float).reshape(-1, 3)
    norms = np.linalg.norm(axis, axis=1)
    if np.any(np.abs(norms - 1) > 1e-6):
        i = int(np.argmax(np.abs(norms - 1)))
        raise PlanningError(
            f"CL point {i}: tool axis length {norms[i]:.6g}, expected a unit vector"
        )
    return axis


def _rotary_angles(
    machine: MachineConfig, axis: np.ndarray, rho: np.ndarray, t0: np.ndarray, c0: np.ndarray,
    start_c_deg: float, line: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Tilt and C (m,) deg per point from the primary solution (``t0``, ``c0``): the branch
    inside the tilt limits (both inside: :func:`solution_branches`), C on its turn nearest the
    previous C inside the C limits."""
    fa = _five(machine)
    lim = tilt_limits(machine)
    a_lo, a_hi = lim.min_deg, lim.max_deg
    letter = "B" if fa.kind.endswith("BC") else "A"
    m = len(axis)
    A, C = np.zeros(m), np.zeros(m)
    branch = solution_branches(t0, c0, rho, a_lo, a_hi, start_c_deg)
    prev_a, prev_c = 0.0, float(start_c_deg)
    for i in range(m):
        if line is not None and i and line[i] != line[i - 1]:
            prev_c = float(start_c_deg)
        c_i = prev_c if rho[i] < 1e-12 else c0[i]  # axis along the C axis: C is free, keep it
        sols = [(t0[i], c_i), (-t0[i], c_i + (0.0 if rho[i] < 1e-12 else 180.0))]
        inside = [s for s in sols if a_lo - 1e-9 <= s[0] <= a_hi + 1e-9]
        if len(inside) == 2:
            inside = [sols[branch[i]]]
        if not inside:
            raise PlanningError(
                f"CL point {i}: tool axis {np.round(axis[i], 5).tolist()} needs {letter} = "
                f"{sols[0][0]:.3f} or {sols[1][0]:.3f} deg, outside the {letter} limits "
                f"[{a_lo:g}, {a_hi:g}] deg of machine {machine.name!r}"
            )
        A[i], C[i] = _nearest_turn(machine, i, inside, prev_a, prev_c)
        prev_a, prev_c = A[i], C[i]
    return A, C


def _nearest_turn(
    machine: MachineConfig, i: int, inside: list[tuple[float, float]], prev_a: float,
    prev_c: float,
) -> tuple[float, float]:  # fmt: skip
    """Of the solutions ``inside`` the tilt limits, the (tilt, C) with C on the turn inside
    the C limits that moves least from (``prev_a``, ``prev_c``); an error when none is."""
    c_lo, c_hi = _five(machine).c.min_deg, _five(machine).c.max_deg
    best = None
    for a, c in inside:
        cands = c + 360.0 * np.arange(-3, 4)
        cands = cands[(cands >= c_lo - 1e-9) & (cands <= c_hi + 1e-9)]
        if cands.size == 0:
            continue
        cc = float(cands[np.argmin(np.abs(cands - prev_c))])
        cost = abs(a - prev_a) + abs(cc - prev_c)
        if best is None or cost < best[2]:
            best = (a, cc, cost)
    if best is None:
        raise PlanningError(
            f"CL point {i}: C = {inside[0][1]:.3f} deg (mod 360) is outside the C limits "
            f"[{c_lo:g}, {c_hi:g}] deg of machine {machine.name!r}"
        )
    return best[0], best[1]


def _axis_positions(
    fa: FiveAxis, tip_mm: np.ndarray, A: np.ndarray, C: np.ndarray, gauge_length_mm: float
) -> np.ndarray:
    """Machine X, Y, Z (m, 3) mm for the tips at tilt ``A`` and ``C`` (deg), per kinematics."""
    Ar, Cr = np.radians(A), np.radians(C)
    pivot = np.asarray(fa.pivot_mm, float)
    reach = gauge_length_mm + fa.head_pivot_length_mm
    if fa.kind == "table-table-AC":
        P = np.einsum("mij,mj->mi", _rx(Ar) @ _rz(Cr), tip_mm - pivot) + pivot
    elif fa.kind == "head-table-AC":
        P = np.einsum("mij,mj->mi", _rz(Cr), tip_mm - pivot) + pivot + reach * (_rx(Ar) @ Z_HAT)
    else:
        P = tip_mm + reach * ((_rz(Cr) @ _ry(Ar)) @ Z_HAT)
    return np.asarray(P)


def _check_linear_travel(machine: MachineConfig, P: np.ndarray) -> None:
    """An error naming the first point whose X, Y or Z leaves the machine's travel."""
    for k, label in enumerate("XYZ"):
        vals, trav = P[:, k], getattr(machine, label.lower())
        bad = np.flatnonzero((vals < trav.min_mm) | (vals > trav.max_mm))
        if bad.size:
            i = int(bad[0])
            raise PlanningError(
                f"CL point {i}: {label} = {vals[i]:.3f} mm is outside the travel "
                f"[{trav.min_mm:g}, {trav.max_mm:g}] mm of machine {machine.name!r} "
                f"({bad.size} points affected)"
            )


def hold_c(kind: str, axis: np.ndarray, line: np.ndarray, cone_deg: float) -> np.ndarray:
    """Axes (m, 3) planned around the singular pose (axis along the C axis, +Z).

    Inside the cone of ``cone_deg`` about +Z, C is undefined and swings by up to 180 deg for a
    tiny change of the axis. Each run of consecutive points of a line inside the cone gets C
    interpolated from the points just before and after it (the shorter way round; held when the
    run starts or ends the line; modulo 180 deg, as the axis may pass through +Z with the tilt
    changing sign), and its axis is moved onto the plane that C and +Z span (the
    nearest axis the machine reaches by tilting alone): each axis moves by less than
    ``cone_deg``. Unit axes outside the cone are returned as they are.
    """
    axis = np.asarray(axis, float).copy()
    inside = axis[:, 2] > np.cos(np.radians(cone_deg))
    if not inside.any():
        return axis
    c_raw = np.degrees(np.arctan2(*_c_plane_components(kind, axis)))
    m = len(axis)
    i = 0
    while i < m:
        if not inside[i]:
            i += 1
            continue
        j = i
        while j + 1 < m and inside[j + 1] and line[j + 1] == line[i]:
            j += 1
        before = c_raw[i - 1] if i > 0 and line[i - 1] == line[i] else None
        after = c_raw[j + 1] if j + 1 < m and line[j + 1] == line[i] else None
        lo = before if before is not None else (after if after is not None else 0.0)
        hi = after if after is not None else lo
        # Mod 180: passing (near) through the C axis, the tilt changes sign at a steady C.
        d = (hi - lo + 90.0) % 180.0 - 90.0
        k = np.arange(1, j - i + 2) / (j - i + 2)
        c_h = lo + d * k
        e = spindle_axis(kind, 90.0, c_h)  # the horizontal direction a positive tilt leans to
        s = (axis[i : j + 1] * e).sum(1)
        held = axis[i : j + 1, 2, None] * Z_HAT + s[:, None] * e
        axis[i : j + 1] = held / np.linalg.norm(held, axis=1)[:, None]
        i = j + 1
    return axis


def _c_plane_components(kind: str, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sin C, cos C) up to a positive factor for the primary (tilt >= 0) solution."""
    if kind == "table-table-AC":
        return axis[:, 0], axis[:, 1]
    if kind == "head-table-AC":
        return -axis[:, 0], -axis[:, 1]
    return axis[:, 1], axis[:, 0]


def inverse_time_feeds(
    machine: MachineConfig,
    moves: AxisMoves,
    tips_mm: np.ndarray,
    feed_mm_min: float,
) -> tuple[np.ndarray, np.ndarray]:
    """G93 F (1/min) per block i (the move from CL point i - 1 to i; entry 0 is NaN) and which
    limit set its time: 0 the tip at ``feed_mm_min``, 1 the machine's feed_max_mm_min over the
    combined travel (mm and deg together, as the control and ``nc check`` measure it), 2 the
    tilt axis' and 3 the C axis' speed (their ``rapid_deg_min``).

    Each block takes the longest of those times, so no axis exceeds its speed; F is rounded down
    at 4 decimals (the NC text's), which only lengthens the move.
    """
    fa = _five(machine)
    lim = tilt_limits(machine)
    P = moves.as_array()
    d = np.abs(np.diff(P, axis=0))
    chord = np.linalg.norm(np.diff(np.asarray(tips_mm, float), axis=0), axis=1)
    times = np.stack(
        [
            np.maximum(chord, 1e-3) / feed_mm_min,  # a repeated point: 1 um is the shortest
            np.linalg.norm(d, axis=1) / machine.feed_max_mm_min,
            d[:, 3] / lim.rapid_deg_min,
            d[:, 4] / fa.c.rapid_deg_min,
        ],
        1,
    )
    t = times.max(1) * (1.0 + 1e-9)
    f = np.floor(1e4 / t) / 1e4
    f = np.where(f > 0, f, 1e-4)
    return np.concatenate([[np.nan], f]), np.concatenate([[-1], times.argmax(1)])


def axis_speeds(
    machine: MachineConfig, moves: AxisMoves, inverse_f: np.ndarray, line: np.ndarray
) -> dict[str, float]:
    """Largest speeds of the posted G93 blocks (inverse_f per block as from
    :func:`inverse_time_feeds`, new lines' first points skipped): combined feed mm/min, tilt and
    C deg/min, with the block indices, and the machine's limits."""
    P = moves.as_array()
    d = np.abs(np.diff(P, axis=0))
    f = np.asarray(inverse_f, float)[1:]
    keep = line[1:] == line[:-1]
    feed = np.where(keep, np.linalg.norm(d, axis=1) * f, 0.0)
    tilt = np.where(keep, d[:, 3] * f, 0.0)
    c = np.where(keep, d[:, 4] * f, 0.0)
    fa = _five(machine)
    return {
        "feed_max_mm_min": float(feed.max(initial=0.0)),
        "feed_max_block": int(np.argmax(feed)) + 1 if feed.size else -1,
        "feed_limit_mm_min": machine.feed_max_mm_min,
        "tilt_max_deg_min": float(tilt.max(initial=0.0)),
        "tilt_limit_deg_min": tilt_limits(machine).rapid_deg_min,
        "c_max_deg_min": float(c.max(initial=0.0)),
        "c_max_block": int(np.argmax(c)) + 1 if c.size else -1,
        "c_limit_deg_min": fa.c.rapid_deg_min,
        "max_c_step_deg": float(np.where(keep, d[:, 4], 0.0).max(initial=0.0)),
        "max_tilt_step_deg": float(np.where(keep, d[:, 3], 0.0).max(initial=0.0)),
    }


def check_forward(
    machine: MachineConfig,
    moves: AxisMoves,
    tips_mm: np.ndarray,
    axis: np.ndarray,
    gauge_length_mm: float,
    tol_mm: float = 1e-6,
    tol_rad: float = 1e-6,
) -> tuple[float, float]:
    """Forward kinematics of every posted point back to the planned pose: the largest tip error
    (mm) and axis error (rad); raises PlanningError naming the first point off by more than
    ``tol_mm`` or ``tol_rad``."""
    tips, u = forward(moves.kind, machine, moves, gauge_length_mm)
    e_tip = np.linalg.norm(tips - tips_mm, axis=1)
    e_ax = 2 * np.arcsin(np.clip(np.linalg.norm(u - axis, axis=1) / 2, 0, 1))
    bad = np.flatnonzero((e_tip > tol_mm) | (e_ax > tol_rad))
    if bad.size:
        i = int(bad[0])
        raise PlanningError(
            f"CL point {i}: forward kinematics of the posted axes is off the planned pose by "
            f"{e_tip[i]:.3g} mm, {e_ax[i]:.3g} rad (tolerance {tol_mm:g} mm, {tol_rad:g} rad)"
        )
    return float(e_tip.max(initial=0.0)), float(e_ax.max(initial=0.0))


def write_cl_csv(path: str | Path, result: OrientResult) -> None:
    """CL data CSV: one row per feasible CC point: tip, centre, axis, angles (mm, deg)."""
    import pandas as pd

    ok = result.feasible
    cc = result.cc
    cols = {"index": np.flatnonzero(ok), "line": cc.line[ok], "u": cc.u[ok], "v": cc.v[ok]}
    for name, xyz in (("cc", cc.point), ("tip", result.tip_mm), ("centre", result.centre_mm)):
        cols |= {f"{name}_{a}_mm": xyz[ok, k] for k, a in enumerate("xyz")}
    cols |= {f"axis_{a}": result.axis[ok, k] for k, a in enumerate("ijk")}
    cols |= {
        "alpha_deg": result.alpha_deg[ok],
        "beta_deg": result.beta_deg[ok],
        "kappa_per_mm": cc.kappa_per_mm[ok],
        "K_per_mm": result.K_per_mm[ok],
        "clearance_mm": result.clearance_mm[ok],
    }
    df = pd.DataFrame(cols)
    df.to_csv(path, index=False, float_format="%.6f")


def nc_program(
    moves: AxisMoves,
    line: np.ndarray,
    feed_mm_min: float,
    spindle_rpm: float,
    tool_number: int = 1,
    safe_z_mm: float | None = None,
    title: str = "cutlab plan orient",
    tips_mm: np.ndarray | None = None,
    inverse_f: np.ndarray | None = None,
) -> str:
    """Fanuc-style G-code (planning.nc's block formatting, 4 decimals): G90 G21, G43, one
    G01 X Y Z A C per CL point.

    Each iso-parameter line starts with a rapid positioning of A and C, an approach and a plunge
    (G94, F in mm/min); lines are separated by a retract to ``safe_z_mm`` (default: 20 mm above
    the highest Z). With ``tips_mm`` ((m, 3), the tool tips in the workpiece frame), the cutting
    blocks run under inverse-time feed G93 with F = feed / tip chord (1/min), so the tip moves
    over the part at ``feed_mm_min`` whatever the rotary axes do; without it they run under G94,
    where the control applies F to millimetres and degrees together. ``inverse_f`` (per point,
    as from :func:`inverse_time_feeds`) gives the G93 F of each block instead of feed / chord.
    The tilt axis is written as A, or B on a BC machine.
    """
    P = moves.as_array()
    safe = float(np.max(P[:, 2]) + 20.0) if safe_z_mm is None else safe_z_mm
    title = " ".join(title.replace("(", "[").replace(")", "]").split()).upper()[:40]
    blocks: list[str | dict[str, BlockValue]] = [
        "%",
        f"O1000 ({title})",
        {"G": [90, 94, 21, 17]},
        {"T": tool_number, "M": "06"},
        {"S": spindle_rpm, "M": "03"},
        {"G": 43, "H": tool_number, "Z": safe},
    ]
    chord = None
    tl = moves.tilt
    if inverse_f is not None:
        chord = feed_mm_min / np.asarray(inverse_f, float)
    elif tips_mm is not None:
        chord = np.linalg.norm(np.diff(np.asarray(tips_mm, float), axis=0), axis=1)
        # A repeated CL point would ask for an infinite F: 1 um is the shortest chord timed.
        chord = np.concatenate([[np.nan], np.maximum(chord, 1e-3)])
    g93 = False
    for i, (x, y, z, a, c) in enumerate(P):
        if i == 0 or line[i] != line[i - 1]:  # a new iso-parameter line: position, then plunge
            if i:
                blocks.append({"G": "00", "Z": safe})
            blocks += [
                {"G": "00", tl: a, "C": c},
                {"G": "00", "X": x, "Y": y},
                {"G": ["01", 94] if g93 else "01", "Z": z, "F": feed_mm_min},
            ]
            g93 = False
        elif chord is not None:
            g: BlockValue = ["01", 93] if not g93 else "01"
            blocks.append({"G": g, "X": x, "Y": y, "Z": z, tl: a, "C": c,
                           "F": feed_mm_min / chord[i]})  # fmt: skip
            g93 = True
        else:
            blocks.append({"G": "01", "X": x, "Y": y, "Z": z, tl: a, "C": c})
    if g93:
        blocks.append({"G": 94})
    blocks += [{"G": "00", "Z": safe}, {"M": "05"}, {"M": 30}, "%"]
    return str(Program.from_blocks(blocks, style=NumberStyle(decimals=4)).text())
