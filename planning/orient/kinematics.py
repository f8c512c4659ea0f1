"""Inverse kinematics of AC 5-axis machines, axis-limit checks, CL data CSV and NC text.

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

A and C are the angles by which the machine turns the workpiece (table) or the spindle (head),
right-handed about +X and +Z, in degrees. Of the two solutions (A, C) and (-A, C + 180 deg) the
one inside the A limits is taken (preferring the one nearer the previous point), and C is unwrapped
to the turn nearest the previous C inside its limits; with the axis along +Z, C keeps its previous
value (the singular pose).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.config import MachineConfig
from planning.errors import PlanningError
from planning.nc import NumberStyle, Program


@dataclass(frozen=True)
class AxisMoves:
    """Machine axis positions per CL point: x, y, z (m,) mm; a_deg, c_deg (m,) deg."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    a_deg: np.ndarray
    c_deg: np.ndarray
    kind: str

    def as_array(self) -> np.ndarray:
        """(m, 5) X, Y, Z, A, C."""
        return np.stack([self.x, self.y, self.z, self.a_deg, self.c_deg], 1)


def _rx(a):
    """Rotation(s) about +X by ``a`` rad: (3, 3), or (m, 3, 3) for an array of angles."""
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.moveaxis(np.array([[o, z, z], [z, c, -s], [z, s, c]]), (0, 1), (-2, -1))


def _rz(a):
    """Rotation(s) about +Z by ``a`` rad: (3, 3), or (m, 3, 3) for an array of angles."""
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.moveaxis(np.array([[c, -s, z], [s, c, z], [z, z, o]]), (0, 1), (-2, -1))


def forward(kind: str, machine: MachineConfig, moves: AxisMoves, gauge_length_mm: float):
    """Tool tip (m, 3) and unit axis (m, 3) in the workpiece frame from machine positions."""
    fa = _five(machine)
    pivot = np.asarray(fa.pivot_mm, float)
    P = np.stack([moves.x, moves.y, moves.z], 1).astype(float)
    A, C = np.radians(moves.a_deg), np.radians(moves.c_deg)
    z_hat = np.array([0.0, 0.0, 1.0])
    if kind == "table-table-AC":
        Rt = np.swapaxes(_rx(A) @ _rz(C), -1, -2)  # workpiece <- machine
        tips = np.einsum("mij,mj->mi", Rt, P - pivot) + pivot
        return tips, Rt @ z_hat
    t = _rx(A) @ z_hat  # (m, 3) spindle direction
    tip_m = P - (gauge_length_mm + fa.head_pivot_length_mm) * t
    Rt = np.swapaxes(_rz(C), -1, -2)
    tips = np.einsum("mij,mj->mi", Rt, tip_m - pivot) + pivot
    return tips, np.einsum("mij,mj->mi", Rt, t)


def _five(machine: MachineConfig):
    if machine.five_axis is None:
        raise PlanningError(
            f"machine {machine.name!r} has no [five_axis] section: cannot post 5-axis motion"
        )
    return machine.five_axis


