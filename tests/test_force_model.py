"""planning.feed.ForceModel (the engagement and forces of plan feed and plan check) against
direct evaluations of analysis.forces.endmill_forces: a piece's force is built from tables of
arcs that start at 0 (an arc (e, x) being (0, x) less (0, e)); here each piece's force is
evaluated directly for its own arcs, at the table's depth and 2 deg grid.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.config import get_material, get_tool
from analysis.forces import EndMillCut, endmill_forces
from planning.feed import ForceModel
from planning.nc import Program, interpret
from planning.stock import ARC_STEP_RAD, ZMap, simulate_motion

TOOL = get_tool("phi10-flat")
COEF = get_material("al6061-t6").endmill


def _model(text: str, stock: ZMap) -> ForceModel:
    motion = interpret(Program.parse(text, "t.nc"))
    sim = simulate_motion(stock, TOOL, motion, piece_mm=2.5, check_holder=False, track_depth=True)
    rpm = np.abs(motion.spindle_rpm[sim.piece_segment]).astype(float)
    return ForceModel(TOOL, COEF, sim, rpm)


def _walled() -> ZMap:
    """A 6 mm slot cut before along X, 3 mm deep, and 1 mm taken off the right of +X (y < -3):
    a cutter along the slot at Z-2.5 meets both walls, at two depths."""
    z = ZMap.box(-30, 30, -20, 20, -10, 0, 0.1)
    y = z.y0_mm + (np.arange(z.shape[0]) + 0.5) * 0.1
    z.heights_mm[np.abs(y) < 3.0] = -3.0
    z.heights_mm[y < -3.0] = -1.0
    return z


def _direct(model: ForceModel, k: int, fz: float) -> np.ndarray:
    """The force over a tooth period of piece k, summed over its arcs, evaluated directly."""
    phi = np.linspace(0.0, 2 * np.pi / TOOL.flutes, 36, endpoint=False)
    total = np.zeros((36, 3))
    for entry, exit_, depth in model.arcs[k]:
        if not math.isfinite(entry):
            continue
        step = math.log1p(0.02)
        d = min(math.exp(math.ceil(math.log(max(depth, 1e-3)) / step - 1e-9) * step),
                TOOL.flute_length_mm)  # fmt: skip
        e = math.floor(entry / ARC_STEP_RAD + 1e-3) * ARC_STEP_RAD
        x = math.ceil(exit_ / ARC_STEP_RAD - 1e-3) * ARC_STEP_RAD
        total += endmill_forces(phi, TOOL, COEF, EndMillCut(fz, d, math.degrees(e),
                                                            math.degrees(x)), 12)  # fmt: skip
    return total


@pytest.mark.parametrize("spindle", ["M3", "M4"])
def test_two_walls_at_two_depths_sum_their_arcs(spindle: str) -> None:
    model = _model(f"G21 G90 G17\nS6000 {spindle}\nG0 X-28 Y0 Z5\nG1 Z-2.5 F500\nX25\nM30\n",
                   _walled())  # fmt: skip
    k = len(model.rpm) // 2  # a piece in the middle of the pass
    arcs = model.arcs[k][np.isfinite(model.arcs[k][:, 0])]
    # the walls at |y| = 3 meet the 5 mm radius 53.13 deg from either side of the feed
    edge = math.acos(3.0 / 5.0)
    left, right = arcs  # (M4 turns the other way: the left wall is where the teeth leave)
    assert len(arcs) == 2
    assert left[:2] == pytest.approx([0.0, edge] if spindle == "M3"
                                     else [math.pi - edge, math.pi], abs=ARC_STEP_RAD)  # fmt: skip
    # the left wall (y > 3) stands 2.5 mm above the tip, the right (y < -3) 1.5 mm
    assert left[2] == pytest.approx(2.5) and right[2] == pytest.approx(1.5)
    fz = 0.05
    peak, lateral, mean = model.forces_n(np.full(len(model.rpm), fz), mean=True)
    f = _direct(model, k, fz)
    assert peak[k] == pytest.approx(np.linalg.norm(f, axis=1).max(), rel=1e-9)
    assert mean[k] == pytest.approx(np.linalg.norm(f, axis=1).mean(), rel=1e-9)
    assert lateral[k] == pytest.approx(np.linalg.norm(f[:, :2], axis=1).max(), rel=1e-9)


def test_a_plunge_is_a_strip_at_the_edge_in_down_milling() -> None:
    model = _model("G21 G90 G17\nS6000 M3\nG0 X0 Y0 Z5\nG1 Z-3 F100\nM30\n",
                   ZMap.box(-30, 30, -20, 20, -10, 0, 0.1))  # fmt: skip
    arcs = model.arcs[:, 0]
    assert np.all(arcs[:, 1] == pytest.approx(math.pi))  # down milling: out at pi
    assert np.all(np.isnan(model.arcs[:, 1:]))
