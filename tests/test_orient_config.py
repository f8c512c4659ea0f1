"""planning.orient.config: the three shipped models load; bad configs name file, line and field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from analysis.errors import ConfigError
from planning.orient import energy_map, load_orient, plan_orientation

ROOT = Path(__file__).resolve().parent.parent
IMP = ROOT / "configs" / "orient" / "impeller.toml"


@pytest.mark.parametrize("name,n_surf", [("impeller", 3), ("fan", 2), ("mask", 1)])
def test_shipped_models_load_and_normals_face_the_tool(name, n_surf):
    cfg, tool, machine = load_orient(ROOT / "configs" / "orient" / f"{name}.toml")
    assert len(cfg.surfaces) == n_surf and machine.five_axis is not None
    machined = cfg.machined.build()
    sp = machined.evaluate(*machined.grid(5, 5))
    assert np.all(sp.normal[:, 2] > 0.3)  # machined from above
    if name == "impeller":  # the blades' normals point into the channel between them
        left, right = (s.build() for s in cfg.surfaces[1:])
        assert np.all(left.evaluate(*left.grid(4, 4)).normal[:, 1] > 0.5)
        assert np.all(right.evaluate(*right.grid(4, 4)).normal[:, 1] < -0.5)


def _write(tmp_path, text):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    return p


def test_ragged_control_net_names_the_surface(tmp_path):
    text = IMP.read_text().replace("[74.6667, 19.2559, 9.8613]],", "],", 1)
    p = _write(tmp_path, text)
    with pytest.raises(ConfigError, match=r"bad.toml:\d+: surfaces.0: control_points_mm rows have"):
        load_orient(p)


def test_two_machined_surfaces_and_unknown_keys_are_refused(tmp_path):
    text = IMP.read_text().replace('role = "check"', 'role = "machined"', 1)
    with pytest.raises(ConfigError, match="exactly one surface must have role = 'machined'"):
        load_orient(_write(tmp_path, text))
    text = IMP.read_text().replace("[planner]\n", "[planner]\nfeed_mm_mn = 3\n")
    with pytest.raises(ConfigError, match=r"bad.toml:12: planner.feed_mm_mn = 3: unknown key"):
        load_orient(_write(tmp_path, text))
    # Another model also has a feed_mm_min (with another description): the unit shown is the
    # planner's own, found by following the error's location, not the first field of that name.
    import planning.rough.part  # noqa: F401

    text = IMP.read_text().replace("feed_mm_min = 800.0", "feed_mm_min = -800.0")
    with pytest.raises(ConfigError, match=r"planner.feed_mm_min = -800.0: .*0 \(mm/min\)$"):
        load_orient(_write(tmp_path, text))


def test_energy_map_has_free_and_colliding_regions_and_the_answer_is_free():
    cfg, tool, _ = load_orient(IMP)
    cfg = cfg.model_copy(
        update={"paths": cfg.paths.model_copy(update={"lines": (0.85,), "points_per_line": 3})}
    )
    res = plan_orientation(cfg, tool)
    emap = energy_map(cfg, tool, 0, res, n_alpha=6, n_beta=37)
    assert emap.energy.shape == (6, 37)
    assert (emap.energy == 0).any() and (emap.energy > 0).any()
    # Leaning 90 deg either way puts the tool into a blade.
    assert np.all(emap.energy[:, 0] > 0) and np.all(emap.energy[:, -1] > 0)
    assert np.all(np.isfinite(emap.descent_deg))
    assert np.all(np.isfinite(emap.chosen_deg))
