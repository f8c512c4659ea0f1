"""Bad roughing input gives one clear message naming file, field, value and unit."""

from __future__ import annotations

import numpy as np
import pytest
from test_rough_parts import bump_grid, load_toml, part_toml

from analysis.errors import ConfigError, CutlabError
from planning.errors import PlanningError
from planning.rough import RoughPlanner


def bump(**kw):
    x, y, z = bump_grid(40, 40, 20, 25, 30)
    return x, y, z, kw


def test_nan_in_the_grid(tmp_path):
    x, y, z, _ = bump()
    z[3, 4] = np.nan
    text = part_toml(x, y, z, top=45.0)  # TOML writes the NaN as nan
    with pytest.raises(ConfigError) as e:  # refused at load, before any planning sees it
        load_toml(tmp_path, text)
    msg = str(e.value)
    assert "part.toml:6: surface.z_mm.3.4 = nan" in msg
    assert "finite number" in msg and "(mm" in msg


def test_folded_grid(tmp_path):
    x, y, z, _ = bump()
    gx, gy = np.meshgrid(x, y, indexing="ij")
    pts = np.stack([gx, gy, z], 2)
    pts[5, :, 0] = pts[3, :, 0]  # grid row 5 folds back over rows 3-4
    text = part_toml(x, y, z, top=45.0)
    rows = ",\n".join(
        "[" + ", ".join(f"[{a!r}, {b!r}, {c!r}]" for a, b, c in row) + "]" for row in pts.tolist()
    )
    head, tail = text.split("[stock]")
    head = head.split("x_mm")[0].replace('kind = "height_field"', 'kind = "grid"')
    text = head + f"points_mm = [\n{rows}\n]\n[stock]" + tail
    with pytest.raises(
        PlanningError, match=r"part.toml: surface: the grid folds over itself in xy"
    ):
        load_toml(tmp_path, text)


def test_tool_larger_than_the_part(tmp_path):
    x = np.linspace(0, 16, 5)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    z = 20 - 0.05 * ((gx - 8) ** 2 + (gy - 8) ** 2)
    part = load_toml(tmp_path, part_toml(x, x, z, top=25.0))
    with pytest.raises(PlanningError, match=r"diameter 20.0 mm\) is larger than the part.*16.0 mm"):
        RoughPlanner(part)


def test_zero_allowance_names_file_line_field_and_unit(tmp_path):
    x, y, z, _ = bump()
    with pytest.raises(ConfigError) as e:
        load_toml(tmp_path, part_toml(x, y, z, top=45.0, finish_allowance_mm=0.0))
    msg = str(e.value)
    lines = (tmp_path / "part.toml").read_text().splitlines()
    line = next(i for i, s in enumerate(lines, 1) if s.startswith("finish_allowance_mm"))
    assert f"part.toml:{line}: rough.finish_allowance_mm = 0.0" in msg
    assert "greater than 0" in msg and "(mm" in msg


def test_cusp_limit_below_what_the_levels_can_hold(tmp_path):
    x, y, z, _ = bump()
    part = load_toml(tmp_path, part_toml(x, y, z, top=45.0, cusp_mm=0.2, dh_mm=0.5))
    with pytest.raises(PlanningError, match=r"rough.cusp_mm = 0.2 mm is smaller than what"):
        RoughPlanner(part)


def test_not_a_flat_end_mill_and_unknown_tool(tmp_path):
    x, y, z, _ = bump()
    with pytest.raises(ConfigError, match="needs a flat end mill"):
        load_toml(tmp_path, part_toml(x, y, z, top=45.0, tool="phi10-ball"))
    with pytest.raises(
        ConfigError, match=r"\.toml:\d+: tool\.name = 'nope': .*tool 'nope' not found"
    ):
        load_toml(tmp_path, part_toml(x, y, z, top=45.0, tool="nope"))


def test_an_unknown_part_name_lists_the_shipped_parts():
    from planning.rough import load_part

    with pytest.raises(ConfigError, match=r"part 'seed000-bmp' not found: .*'seed000-bump'"):
        load_part("seed000-bmp")


def test_stock_not_covered_and_stock_below_the_part(tmp_path):
    x, y, z, _ = bump()
    part = load_toml(tmp_path, part_toml(x, y, z, top=45.0, stock_xy=(-10.0, 80.0, 0.0, 80.0)))
    with pytest.raises(PlanningError, match="not covered by the part surface"):
        RoughPlanner(part)
    part = load_toml(tmp_path, part_toml(x, y, z, top=5.0), name="low.toml")
    with pytest.raises(PlanningError, match="nothing to rough"):
        RoughPlanner(part)


def test_every_error_is_a_cutlab_error():
    assert issubclass(PlanningError, CutlabError) and issubclass(ConfigError, CutlabError)


def test_a_feed_per_tooth_given_as_the_table_feed_is_refused(tmp_path):
    x, y, z, _ = bump()
    text = part_toml(x, y, z, top=45.0).replace("feed_mm_min = 300.0", "feed_mm_min = 0.3")
    with pytest.raises(ConfigError, match=r"cutting\.feed_mm_min = 0\.3: .*mm/min, not mm/tooth"):
        load_toml(tmp_path, text)