def inverse(
    machine: MachineConfig,
    tip_mm: np.ndarray,
    axis: np.ndarray,
    gauge_length_mm: float = 0.0,
    check_limits: bool = True,
) -> AxisMoves:
    """Machine X, Y, Z, A, C for tool tips (m, 3) mm and unit axes (m, 3) in the workpiece frame.

    Raises PlanningError naming the first point whose axis has no solution inside the A limits or
    whose C, X, Y or Z leaves its travel (when ``check_limits``).
    """
    fa = _five(machine)
    kind = fa.kind
    if kind not in ("table-table-AC", "head-table-AC"):
        raise PlanningError(
            f"machine {machine.name!r}: five_axis.kind = {kind!r} is not supported "
            "(supported: table-table-AC, head-table-AC)"
        )
    tip_mm = np.asarray(tip_mm, float).reshape(-1, 3)
    axis = np.asarray(axis, float).reshape(-1, 3)
    norms = np.linalg.norm(axis, axis=1)
    if np.any(np.abs(norms - 1) > 1e-6):
        i = int(np.argmax(np.abs(norms - 1)))
        raise PlanningError(
            f"CL point {i}: tool axis length {norms[i]:.6g}, expected a unit vector"
        )
    pivot = np.asarray(fa.pivot_mm, float)
    a_lo, a_hi = fa.a.min_deg, fa.a.max_deg
    c_lo, c_hi = fa.c.min_deg, fa.c.max_deg
    m = len(axis)
    A, C, P = np.zeros(m), np.zeros(m), np.zeros((m, 3))
    prev_a, prev_c = 0.0, 0.0
    for i, (ux, uy, uz) in enumerate(axis):
        rho = np.hypot(ux, uy)
        if kind == "table-table-AC":
            # Rz(C) u = (0, rho', uz) with rho' = +-rho, then Rx(A) takes it to +Z.
            sols = [(np.degrees(np.arctan2(rho, uz)), np.degrees(np.arctan2(ux, uy)))]
            sols.append((-sols[0][0], sols[0][1] + 180.0))
        else:
            # Rz(C) (ux, uy) = (0, -sin A); cos A = uz.
            a0 = np.degrees(np.arctan2(rho, uz))  # = arccos(uz), without its loss near 0
            sols = [(a0, np.degrees(np.arctan2(-ux, -uy))), (-a0, np.degrees(np.arctan2(ux, uy)))]
        if rho < 1e-12:  # axis along the C axis: C is free, keep it
            sols = [(s[0], prev_c) for s in sols]
        inside = [s for s in sols if a_lo - 1e-9 <= s[0] <= a_hi + 1e-9]
        if not inside:
            raise PlanningError(
                f"CL point {i}: tool axis {np.round(axis[i], 5).tolist()} needs A = "
                f"{sols[0][0]:.3f} or {sols[1][0]:.3f} deg, outside the A limits "
                f"[{a_lo:g}, {a_hi:g}] deg of machine {machine.name!r}"
            )
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
        A[i], C[i] = best[0], best[1]
        prev_a, prev_c = A[i], C[i]
        Ar, Cr = np.radians(A[i]), np.radians(C[i])
        if kind == "table-table-AC":
            P[i] = _rx(Ar) @ _rz(Cr) @ (tip_mm[i] - pivot) + pivot
        else:
            t = _rx(Ar) @ np.array([0.0, 0.0, 1.0])
            P[i] = (
                _rz(Cr) @ (tip_mm[i] - pivot)
                + pivot
                + (gauge_length_mm + fa.head_pivot_length_mm) * t
            )
    moves = AxisMoves(P[:, 0], P[:, 1], P[:, 2], A, C, kind)
    if check_limits:
        for label, vals, trav in (
            ("X", P[:, 0], machine.x),
            ("Y", P[:, 1], machine.y),
            ("Z", P[:, 2], machine.z),
        ):
            bad = np.flatnonzero((vals < trav.min_mm) | (vals > trav.max_mm))
            if bad.size:
                i = int(bad[0])
                raise PlanningError(
                    f"CL point {i}: {label} = {vals[i]:.3f} mm is outside the travel "
                    f"[{trav.min_mm:g}, {trav.max_mm:g}] mm of machine {machine.name!r} "
                    f"({bad.size} points affected)"
                )
    return moves


def write_cl_csv(path: str | Path, result) -> None:
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
) -> str:
    """Fanuc-style G-code (planning.nc's block formatting, 4 decimals): G90 G21, G43, one
    G01 X Y Z A C per CL point.

    Each iso-parameter line starts with a rapid positioning of A and C, an approach and a plunge
    (G94, F in mm/min); lines are separated by a retract to ``safe_z_mm`` (default: 20 mm above
    the highest Z). With ``tips_mm`` ((m, 3), the tool tips in the workpiece frame), the cutting
    blocks run under inverse-time feed G93 with F = feed / tip chord (1/min), so the tip moves
    over the part at ``feed_mm_min`` whatever the rotary axes do; without it they run under G94,
    where the control applies F to millimetres and degrees together.
    """
    P = moves.as_array()
    safe = float(np.max(P[:, 2]) + 20.0) if safe_z_mm is None else safe_z_mm
    title = " ".join(title.replace("(", "[").replace(")", "]").split()).upper()[:40]
    blocks: list[str | dict] = [
        "%",
        f"O1000 ({title})",
        {"G": [90, 94, 21, 17]},
        {"T": tool_number, "M": "06"},
        {"S": spindle_rpm, "M": "03"},
        {"G": 43, "H": tool_number, "Z": safe},
    ]
    chord = None
    if tips_mm is not None:
        chord = np.linalg.norm(np.diff(np.asarray(tips_mm, float), axis=0), axis=1)
        # A repeated CL point would ask for an infinite F: 1 um is the shortest chord timed.
        chord = np.concatenate([[np.nan], np.maximum(chord, 1e-3)])
    g93 = False
    for i, (x, y, z, a, c) in enumerate(P):
        if i == 0 or line[i] != line[i - 1]:  # a new iso-parameter line: position, then plunge
            if i:
                blocks.append({"G": "00", "Z": safe})
            blocks += [
                {"G": "00", "A": a, "C": c},
                {"G": "00", "X": x, "Y": y},
                {"G": ["01", 94] if g93 else "01", "Z": z, "F": feed_mm_min},
            ]
            g93 = False
        elif chord is not None:
            g = ["01", 93] if not g93 else "01"
            blocks.append({"G": g, "X": x, "Y": y, "Z": z, "A": a, "C": c,
                           "F": feed_mm_min / chord[i]})  # fmt: skip
            g93 = True
        else:
            blocks.append({"G": "01", "X": x, "Y": y, "Z": z, "A": a, "C": c})
    if g93:
        blocks.append({"G": 94})
    blocks += [{"G": "00", "Z": safe}, {"M": "05"}, {"M": 30}, "%"]
    return Program.from_blocks(blocks, style=NumberStyle(decimals=4)).text()
