"""G2/G3 arcs fitted to roughing passes (planning/rough/_arcs.py) and the program written."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, MultiPoint
from shapely.geometry.polygon import orient

from analysis.config import REPO_ROOT
from analysis.errors import ConfigError
from planning.errors import PlanningError
from planning.nc import ARC_CCW, ARC_CW, LINE, interpret, linearize
from planning.rough import Part, RoughPlanner, check_program, fit_arcs, load_part, sample_path
from planning.rough.gcode import MoveSettings, plan_motion, plan_program, plan_totals

PART = REPO_ROOT / "configs" / "parts" / "seed000-bump.toml"


def circle(c, r, t0, sweep, n):
    th = t0 + sweep * np.arange(n + 1) / n
    return np.stack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)], 1)


def check_structure(p, fit, min_chords=3):
    assert fit.first[0] == 0 and fit.last[-1] == len(p) - 1
    assert np.array_equal(fit.last[:-1], fit.first[1:])
    arcs = fit.kind != LINE
    assert np.all(fit.last[arcs] - fit.first[arcs] >= min_chords)
    assert np.all(np.isnan(fit.center_mm[~arcs])) and np.all(np.isfinite(fit.center_mm[arcs]))


def vertex_deviation(p, fit):
    """Exact distance of every input vertex to the element that replaces it, (n,) mm."""
    dev = np.zeros(len(p))
    for k in range(len(fit)):
        a, b = p[fit.first[k]], p[fit.last[k]]
        q = p[fit.first[k] : fit.last[k] + 1]
        if fit.kind[k] == LINE:
            d = shapely.distance(shapely.points(q), LineString([a, b]))
        else:
            c, r = fit.center_mm[k], fit.radius_mm[k]
            # the run's vertices lie inside the arc's angular sweep (checked by the fit), so
            # the nearest arc point is along the ray from the centre
            d = np.abs(np.hypot(*(q - c).T) - r)
        dev[fit.first[k] : fit.last[k] + 1] = np.maximum(dev[fit.first[k] : fit.last[k] + 1], d)
    return dev


def distance_to_path(pts, p, fit):
    """Exact distance (m,) of points (m, 2) to the fitted path (its lines and arcs), mm."""
    d = np.full(len(pts), np.inf)
    lines = fit.kind == LINE
    if lines.any():
        segs = shapely.MultiLineString(
            [[p[a], p[b]] for a, b in zip(fit.first[lines], fit.last[lines])]
        )
        d = shapely.distance(shapely.points(pts), segs)
    for k in np.flatnonzero(~lines):
        c, r = fit.center_mm[k], fit.radius_mm[k]
        a, b = p[fit.first[k]], p[fit.last[k]]
        t0 = math.atan2(*(a - c)[::-1])
        sweep = (math.atan2(*(b - c)[::-1]) - t0) % (2 * math.pi)
        if np.array_equal(a, b):
            sweep = 2 * math.pi
        v = pts - c
        rel = (np.arctan2(v[:, 1], v[:, 0]) - t0) % (2 * math.pi)
        if fit.kind[k] == ARC_CW:
            rel, sweep = (
                (-rel) % (2 * math.pi),
                (2 * math.pi - sweep) % (2 * math.pi) or 2 * math.pi,
            )
        inside = rel <= sweep
        to_ends = np.minimum(np.linalg.norm(pts - a, axis=1), np.linalg.norm(pts - b, axis=1))
        dk = np.where(inside, np.abs(np.hypot(v[:, 0], v[:, 1]) - r), to_ends)
        d = np.minimum(d, dk)
    return d


def assert_hausdorff(p, fit, tol):
    """Both ways, exactly: points along the input near the output, output points near the input."""
    check_structure(p, fit)
    length = float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
    step = max(tol / 2, length / 3000)
    assert vertex_deviation(p, fit).max() <= tol + 1e-9
    dense = shapely.get_coordinates(shapely.segmentize(LineString(p), step))
    assert distance_to_path(dense, p, fit).max() <= tol + 1e-9
    # every sampled point is a point of the output path: each must be within tol
    out = sample_path(p, fit, step)
    assert shapely.distance(shapely.points(out), LineString(p)).max() <= tol + 1e-9


# ----------------------------------------------------------------------------- examples


@pytest.mark.parametrize("sense", [1, -1])
def test_a_sampled_circle_is_one_full_circle(sense):
    c, r = np.array([3.0, -2.0]), 7.0
    p = circle(c, r, 0.3, sense * 2 * math.pi, 64)
    p[-1] = p[0]
    # sagitta of a 5.6 degree chord on r = 7: 0.0084 mm
    fit = fit_arcs(p, 0.01)
    assert len(fit) == 1 and fit.first[0] == 0 and fit.last[0] == 64
    assert fit.kind[0] == (ARC_CCW if sense > 0 else ARC_CW)
    assert np.allclose(fit.center_mm[0], c, atol=0.01)
    assert fit.radius_mm[0] == pytest.approx(r, abs=0.01)
    assert_hausdorff(p, fit, 0.01)
    # under the chord sagitta no circle fits; the ring stays lines
    assert fit_arcs(p, 0.004).n_arcs == 0


@pytest.mark.parametrize("sense", [1, -1])
def test_an_open_arc_is_one_arc_and_a_longer_one_is_split(sense):
    c, r = np.array([-10.0, 4.0]), 20.0
    p = circle(c, r, 1.0, sense * math.radians(200), 50)
    fit = fit_arcs(p, 0.02)  # 4 degree chords on r = 20: sagitta 0.012 mm
    assert len(fit) == 1 and fit.kind[0] == (ARC_CCW if sense > 0 else ARC_CW)
    assert np.allclose(fit.center_mm[0], c, atol=0.02)
    assert fit.radius_mm[0] == pytest.approx(r, abs=0.02)
    assert_hausdorff(p, fit, 0.02)
    # 300 degrees: over the 270 degree limit of one arc
    p = circle(c, r, 1.0, sense * math.radians(300), 75)
    fit = fit_arcs(p, 0.02)
    assert len(fit) == 2 and np.all(fit.kind == fit.kind[0])
    assert np.allclose(fit.center_mm, c, atol=0.02)
    assert_hausdorff(p, fit, 0.02)


def test_a_slot_outline_is_two_lines_and_two_half_circles():
    # shapely buffer of a 30 mm segment: straight flanks and round ends r = 5 (quad_segs 16)
    ring = orient(LineString([(0, 0), (30, 0)]).buffer(5.0, quad_segs=16), 1.0).exterior
    p = np.asarray(ring.coords)
    fit = fit_arcs(p, 0.01)
    assert_hausdorff(p, fit, 0.01)
    arcs, lines = fit.kind != LINE, fit.kind == LINE
    seg = np.linalg.norm(p[fit.last] - p[fit.first], axis=1)
    # the ring may start inside a round end, which then is two arcs
    assert lines.sum() == 2 and np.allclose(seg[lines], 30.0)
    assert 2 <= arcs.sum() <= 3 and np.all(fit.kind[arcs] == ARC_CCW)
    assert np.allclose(fit.radius_mm[arcs], 5.0, atol=0.01)
    ends = np.array([(0.0, 0.0), (30.0, 0.0)])
    d = np.linalg.norm(fit.center_mm[arcs][:, None] - ends[None], axis=2).min(axis=1)
    assert np.all(d <= 0.01)


def test_zero_tolerance_keeps_every_chord_and_straight_runs_become_one_line():
    p = circle((0, 0), 10.0, 0.0, 1.0, 20)
    fit = fit_arcs(p, 0.0)
    assert np.all(fit.kind == LINE) and np.array_equal(fit.first, np.arange(20))
    # a 1e5 mm radius over 40 mm is straight within 0.01 mm (sagitta 0.002): one line, no arc
    far = circle((0, -1e5), 1e5, math.pi / 2, -4e-4, 30)
    fit = fit_arcs(far, 0.01)
    assert len(fit) == 1 and fit.kind[0] == LINE
    # without line merging it is still no arc: the radius is over max_radius_mm
    fit = fit_arcs(far, 0.01, merge_lines=False)
    assert fit.n_arcs == 0 and len(fit) == 30
    fit = fit_arcs(far, 0.01, merge_lines=False, max_radius_mm=1e6)
    assert fit.n_arcs == 1


def test_a_zigzag_and_a_corner_are_not_arcs():
    zig = np.stack([np.arange(12.0), np.where(np.arange(12) % 2, 0.5, 0.0)], 1)
    fit = fit_arcs(zig, 0.01)
    assert fit.n_arcs == 0 and len(fit) == 11
    # a square corner sampled finely: two lines, the corner kept
    corner = np.array([(x, 0.0) for x in range(10)] + [(9.0, y) for y in range(1, 10)])
    fit = fit_arcs(corner, 0.01)
    assert len(fit) == 2 and np.all(fit.kind == LINE) and fit.last[0] == 9


def test_bad_input_is_refused():
    with pytest.raises(PlanningError, match="polyline"):
        fit_arcs(np.zeros((1, 2)), 0.01)
    with pytest.raises(PlanningError, match="polyline"):
        fit_arcs(np.array([[0, 0], [np.nan, 1]]), 0.01)
    with pytest.raises(PlanningError, match="tol_mm = -1"):
        fit_arcs(np.zeros((3, 2)), -1)


# ----------------------------------------------------------------------------- properties


def _smooth(rng, tol):
    """Tangent-continuous lines and arcs of random radii, sampled with random chords, noisy."""
    pts, xy, head = [np.zeros((1, 2))], np.zeros(2), rng.uniform(0, 2 * math.pi)
    for _ in range(rng.integers(1, 6)):
        n = int(rng.integers(1, 40))
        if rng.random() < 0.3:
            ds = rng.uniform(0.05, 3.0, n)
            steps = ds[:, None] * np.array([math.cos(head), math.sin(head)])
            new = xy + np.cumsum(steps, 0)
        else:
            r = 10 ** rng.uniform(-0.5, 2.5)
            sweep = rng.choice([-1, 1]) * rng.uniform(0.1, 2 * math.pi)
            th = np.cumsum(rng.uniform(0.5, 1.5, n))
            th = sweep * th / th[-1]
            s = math.copysign(1, sweep)
            c = xy + s * r * np.array([-math.sin(head), math.cos(head)])
            ang = math.atan2(*(xy - c)[::-1]) + th
            new = c + r * np.stack([np.cos(ang), np.sin(ang)], 1)
            head += sweep
        pts.append(new)
        xy = new[-1]
    p = np.concatenate(pts)
    return p + rng.normal(0, 0.2 * tol, p.shape)


def _buffer(rng, _tol):
    """Exterior of a shapely buffer of random points or a random line (round joins)."""
    q = rng.uniform(0, 40, (int(rng.integers(1, 6)), 2))
    shape = LineString(q) if len(q) > 1 and rng.random() < 0.5 else MultiPoint(q)
    g = shape.buffer(rng.uniform(0.5, 12), quad_segs=int(rng.integers(4, 33)))
    g = max(getattr(g, "geoms", [g]), key=lambda x: x.area)
    return np.asarray(g.exterior.coords)


def _jagged(rng, _tol):
    return np.cumsum(rng.normal(0, 1, (int(rng.integers(2, 60)), 2)), 0)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    maker=st.sampled_from([_smooth, _buffer, _jagged]),
    tol=st.sampled_from([0.001, 0.01, 0.05]),
)
def test_fitted_path_and_polyline_are_within_tol_both_ways(seed, maker, tol):
    rng = np.random.default_rng(seed)
    p = maker(rng, tol)
    fit = fit_arcs(p, tol)
    assert_hausdorff(p, fit, tol)
    assert np.all(fit.radius_mm[fit.kind != LINE] <= 1000.0)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_arcs_of_a_buffered_convex_polygon_are_its_round_joins(seed):
    # a convex polygon buffered by rad: straight edges and round joins (centre: a vertex, radius:
    # rad) meeting tangentially; with a tolerance just over the chords' sagitta every join of
    # more than 15 degrees must come out as arcs about its vertex, and no arc anywhere else.
    # That needs edges of some length: a straight shorter than about two chords (1.8 found) and
    # the joins at its ends lie within tol of one circle of another radius, a valid arc (seed
    # 1196: a 0.18 mm edge and a 6 degree join, one arc of r 6.43 instead of three lines)
    rng = np.random.default_rng(seed)
    hull = MultiPoint(rng.uniform(0, 60, (int(rng.integers(3, 8)), 2))).convex_hull
    rad = rng.uniform(1, 8)
    edges = np.diff(np.asarray(hull.exterior.coords), axis=0)
    assume(np.hypot(*edges.T).min() >= 3 * 2 * rad * math.sin(math.pi / 128))
    p = np.asarray(orient(hull.buffer(rad, quad_segs=32), 1.0).exterior.coords)
    tol = 1.5 * rad * (1 - math.cos(math.pi / 128))
    fit = fit_arcs(p, tol)
    assert_hausdorff(p, fit, tol)
    arcs = fit.kind != LINE
    assert np.all(fit.kind[arcs] == ARC_CCW)
    assert np.allclose(fit.radius_mm[arcs], rad, atol=tol)
    v = np.asarray(orient(hull, 1.0).exterior.coords)[:-1]
    d = np.linalg.norm(fit.center_mm[arcs][:, None] - v[None], axis=2)
    assert np.all(d.min(axis=1) <= tol)
    e = np.diff(np.vstack([v[-1:], v, v[:1]]), axis=0)
    turn = np.abs(_wrap_deg(np.degrees(np.diff(np.arctan2(e[:, 1], e[:, 0])))))
    assert np.all(d[:, turn > 15].min(axis=0) <= tol)


def _wrap_deg(a):
    return (a + 180) % 360 - 180


# ----------------------------------------------------------------------------- the program


def _with_tol(part, tol):
    cfg = part.config
    rough = cfg.rough.model_copy(update={"arc_fit_tol_mm": tol})
    return Part(cfg.model_copy(update={"rough": rough}), part.path)


@pytest.fixture(scope="module")
def shipped_bisection():
    part = load_part(PART)
    planner = RoughPlanner(part)
    return part, planner, planner.plan_bisection()


@pytest.mark.long
def test_shipped_program_with_arcs_passes_the_zmap_check(shipped_bisection):
    part, planner, plan = shipped_bisection
    assert part.config.rough.arc_fit_tol_mm == 0.01
    st_ = part.config.stock
    box = (st_.x_min_mm, st_.x_max_mm, st_.y_min_mm, st_.y_max_mm, st_.z_min_mm, st_.z_max_mm)
    res, progs = {}, {}
    for tol in (0.0, 0.01):
        p = _with_tol(part, tol)
        progs[tol] = plan_program(plan, p).text()
        res[tol] = check_program(
            progs[tol], planner.offset_surface, box, part.tool.radius_mm,
            part.config.rough.cusp_mm, MoveSettings.of(p).safe_z_mm, spacing_mm=1.0,
        )  # fmt: skip
    arcs = interpret(progs[0.01], strict=True)
    assert arcs.is_arc.sum() > 100 and not interpret(progs[0.0]).is_arc.any()
    assert len(progs[0.01].splitlines()) < 0.2 * len(progs[0.0].splitlines())
    for r in res.values():
        assert r.ok and r.max_gouge_mm <= 0.05 and r.rapid_removed_mm3 == 0.0
        assert r.max_left_mm <= part.config.rough.cusp_mm + 0.05
    # arcs within 0.01 mm of the chords remove the same material to a fraction of a percent
    assert res[0.01].removed_mm3 == pytest.approx(res[0.0].removed_mm3, rel=1e-3)


def test_written_arcs_follow_the_passes_within_the_tolerance(shipped_bisection):
    part, _, plan = shipped_bisection
    tol = part.config.rough.arc_fit_tol_mm
    motion = plan_motion(plan, part)
    # the program reads back to the same moves, arcs included, to the written 0.001 mm
    back = interpret(plan_program(plan, part, motion).text(), strict=True)
    assert back.same_path(motion, atol_mm=1e-3)
    helical = motion.is_arc & (motion.start[:, 2] != motion.end[:, 2])
    assert helical.any() and np.all(motion.end[helical, 2] < motion.start[helical, 2])  # ramps
    # every point of every arc (flat and helical) within tol of a pass of its own level (block
    # holds the level index), plus the 0.0007 mm rounding of the vertices to the written grid
    lin = linearize(motion, chord_tol_mm=1e-4)
    on_arc = motion.is_arc[lin.source]
    level = motion.block[lin.source]
    for k, lv in enumerate(plan.levels):
        sel = on_arc & (level == k)
        rings = shapely.MultiLineString([q.xy_mm for q in lv.paths.passes])
        d = shapely.distance(shapely.points(lin.end[sel, :2]), rings)
        assert sel.any() and d.max() <= tol + 1e-3


def test_path_lengths_do_not_change_with_arcs(shipped_bisection):
    part, _, plan = shipped_bisection
    lines = plan_totals(plan, _with_tol(part, 0.0))
    arcs = plan_totals(plan, part)
    assert arcs["cutting_path_mm"] == lines["cutting_path_mm"] == round(plan.path_mm, 2)
    # an arc is a little longer than its chords; within 0.1 % over the whole program
    assert arcs["feed_length_mm"] == pytest.approx(lines["feed_length_mm"], rel=1e-3)
    m = plan_motion(plan, _with_tol(part, 0.0))
    assert not m.is_arc.any()


def test_arc_tolerance_out_of_range_names_the_field(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(PART.read_text() + "arc_fit_tol_mm = 2.0\n")
    with pytest.raises(ConfigError, match=r"rough\.arc_fit_tol_mm"):
        load_part(bad)
