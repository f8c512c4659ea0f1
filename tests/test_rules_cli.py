"""`cutlab rules ...` end to end on real HDF5 run files written by the rig's RunWriter."""

from __future__ import annotations

import json

import numpy as np
import pytest
from _rules_sweep import FS, RPM, sweep

from analysis.config import load_rig
from analysis.rules import load_rule
from rig.calibration import Calibration
from rig.cli import main
from rig.daq.base import SAMPLE_FORMAT_VOLTS, DaqInfo
from rig.logger import RunWriter


def _write_runs(tmp_path, change_at=1000.0):
    rig = load_rig()
    cal = Calibration.from_rig(rig)
    info = DaqInfo(
        "sim", ("ai0", "ai1", "ai2"), cal.channel_names, FS, SAMPLE_FORMAT_VOLTS, 10.0, 2000
    )
    paths = []
    for run in sweep(change_at):
        f = np.zeros((len(run.forces_n) + 4000, 3))
        f[2000:-2000, :2] = run.forces_n  # air before and after the cut
        volts = cal.volts_from_force(f)
        p = tmp_path / f"sweep-{int(run.feed_mm_min)}.h5"
        w = RunWriter(p, info, cal)
        w.set_conditions(
            {
                "feed_mm_min": run.feed_mm_min,
                "spindle_rpm": RPM,
                "tool": "phi30-ball",
                "depth_mm": 0.3,
                "width_mm": 30.0,
                "material": "gm241",
            }
        )
        w.on_start(info, 0.0)
        for i in range(0, len(volts), 2000):
            w.put_block(i, np.ascontiguousarray(volts[i : i + 2000].T))
        w.close()
        paths.append(p)
    return paths


def test_rules_derive_add_list_show_export(tmp_path, capsys) -> None:
    runs = _write_runs(tmp_path)
    rule_path = tmp_path / "gm241.toml"
    assert (
        main(
            [
                "rules",
                "derive",
                *map(str, runs),
                "-o",
                str(rule_path),
                "--min-feed",
                "100",
                "--max-feed",
                "3500",
                "--json",
                "--png",
                str(tmp_path / "r.png"),
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert out["base_feed_mm_min"] == 1000.0
    assert "between 1000 and 1200" in out["base_feed_reason"]
    rule = load_rule(rule_path)
    assert rule.n_bins == 20 and rule.feed_for(rule.reference_load_pct) == 1000
    assert rule.reference_load_pct == pytest.approx(0.1329, rel=1e-3)  # phi 30 ball, 0.3 mm slot
    assert (tmp_path / "r.png").stat().st_size > 5000

    db = str(tmp_path / "rb.sqlite")
    key = [
        "--part-family",
        "test/sweep",
        "--operation",
        "slotting",
        "--tool-diameter",
        "30",
        "--flute-length",
        "30",
        "--material",
        "gm241",
        "--spindle",
        "2000",
        "--depth",
        "0.3",
        "--tolerance",
        "0.05",
    ]
    assert main(["rules", "add", str(rule_path), *key, "--db", db]) == 0
    assert main(["rules", "list", "--db", db, "--json"]) == 0
    capsys.readouterr()
    assert main(["rules", "show", "gm241", "--db", db, "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["base_feed_mm_min"] == 1000 and len(shown["bins"]) == 20
    key[key.index("30")] = "25"  # a 25 mm tool: nearest match, stated
    assert main(["rules", "lookup", *key, "--db", db]) == 0
    assert "nearest match" in capsys.readouterr().out
    assert main(["rules", "export", "gm241", "-o", str(tmp_path / "x.toml"), "--db", db]) == 0
    assert (tmp_path / "x.toml").read_text() == rule_path.read_text()


def test_rules_derive_without_a_change_fails_cleanly(tmp_path, capsys) -> None:
    runs = _write_runs(tmp_path, change_at=None)
    assert main(["rules", "derive", *map(str, runs), "-o", str(tmp_path / "r.toml")]) == 2
    err = capsys.readouterr().err
    assert "no base feed found: no sharp change" in err and "--base-feed" in err
    assert not (tmp_path / "r.toml").exists()
