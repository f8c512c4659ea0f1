"""Arcs against closed forms: all planes, IJK and R (both signs), CW/CCW, G90/G91, G20/G21,
helical and full circles; arc sweeps, lengths and linearisation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planning.nc import (
    ARC_CCW,
    ARC_CW,
    NCError,
    arc_radius_mm,
    arc_sweep_rad,
    interpret,
    linearize,
    segment_length_mm,
)
from planning.nc.arcs import PLANE_AXES

TAU = 2 * math.pi


def _xyz(plane: int, a: float, b: float, n: float) -> np.ndarray:
    ia, ib, ic = PLANE_AXES[plane]
    p = np.zeros(3)
    p[ia], p[ib], p[ic] = a, b, n
    return p


def _words(letters: str, values) -> str:
    return " ".join(f"{L}{v:.12f}" for L, v in zip(letters, values))


@st.composite
def arcs(draw):
    plane = draw(st.sampled_from([17, 18, 19]))
    cw = draw(st.booleans())
    spec = draw(st.sampled_from(["ijk", "r"]))
    absolute = draw(st.booleans())
    inch = draw(st.booleans())
    ca, cb = draw(st.floats(-50, 50)), draw(st.floats(-50, 50))
    r = draw(st.floats(0.5, 60))
    th0 = draw(st.floats(0, TAU))
    if spec == "r":  # keep clear of the semicircle, where the R form is ill-conditioned
        sweep = draw(
            st.one_of(st.floats(0.05, math.pi - 0.05), st.floats(math.pi + 0.05, TAU - 0.05))
        )
    else:
        sweep = draw(st.floats(0.05, TAU - 0.05))
    n0, n1 = draw(st.floats(-20, 20)), draw(st.floats(-20, 20))
    return plane, cw, spec, absolute, inch, ca, cb, r, th0, sweep, n0, n1


def _program(plane, cw, spec, absolute, inch, ca, cb, r, th0, sweep, n0, n1):
    th1 = th0 - sweep if cw else th0 + sweep
    p0 = _xyz(plane, ca + r * math.cos(th0), cb + r * math.sin(th0), n0)
    p1 = _xyz(plane, ca + r * math.cos(th1), cb + r * math.sin(th1), n1)
    u = 25.4 if inch else 1.0
    ia, ib, _ = PLANE_AXES[plane]
    lines = ["G20" if inch else "G21", f"G90 G{plane} F100", "G0 " + _words("XYZ", p0 / u)]
    if not absolute:
        lines.append("G91")
    target = (p1 - p0) if not absolute else p1
    arc = ("G2 " if cw else "G3 ") + _words("XYZ", target / u)
    if spec == "ijk":
        arc += " " + _words("IJK"[ia] + "IJK"[ib], [(ca - p0[ia]) / u, (cb - p0[ib]) / u])
    else:
        arc += f" R{(r if sweep < math.pi else -r) / u:.12f}"
    lines.append(arc)
    return "\n".join(lines), p0, p1


@pytest.mark.long
@settings(max_examples=300, deadline=None)
@given(arcs())
def test_arc_matches_closed_form(case):
    plane, cw, spec, absolute, inch, ca, cb, r, th0, sweep, n0, n1 = case
    text, p0, p1 = _program(*case)
    m = interpret(text)
    arc = m[m.is_arc]
    assert len(arc) == 1
    assert arc.kind[0] == (ARC_CW if cw else ARC_CCW)
    assert arc.plane[0] == plane
    np.testing.assert_allclose(arc.start[0], p0, atol=1e-6)
    np.testing.assert_allclose(arc.end[0], p1, atol=1e-6)
    ia, ib, ic = PLANE_AXES[plane]
    np.testing.assert_allclose(arc.center[0, [ia, ib]], [ca, cb], atol=1e-5)
    assert arc.center[0, ic] == pytest.approx(n0, abs=1e-6)  # out-of-plane coordinate = start's
    assert arc_radius_mm(arc)[0] == pytest.approx(r, abs=1e-5)
    assert arc_sweep_rad(arc)[0] == pytest.approx(sweep, abs=1e-6)
    assert segment_length_mm(arc)[0] == pytest.approx(math.hypot(r * sweep, n1 - n0), rel=1e-6)


@pytest.mark.parametrize(
    "words, center, sweep_deg",
    [
        ("G3 X0 Y10 R10", (0, 0), 90),  # CCW minor: centre left of the chord
        ("G3 X0 Y10 R-10", (10, 10), 270),  # CCW major
        ("G2 X0 Y10 R10", (10, 10), 90),  # CW minor: centre right of the chord
        ("G2 X0 Y10 R-10", (0, 0), 270),  # CW major
        ("G3 X0 Y10 I-10 J0", (0, 0), 90),
        ("G2 X0 Y10 I-10 J0", (0, 0), 270),
    ],
)
def test_quarter_circle_by_hand(words, center, sweep_deg):
    m = interpret(f"G0 X10 Y0\nG1 F100\n{words}")
    arc = m[m.is_arc]
    np.testing.assert_allclose(arc.center[0, :2], center, atol=1e-12)
    assert math.degrees(arc_sweep_rad(arc)[0]) == pytest.approx(sweep_deg)


@pytest.mark.parametrize("plane", [17, 18, 19])
@pytest.mark.parametrize("g", ["G2", "G3"])
def test_full_circle_and_helix(plane, g):
    ia, ib, ic = PLANE_AXES[plane]
    la, lb, ln = "XYZ"[ia], "XYZ"[ib], "XYZ"[ic]
    ca = "IJK"[ia]
    text = f"G{plane} G0 {la}10 {lb}0 {ln}0\nG1 F100\n{g} {la}10 {lb}0 {ca}-4 {ln}-3\n{g} {ca}-4"
    m = interpret(text)
    arcs_ = m[m.is_arc]
    assert len(arcs_) == 2  # helical full turn, then a flat full circle given by I/J/K alone
    np.testing.assert_allclose(arc_sweep_rad(arcs_), TAU)
    lengths = segment_length_mm(arcs_)
    assert lengths[0] == pytest.approx(math.hypot(TAU * 4, 3))
    assert lengths[1] == pytest.approx(TAU * 4)
    assert arcs_.end[0, ic] == -3 and arcs_.end[1, ic] == -3


def test_inch_and_incremental_arc():
    mm = interpret("G21 G90 G0 X25.4 Y0\nG1 F254\nG2 X50.8 Y0 I12.7 J0")
    inch = interpret("G20 G90 G0 X1 Y0\nG91 G1 F10\nG2 X1 Y0 I0.5 J0")
    assert mm.same_path(inch, atol_mm=1e-9)
    assert inch.feed_mm_min[-1] == pytest.approx(254.0)


def test_absolute_arc_centre_mode():
    a = interpret("G0 X10 Y0\nG1 F100\nG90.1 G3 X0 Y10 I0 J0")
    b = interpret("G0 X10 Y0\nG1 F100\nG91.1 G3 X0 Y10 I-10 J0")
    assert a.same_path(b)


@pytest.mark.parametrize(
    "arc, why",
    [
        ("G2 X20 Y0 R4", "smaller than half the chord"),
        ("G2 X10 Y0 R5", "start = end"),
        ("G2 X20 Y0 I4 J0", "differs from start radius"),
        ("G2 X20 Y0", "needs its centre"),
        ("G2 X20 Y0 R5 I5", "not both"),
    ],
)
def test_bad_arcs(arc, why):
    with pytest.raises(NCError, match=why) as info:
        interpret(f"G0 X10 Y0\nG1 F100\n{arc}", file="t.nc")
    assert info.value.line == 3 and info.value.file == "t.nc"


def test_radius_tolerance_from_machine():
    text = "G0 X10 Y0\nG1 F100\nG2 X20.005 Y0 I5 J0"
    with pytest.raises(NCError):
        interpret(text)
    assert len(interpret(text, arc_tolerance_mm=0.01)) == 2


@settings(max_examples=100, deadline=None)
@given(arcs(), st.sampled_from([0.1, 0.01, 0.001]))
def test_linearize_within_chord_tolerance(case, tol):
    text, p0, p1 = _program(*case)
    m = interpret(text)
    lin = linearize(m, tol)
    assert np.all(np.diff(lin.source) >= 0) and set(lin.source) == set(range(len(m)))
    np.testing.assert_allclose(lin.start[1:], lin.end[:-1], atol=1e-9)  # contiguous
    k = m.is_arc[lin.source]
    plane = case[0]
    ia, ib, _ = PLANE_AXES[plane]
    c = m.center[lin.source[k]][:, [ia, ib]]
    mid = 0.5 * (lin.start[k] + lin.end[k])[:, [ia, ib]]
    r = arc_radius_mm(m)[lin.source[k]]
    sagitta = r - np.linalg.norm(mid - c, axis=1)
    assert sagitta.max() <= tol * (1 + 1e-6)
    # ends on the arc
    np.testing.assert_allclose(np.linalg.norm(lin.end[k][:, [ia, ib]] - c, axis=1), r, atol=1e-6)
    np.testing.assert_array_equal(lin.end[-1], m.end[-1])


def test_linearize_maps_non_arcs_one_to_one_and_motion_indexing():
    m = interpret("G0 X1\nG1 Y2 F10\nG4 P100\nG2 X3 Y4 R1.5\nG0 Z3")
    lin = linearize(m, 0.01)
    assert list(lin.source[lin.source != 3]) == [0, 1, 2, 4]
    assert (lin.source == 3).sum() >= 2
    assert len(m[1]) == 1 and m[-1].end[0, 2] == 3 and len(m[m.is_feed]) == 2
    from planning.nc import Motion

    both = Motion.concatenate([m[:2], m[2:]])
    assert both.equals(m) and not both.equals(m[1:])


@settings(max_examples=100, deadline=None)
@given(arcs())
def test_exact_bounding_box_matches_fine_linearisation(case):
    from planning.nc import bounding_box

    text, _, _ = _program(*case)
    m = interpret(text)
    lo, hi = bounding_box(m)
    lin = linearize(m, 1e-5)
    pts = np.concatenate([lin.start, lin.end])
    np.testing.assert_allclose(lo, pts.min(axis=0), atol=2e-5)
    np.testing.assert_allclose(hi, pts.max(axis=0), atol=2e-5)
    assert np.all(lo <= pts.min(axis=0) + 1e-9) and np.all(hi >= pts.max(axis=0) - 1e-9)


@settings(max_examples=60, deadline=None)
@given(st.lists(arcs(), min_size=1, max_size=6))
def test_stats_box_equals_every_quadrant_point_box(cases):
    """motion_stats widens the end points' box only by the arcs that can leave it; the result is
    bit for bit the box of every segment's end and quadrant points (segment_boxes)."""
    from planning.nc import bounding_box, motion_stats

    m = interpret("\n".join(_program(*c)[0] for c in cases))
    st_ = motion_stats(m)
    lo, hi = bounding_box(m)
    assert st_.bbox_min_mm == tuple(lo) and st_.bbox_max_mm == tuple(hi)
    clo, chi = bounding_box(m[m.is_feed])
    assert st_.cutting_bbox_min_mm == tuple(clo) and st_.cutting_bbox_max_mm == tuple(chi)
