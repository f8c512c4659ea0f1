"""The engaged arcs the Z-map reads before each piece cuts (``ZMap.cut_pieces(arcs=...)``, the
engagement of ``plan check``), against the closed forms of a straight cut: a strip of width ae
on the feed's right (down milling, M3) is entered at pi - acos(1 - 2 ae / D) and left at pi; on
the left (up milling) entered at 0 and left at acos(1 - 2 ae / D); a slot spans 0..pi.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planning.stock import ARC_STEP_RAD, MAX_ARCS, Cutter, ZMap

R_MM = 5.0
GRID_MM = 0.05


def _arcs(zmap: ZMap, p0, p1, cutter: Cutter | None = None) -> np.ndarray:  # noqa: ANN001
    a = np.full((1, 3 * MAX_ARCS), np.nan, np.float32)
    zmap.cut_pieces(cutter or Cutter("flat", R_MM), np.array([p0], float), np.array([p1], float),
                    arcs=a)  # fmt: skip
    return a.reshape(MAX_ARCS, 3).astype(float)


def _wall(y_wall_mm: float, keep_below: bool) -> ZMap:
    """Stock 5 mm high on one side of the line y = y_wall (the other side cut to the floor)."""
    z = ZMap.box(-20, 20, -20, 20, -10, 0, GRID_MM)
    y = z.y0_mm + (np.arange(z.shape[0]) + 0.5) * GRID_MM
    gone = y[:, None] >= y_wall_mm if keep_below else y[:, None] <= y_wall_mm
    z.heights_mm[np.broadcast_to(gone, z.shape)] = -5.0
    return z


@settings(max_examples=40, deadline=None, database=None)
@given(ae=st.floats(0.5, 9.5), down=st.booleans(), direction=st.sampled_from([1.0, -1.0]))
def test_a_strip_at_the_edge_is_the_closed_form(ae: float, down: bool, direction: float) -> None:
    # feed along +X (or -X): the right of the feed is -Y (or +Y)
    right_is_low = direction > 0
    keep_low = right_is_low if down else not right_is_low
    y_wall = (-R_MM + ae) if keep_low else (R_MM - ae)
    arcs = _arcs(_wall(y_wall, keep_low), (-direction, 0, -2), (direction, 0, -2))
    span = math.acos(1 - 2 * ae / (2 * R_MM))
    want = (math.pi - span, math.pi) if down else (0.0, span)
    assert np.isnan(arcs[1:, 0]).all()  # one arc
    assert arcs[0, :2] == pytest.approx(want, abs=ARC_STEP_RAD + 0.03)
    assert arcs[0, 2] == pytest.approx(2.0, abs=1e-6)  # 5 mm of stock above a tip at -2 ... 0


def test_a_slot_is_the_leading_half_and_the_depth_is_the_stock_above_the_tip() -> None:
    z = ZMap.box(-20, 20, -20, 20, -10, 0, 0.25)
    arcs = _arcs(z, (-1, 0, -3), (1, 0, -3))
    assert arcs[0].tolist() == pytest.approx([0.0, math.pi, 3.0], abs=1e-6)
    assert np.isnan(arcs[1:]).all()


def test_widening_a_narrower_slot_gives_two_arcs_and_a_plunge_none() -> None:
    z = ZMap.box(-20, 20, -20, 20, -10, 0, 0.05)
    y = z.y0_mm + (np.arange(z.shape[0]) + 0.5) * 0.05
    z.heights_mm[np.abs(y) < 3.0] = -5.0  # a 6 mm slot along X, cut before
    arcs = _arcs(z, (-0.1, 0, -2), (0.1, 0, -2))  # a 10 mm cutter along it: both walls
    edge = math.acos(3.0 / R_MM)  # the rim meets a wall where R cos(phi) = +-3
    assert arcs[0, :2] == pytest.approx([0.0, edge], abs=ARC_STEP_RAD)
    assert arcs[1, :2] == pytest.approx([math.pi - edge, math.pi], abs=ARC_STEP_RAD)
    assert arcs[:2, 2] == pytest.approx([2.0, 2.0])
    assert np.isnan(arcs[2:]).all()
    assert np.isnan(_arcs(z, (10, 10, -1), (10, 10, -2))).all()  # no XY motion: no direction


def test_a_ball_end_mill_gets_no_arcs() -> None:
    z = ZMap.box(-20, 20, -20, 20, -10, 0, 0.25)
    assert np.isnan(_arcs(z, (-1, 0, -3), (1, 0, -3), Cutter("ball", R_MM))).all()


def test_a_step_in_height_splits_the_arc_with_each_depth() -> None:
    z = ZMap.box(-20, 20, -20, 20, -10, 0, 0.05)
    y = z.y0_mm + (np.arange(z.shape[0]) + 0.5) * 0.05
    z.heights_mm[y < 0] = -1.0  # right of a +X feed: 1 mm of stock above the tip; left: 2 mm
    arcs = _arcs(z, (-0.1, 0, -2), (0.1, 0, -2))
    assert arcs[0].tolist() == pytest.approx([0.0, math.pi / 2, 2.0], abs=ARC_STEP_RAD)
    assert arcs[1].tolist() == pytest.approx([math.pi / 2, math.pi, 1.0], abs=ARC_STEP_RAD)


def test_the_compiled_and_the_numpy_kernels_read_the_same_arcs() -> None:
    from planning.stock import compiled as _numba

    if not _numba.AVAILABLE:
        pytest.skip("numba is not installed: only the numpy kernel runs")
    rng = np.random.default_rng(7)
    p0 = np.cumsum(rng.uniform(-2, 2, (300, 3)) * [1, 1, 0.05], axis=0) + [0, 0, -1]
    p1 = np.vstack([p0[1:], p0[-1:] + 1])
    out = []
    for compiled in (True, False):
        z = ZMap.box(-40, 40, -40, 40, -20, 0, 0.25)
        z.compiled = compiled
        a = np.full((len(p0), 3 * MAX_ARCS), np.nan, np.float32)
        z.cut_pieces(Cutter("bull", R_MM, 1.0), p0, p1, arcs=a)
        out.append(a)
    assert np.isfinite(out[0]).any()
    np.testing.assert_array_equal(out[0], out[1])
