"""Config loading: shipped configs validate; bad fields are named with file, line, value, unit."""

from __future__ import annotations

from pathlib import Path

import pytest

from analysis import config as cfg
from analysis.errors import ConfigError


def test_shipped_configs_load() -> None:
    for m in sorted((cfg.config_dir() / "machines").glob("*.toml")):
        assert cfg.load_machine(m).feed_max_mm_min > 0
    tools = cfg.load_tools()
    fm = tools["seed003-facemill"]
    assert (fm.diameter_mm, fm.inserts, fm.lead_angle_deg, fm.axial_rake_deg) == (125, 1, 15, 7)
    assert fm.nose_radius_mm == 0.4 and fm.radial_rake_deg == 0
    mat = cfg.get_material("al6061-t6")
    assert mat.facemill is not None and mat.facemill.K_T_n_mm2 == 405.4
    rig = cfg.load_rig()
    assert [m.f_hz for m in rig.dynamometer.modes] == [2050, 1810, 3230]


def _write(tmp_path: Path, text: str, name: str = "tools.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_error_names_file_line_field_value_and_unit(tmp_path: Path) -> None:
    p = _write(
        tmp_path, '[tools.a]\nkind = "flat"\ndiameter_mm = -10\nflute_length_mm = 20\nflutes = 3\n'
    )
    with pytest.raises(ConfigError) as ei:
        cfg.load_tools(p)
    msg = str(ei.value)
    assert f"{p}:3: tools.a.diameter_mm = -10" in msg
    assert "greater than 0" in msg and "(mm)" in msg


def test_unknown_key_is_an_error(tmp_path: Path) -> None:
    p = _write(
        tmp_path,
        '[tools.a]\nkind = "flat"\ndiameter_mm = 10\nflute_length_mm = 20\n'
        'flutes = 3\ncolour = "red"\n',
    )
    with pytest.raises(ConfigError, match=r":6: tools\.a\.colour = 'red': unknown key"):
        cfg.load_tools(p)


def test_ball_corner_radius_must_be_half_diameter(tmp_path: Path) -> None:
    p = _write(
        tmp_path,
        '[tools.b]\nkind = "ball"\ndiameter_mm = 10\ncorner_radius_mm = 4\n'
        "flute_length_mm = 20\nflutes = 2\n",
    )
    with pytest.raises(ConfigError, match=r":1: tools\.b: corner_radius_mm = 4.0: a ball end mill"):
        cfg.load_tools(p)


def test_crosstalk_shape_checked(tmp_path: Path) -> None:
    p = _write(
        tmp_path,
        '[dynamometer]\nmodel = "x"\ncrosstalk = [[1, 0], [0, 1]]\n'
        '[[dynamometer.channels]]\nname = "Fx"\naxis = "x"\nsensitivity_pc_n = -7.9\n'
        "range_n_v = 500\n",
        "rig.toml",
    )
    with pytest.raises(ConfigError, match=r"crosstalk is 2 x \[2\]: expected 1 x 1"):
        cfg.load_rig(p)


def test_bad_toml_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not valid TOML"):
        cfg.load_machine(_write(tmp_path, "name = \n", "m.toml"))
    with pytest.raises(ConfigError, match="not found"):
        cfg.load_machine("no-such-machine")


def test_machine_feed_limits_ordered(tmp_path: Path) -> None:
    text = (cfg.config_dir() / "machines" / "ace-h63.toml").read_text()
    text = text.replace("feed_min_mm_min = 1", "feed_min_mm_min = 20000")
    with pytest.raises(ConfigError, match="feed_max_mm_min"):
        cfg.load_machine(_write(tmp_path, text, "m.toml"))


def test_the_unit_shown_is_that_of_the_tool_kind_at_fault(tmp_path: Path) -> None:
    """End mills and face mills both have runout_mm, described differently: the face mill's
    description must come with a face mill's error (the union member chosen by `kind`)."""
    text = (
        '[tools.fm]\nkind = "facemill"\ndiameter_mm = 125.0\ninserts = 1\nrunout_mm = 5\n'
        "lead_angle_deg = 15.0\naxial_rake_deg = 7.0\nradial_rake_deg = 0.0\n"
        "nose_radius_mm = 0.4\ninsert_edge_length_mm = 12.7\n"
    )
    p = tmp_path / "tools.toml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=r"tools\.toml:5: tools\.fm\.runout_mm = 5: .*\(mm, "
                       r"radial runout per insert\)$"):  # fmt: skip
        cfg.load_tools(p)
