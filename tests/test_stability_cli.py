"""`cutlab analyze stability CONFIG -o lobes.csv [--method sd|zoa] [--json] [--plot PNG]`.

The command is called as `cutlab analyze ...` (``rig.cli.main``: a CutlabError is one line
``cutlab: error: ...``, exit 2).
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from rig.cli import main

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "configs" / "stability" / "insperger-1dof-down-005.toml"


def cutlab(argv: list[str]) -> int:
    """`cutlab analyze ARGV`."""
    return main(["analyze", *argv])


def _strict(text: str):
    def refuse(name: str) -> None:
        raise ValueError(f"{name} in the JSON output")

    return json.loads(text, parse_constant=refuse)


@pytest.mark.parametrize("method", ["sd", "zoa"])
def test_the_contract_command_writes_200_rows(tmp_path, capsys, method) -> None:
    out = tmp_path / "lobes.csv"
    assert cutlab(["stability", str(CONFIG), "-o", str(out), "--method", method]) == 0
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == [
        "spindle_rpm", "depth_limit_mm", "chatter_hz", "kind", "steps", "convergence_pct",
    ]  # fmt: skip
    assert len(rows) == 200
    assert float(rows[0]["spindle_rpm"]) == 5000 and float(rows[-1]["spindle_rpm"]) == 25000
    assert all(float(r["depth_limit_mm"]) > 0 for r in rows)
    err = capsys.readouterr().err
    # the benchmark's flip lobes: ZOA warns, SD does not
    assert ("warning: the zero-order approximation misses period-doubling" in err) == (
        method == "zoa"
    )


def test_json_is_strict_with_null_and_a_reason(tmp_path, capsys) -> None:
    cfg = tmp_path / "c.toml"
    text = CONFIG.read_text().replace("points = 200", "points = 40")
    cfg.write_text(text + "\n[search]\ndepth_max_mm = 3.0\n")
    assert cutlab(["stability", str(cfg), "-o", str(tmp_path / "l.csv"), "--json"]) == 0
    got = _strict(capsys.readouterr().out)
    assert got["method"] == "sd" and got["steps_per_period"] == 30 and got["warnings"] == []
    conv = got["convergence"]
    assert conv["checked"] and conv["max_change_pct"] <= 1.0 and conv["unconverged_speeds"] == 0
    assert all(r["steps"] >= 30 and r["convergence_pct"] <= 1.0 for r in got["rows"])
    stable = [r for r in got["rows"] if r["depth_limit_mm"] is None]
    assert stable and all("stable up to depth_max_mm = 3 mm" in r["depth_limit_mm_reason"]
                          for r in stable)  # fmt: skip
    assert any(r["kind"] == "flip" for r in got["rows"])
    rows = list(csv.DictReader((tmp_path / "l.csv").open()))
    # nothing blank: a speed stable up to the ceiling reads inf, its kind "stable"
    assert all(v != "" for r in rows for v in r.values())
    assert sum(r["depth_limit_mm"] == "inf" and r["kind"] == "stable" for r in rows) == len(stable)


def test_csv_is_round_trip_exact_and_max_depth_sets_the_ceiling(tmp_path, capsys) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text(CONFIG.read_text().replace("points = 200", "points = 12"))
    out = tmp_path / "l.csv"
    assert cutlab(["stability", str(cfg), "-o", str(out), "--json", "--max-depth", "100"]) == 0
    got = _strict(capsys.readouterr().out)
    assert got["depth_max_mm"] == 100.0
    rows = list(csv.DictReader(out.open()))
    for r, j in zip(rows, got["rows"]):
        assert float(r["spindle_rpm"]) == j["spindle_rpm"]  # exact, not to 6 digits
        if j["depth_limit_mm"] is not None:
            assert float(r["depth_limit_mm"]) == j["depth_limit_mm"]
    # the default ceiling (30 x the ZOA minimum, ~45 mm here) left speeds without a limit that
    # exists below 100 mm
    assert cutlab(["stability", str(cfg), "-o", str(out), "--json"]) == 0
    default = _strict(capsys.readouterr().out)
    assert sum(r["depth_limit_mm"] is None for r in got["rows"]) <= sum(
        r["depth_limit_mm"] is None for r in default["rows"]
    )


def test_fixed_steps_say_convergence_is_unchecked(tmp_path, capsys) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text(CONFIG.read_text().replace("points = 200", "points = 6"))
    assert cutlab(["stability", str(cfg), "-o", str(tmp_path / "l.csv"), "--steps", "20"]) == 0
    assert "convergence unchecked" in capsys.readouterr().out


def test_plot_writes_a_png(tmp_path) -> None:
    png = tmp_path / "lobes.png"
    assert cutlab(["stability", str(CONFIG), "-o", str(tmp_path / "l.csv"), "--plot",
                   str(png)]) == 0  # fmt: skip
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "old,new,words",
    [
        ("zeta = 0.011", "zeta = 1.5", ["modes.0.zeta", "1.5", "damping ratio"]),
        ("points = 200", "points = 0", ["spindle.points", "0"]),
        ("m_kg = 0.03993", "", ["exactly one of k_N_m"]),
        ("teeth = 2", 'teeth = "two"', ["tool.teeth", "'two'"]),
    ],
)
def test_bad_config_is_one_line_exit_2(tmp_path, capsys, old, new, words) -> None:
    cfg = tmp_path / "bad.toml"
    cfg.write_text(CONFIG.read_text().replace(old, new))
    assert cutlab(["stability", str(cfg), "-o", str(tmp_path / "l.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("cutlab: error: ") and "\n" not in err and "Traceback" not in err
    assert str(cfg) in err
    for w in words:
        assert w in err
    assert not (tmp_path / "l.csv").exists()


def test_missing_config_and_bad_steps(tmp_path, capsys) -> None:
    assert cutlab(["stability", str(tmp_path / "no.toml"), "-o", str(tmp_path / "l.csv")]) == 2
    assert "config file not found" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        cutlab(["stability", str(CONFIG), "-o", str(tmp_path / "l.csv"), "--steps", "2"])
    assert exc.value.code == 2


def test_shipped_configs_load(tmp_path) -> None:
    from analysis.stability import load_case

    for p in sorted((ROOT / "configs" / "stability").glob("*.toml")):
        shutil.copy(p, tmp_path / p.name)
        assert load_case(tmp_path / p.name).rpm.size >= 2
