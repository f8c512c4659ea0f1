"""Properties of one level's passes on random bumps (hypothesis)."""

from __future__ import annotations

import tomllib

import numpy as np
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from shapely.geometry import MultiLineString
from test_rough_parts import bump_grid, part_toml

from analysis.validation import validate
from planning.rough import RoughPlanner
from planning.rough.part import Part, PartConfig

TOL_MM = 0.03  # contour tolerance + polygonal offsets (16 segments per quarter circle)


def planner_for(cx, cy, wx, wy, height) -> RoughPlanner:
    x, y, z = bump_grid(cx, cy, wx, wy, height)
    text = part_toml(x, y, z, top=10.0 + height + 3.0, tool="phi10-flat", cusp_mm=3.0)
    return RoughPlanner(Part(validate(PartConfig, tomllib.loads(text))))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    cx=st.floats(25, 55),
    cy=st.floats(25, 55),
    wx=st.floats(12, 30),
    wy=st.floats(12, 30),
    height=st.floats(15, 40),
    z_frac=st.floats(0.1, 0.9),
    lo_frac=st.one_of(st.none(), st.floats(0.05, 0.95)),
)
def test_passes_stay_in_the_region_and_never_cross_the_offset_surface(
    cx, cy, wx, wy, height, z_frac, lo_frac
):
    pl = planner_for(cx, cy, wx, wy, height)
    top = pl.cusps.z_top_mm
    z = pl.bottom + z_frac * (top - pl.bottom)
    lo = None if lo_frac is None else pl.bottom + lo_frac * (z - pl.bottom)
    lv = pl.geom.level(z, lo)
    r = pl.geom.r
    region = pl.geom.region(z, lo)
    if region.area < 1e-6:
        assert not lv.passes
        return
    assert lv.passes
    pts = np.concatenate(
        [
            shapely.get_coordinates(shapely.segmentize(shapely.LineString(p.xy_mm), 1.0))
            for p in lv.passes
        ]
    )
    # Inside the region: the tool reaches material of A(lo) and keeps r off the section at z.
    reach = pl.geom.above(lo).buffer(r + 1e-6)
    assert shapely.contains_xy(reach, pts[:, 0], pts[:, 1]).all()
    section = pl.geom.section(z)
    if not section.is_empty:
        d = shapely.distance(shapely.points(pts), section)
        assert d.min() >= r - TOL_MM
    # No path crosses the offset surface: no surface point under the flat end is above z (the
    # offset surface's rim that the allowance pushes outside the stock is no material).
    p, _ = pl.offset_surface.sample(10)
    p = p.reshape(-1, 3)
    p = p[(p[:, 0] >= 0) & (p[:, 0] <= 80) & (p[:, 1] >= 0) & (p[:, 1] <= 80)]
    tree = cKDTree(p[:, :2])
    for idx in tree.query_ball_point(pts, r - TOL_MM):
        if idx:
            assert p[idx, 2].max() <= z + TOL_MM
    # And the passes clear the whole region (the shoulder's area at this level).
    swept = MultiLineString([q.xy_mm for q in lv.passes]).buffer(r)
    assert region.difference(swept).area <= max(1e-3 * region.area, 0.5)
