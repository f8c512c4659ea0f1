"""`cutlab plan orient`: outputs, JSON summary, and one-line errors for bad input (exit 2)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rig.cli import main

ROOT = Path(__file__).resolve().parent.parent
FAN = ROOT / "configs" / "orient" / "fan.toml"


def small(text: str, lines: str = "[0.5]", points: int = 6) -> str:
    return text.replace("lines = [0.1, 0.5, 0.9]", f"lines = {lines}").replace(
        "points_per_line = 10", f"points_per_line = {points}"
    )


@pytest.mark.long
def test_fan_writes_cl_nc_map_and_summary(tmp_path, capsys):
    cfg = tmp_path / "fan.toml"
    cfg.write_text(small(FAN.read_text(), "[0.1, 0.5]", 5))
    out = tmp_path / "out"
    assert main(["plan", "orient", str(cfg), "-o", str(out), "--json", "--map-point", "2"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["cc_points"] == summary["feasible"] == 10
    n = summary["cl_points"]  # the CC points and those refinement inserted between them
    assert n == 10 + summary["inserted_points"] == summary["checked"]
    assert summary["collisions"] == summary["between_collisions"] == 0
    assert summary["tip_deviation_mm"] <= 0.01 and summary["max_axis_jump_deg"] <= 5.0
    assert summary["feed_max_mm_min"] <= summary["feed_limit_mm_min"]
    assert summary["forward_check_mm"] < 1e-6 and summary["forward_check_rad"] < 1e-6
    assert summary["kinematics"] == "table-table-AC"
    cl = pd.read_csv(out / "cl.csv")
    assert len(cl) == n
    axis = cl[["axis_i", "axis_j", "axis_k"]].to_numpy()
    assert np.allclose(np.linalg.norm(axis, axis=1), 1.0, atol=1e-5)
    blocks = (out / "program.nc").read_text().splitlines()
    cuts = [b for b in blocks if b.startswith("G01") and " A" in b]
    assert len(cuts) == n - 2  # 2 lines: all but each line's first point, under G93
    assert sum(b.startswith("G01 G93") for b in cuts) == 2 and all(" F" in b for b in cuts)
    png = (out / "energy_map.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    assert json.loads((out / "summary.json").read_text())["energy_map_point"] == 2


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    msg = [line for line in err if line.startswith("cutlab: error:")]
    assert msg, err
    return "\n".join(err[err.index(msg[0]) :])


def test_bad_limit_names_file_line_field_value_and_unit(tmp_path, capsys):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(FAN.read_text().replace("alpha_deg = [0.0, 15.0]", "alpha_deg = [0.0, 95.0]"))
    assert main(["plan", "orient", str(cfg), "-o", str(tmp_path / "o")]) == 2
    msg = _err(capsys)
    assert f"{cfg}:8: limits: " in msg or f"{cfg}:" in msg
    assert "alpha_deg = (0.0, 95.0)" in msg and "(deg)" in msg
    assert "Traceback" not in msg


def test_degenerate_normals_are_reported(tmp_path, capsys):
    text = FAN.read_text()
    start = text.index("control_points_mm = [\n") + len("control_points_mm = [\n")
    end = text.index("\n", start)
    row = text[start:end]
    n = row.count("[") - 1
    text = text[:start] + "  [" + ", ".join(["[0.0, 0.0, 0.0]"] * n) + "]," + text[end:]
    cfg = tmp_path / "degenerate.toml"
    cfg.write_text(small(text, "[0.5]", 3).replace("span = [0.08, 0.92]", "span = [0.0, 1.0]"))
    assert main(["plan", "orient", str(cfg), "-o", str(tmp_path / "o")]) == 2
    assert "blade: degenerate normal at u = 0, v = 0.5" in _err(capsys)


def test_no_collision_free_orientation_stops_without_output(tmp_path, capsys):
    imp = (ROOT / "configs" / "orient" / "impeller.toml").read_text()
    imp = imp.replace("alpha_deg = [0.0, 15.0]", "alpha_deg = [10.0, 10.0]")
    imp = imp.replace("beta_deg = [-90.0, 90.0]", "beta_deg = [60.0, 65.0]")
    imp = imp.replace("lines = [0.15, 0.38, 0.62, 0.85]", "lines = [0.5]")
    imp = imp.replace("points_per_line = 10", "points_per_line = 2")
    cfg = tmp_path / "tight.toml"
    cfg.write_text(imp)
    out = tmp_path / "o"
    assert main(["plan", "orient", str(cfg), "-o", str(out)]) == 2
    msg = _err(capsys)
    assert "2 of 2 CC points have no collision-free orientation" in msg
    assert "CC point 0 (line 0" in msg and "hits blade" in msg
    assert not (out / "cl.csv").exists() and not (out / "program.nc").exists()


def test_tool_with_corner_radius_above_radius_is_refused(tmp_path, capsys, monkeypatch):
    conf = tmp_path / "conf"
    (conf / "machines").mkdir(parents=True)
    shutil.copy(ROOT / "configs" / "machines" / "mill-5axis.toml", conf / "machines")
    (conf / "tools.toml").write_text(
        '[tools.phi10-flat]\nkind = "bull"\ndiameter_mm = 10.0\ncorner_radius_mm = 6.0\n'
        "flute_length_mm = 20.0\nflutes = 2\n"
    )
    monkeypatch.setenv("CUTLAB_CONFIG_DIR", str(conf))
    assert main(["plan", "orient", str(FAN), "-o", str(tmp_path / "o")]) == 2
    msg = _err(capsys)
    assert "tools.toml:4: tools.phi10-flat.corner_radius_mm = 6.0" in msg or (
        "corner_radius_mm = 6.0: a bull end mill needs 0 < corner radius < D/2 = 5.0 mm" in msg
    )


@pytest.mark.long
def test_grbl_dialect_is_refused_and_linuxcnc_is_written(tmp_path, capsys):
    cfg = tmp_path / "fan.toml"
    cfg.write_text(small(FAN.read_text(), "[0.5]", 3))
    out = tmp_path / "o"
    assert main(["plan", "orient", str(cfg), "-o", str(out), "--dialect", "grbl"]) == 2
    assert "GRBL has no rotary axes" in _err(capsys) and not out.exists()
    args = ["plan", "orient", str(cfg), "-o", str(out), "--dialect", "linuxcnc", "--no-plot"]
    assert main([*args, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["dialect"] == "linuxcnc"
    text = (out / "program.nc").read_text()
    assert "O1000" not in text and "G93" in text


@pytest.mark.long
@pytest.mark.parametrize("kind", ["head-table-AC", "head-head-BC"])
def test_head_table_machine(tmp_path, capsys, kind, monkeypatch):
    conf = tmp_path / "conf"
    (conf / "machines").mkdir(parents=True)
    shutil.copy(ROOT / "configs" / "tools.toml", conf)
    m = (ROOT / "configs" / "machines" / "mill-5axis.toml").read_text()
    m = m.replace('kind = "table-table-AC"', f'kind = "{kind}"\nhead_pivot_length_mm = 150.0')
    m = m.replace("[x]\nmin_mm = -400\nmax_mm = 400", "[x]\nmin_mm = -800\nmax_mm = 800")
    m = m.replace("[y]\nmin_mm = -300\nmax_mm = 300", "[y]\nmin_mm = -800\nmax_mm = 800")
    (conf / "machines" / "mill-5axis.toml").write_text(m)
    monkeypatch.setenv("CUTLAB_CONFIG_DIR", str(conf))
    cfg = tmp_path / "fan.toml"
    cfg.write_text(small(FAN.read_text(), "[0.5]", 4))
    assert main(["plan", "orient", str(cfg), "-o", str(tmp_path / "o"), "--json", "--no-plot"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["kinematics"] == kind and summary["collisions"] == 0
