"""`cutlab rules ...` end to end on real HDF5 run files written by the rig's RunWriter."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from _rules_sweep import FS, RPM, sweep

from analysis.config import load_rig
from analysis.rules import derive_rule, load_rule, save_rule
from rig.cli import main
from rig.daq import SAMPLE_FORMAT_VOLTS, Calibration, DaqInfo
from rig.log import RunWriter
from rig.report.feedrule import feed_rule_section


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


def _rule_base(tmp_path) -> tuple[str, list[str]]:
    """A rule base holding one group (roughing/gm241, phi 30) and the CLI key that selects it."""
    rule = tmp_path / "gm241.toml"
    save_rule(derive_rule("gm241", 100, 1000, 3500, 0.1329), rule)
    db = str(tmp_path / "rb.sqlite")
    key = ["--part-family", "trunk/outer/draw/lower-die", "--operation", "roughing",
           "--tool-diameter", "30", "--flute-length", "30", "--material", "gm241",
           "--spindle", "2000", "--depth", "0.3", "--tolerance", "0.05"]  # fmt: skip
    assert main(["rules", "add", str(rule), *key, "--db", db]) == 0
    return db, key


def test_add_says_when_it_creates_the_rule_base(tmp_path, capsys) -> None:
    db, key = _rule_base(tmp_path)
    assert f"{db} does not exist: creating a new rule base there" in capsys.readouterr().err
    other = save_rule(derive_rule("b", 100, 800, 3500, 0.1329), tmp_path / "b.toml")
    key[key.index("--depth") + 1] = "0.5"
    assert main(["rules", "add", str(other), *key, "--db", db]) == 0
    assert "creating" not in capsys.readouterr().err


def test_derived_description_says_base_feed_once(tmp_path, capsys) -> None:
    runs = _write_runs(tmp_path)
    out = tmp_path / "r.toml"
    assert main(["rules", "derive", *map(str, runs), "-o", str(out)]) == 0
    text = load_rule(out).description
    assert (
        text.startswith("base feed 1000 mm/min: between 1000 and 1200")
        and text.count("base feed") == 1
    )
    assert main(["rules", "derive", *map(str, runs[:3]), "-o", str(out), "--base-feed", "900"]) == 0
    assert load_rule(out).description == "base feed 900 mm/min given with --base-feed"
    capsys.readouterr()


def test_feed_rule_report_says_base_feed_once(tmp_path) -> None:
    runs = _write_runs(tmp_path)
    spec = SimpleNamespace(
        analysis=SimpleNamespace(identify_groups=(), rule_name="derived"),
        feed_rule=SimpleNamespace(min_feed_mm_min=100.0, max_feed_mm_min=3500.0,
                                  base_feed_mm_min=1000.0, exponent=1.0, n_bins=20),
    )  # fmt: skip
    out = tmp_path / "report"
    out.mkdir()
    sec = feed_rule_section(
        SimpleNamespace(spec=spec, name="sweep"),
        [SimpleNamespace(path=p, group="sweep") for p in runs],
        out,
    )
    first = sec.markdown.splitlines()[0]
    assert first.startswith("Base feed 1000 mm/min: between 1000 and 1200 mm/min the")
    assert first.lower().count("base feed") == 1
    assert sec.summary["base_feed_mm_min"] == 1000 and (out / "derived.toml").exists()


def test_commands_other_than_add_refuse_a_missing_rule_base(tmp_path, capsys) -> None:
    db, key = _rule_base(tmp_path)
    typo = tmp_path / "rulbase.sqlite"
    for argv in (
        ["rules", "list"],
        ["rules", "show", "gm241"],
        ["rules", "lookup", *key],
        ["rules", "export", "gm241", "-o", str(tmp_path / "x.toml")],
    ):
        capsys.readouterr()
        assert main([*argv, "--db", str(typo)]) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err == (
            f"cutlab: error: {typo}: no rule base here (no such file); `cutlab rules add` "
            "creates it"
        )
        assert not typo.exists()
    assert main(["rules", "list", "--db", db, "--json"]) == 0
    assert [g["rule"] for g in json.loads(capsys.readouterr().out)] == ["gm241"]


def test_add_onto_an_existing_group_names_replace_option(tmp_path, capsys) -> None:
    db, key = _rule_base(tmp_path)
    other = save_rule(derive_rule("gm241-b", 100, 800, 3500, 0.1329), tmp_path / "b.toml")
    capsys.readouterr()
    assert main(["rules", "add", str(other), *key, "--db", db]) == 2
    err = capsys.readouterr().err
    assert "group 1 has this key already; add --replace to replace its rule" in err
    assert "use replace" not in err and len(err.strip().splitlines()) == 1
    assert main(["rules", "add", str(other), *key, "--db", db, "--replace"]) == 0
    assert "as group 1 in" in capsys.readouterr().out
    assert main(["rules", "show", "gm241-b", "--db", db, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["base_feed_mm_min"] == 800


def test_lookup_exact_names_the_fields_that_differ(tmp_path, capsys) -> None:
    db, key = _rule_base(tmp_path)
    other = save_rule(derive_rule("gm241-50", 100, 800, 3500, 0.1329), tmp_path / "b.toml")
    key50 = list(key)
    key50[key50.index("--tool-diameter") + 1] = "50"
    assert main(["rules", "add", str(other), *key50, "--db", db]) == 0
    key32 = list(key)
    key32[key32.index("--tool-diameter") + 1] = "32"
    capsys.readouterr()
    assert main(["rules", "lookup", *key32, "--exact", "--db", db]) == 2
    err = capsys.readouterr().err
    assert (
        "no rule for tool_diameter_mm = 32 (the base has 30, 50) among the 2 roughing/gm241" in err
    )
    assert "nearest: group 1 (gm241) with tool_diameter_mm = 30" in err
    assert "the base has (operation, material)" not in err
    assert main(["rules", "lookup", *key, "--exact", "--db", db]) == 0
    assert "exact match: group 1 (gm241)" in capsys.readouterr().out


def test_a_derived_rule_records_the_tool_of_its_runs_and_plan_feed_warns_on_another(
    tmp_path, capsys
) -> None:
    runs = _write_runs(tmp_path)
    out = tmp_path / "r.toml"
    assert main(["rules", "derive", *map(str, runs), "-o", str(out)]) == 0
    rule = load_rule(out)
    assert rule.tool == "phi30-ball"
    # Old rule files without a tool still load (the tool is then unknown).
    old = out.read_text().replace('tool = "phi30-ball"\n', "")
    (tmp_path / "old.toml").write_text(old)
    assert load_rule(tmp_path / "old.toml").tool == ""
    prog = tmp_path / "slot.nc"
    prog.write_text("G21 G90 G17\nG0 X-20 Y30 Z5\nG1 Z-0.3 F1000\nG1 X120\nG0 Z50\nM30\n")
    for tool, warned in (("phi30-ball", False), ("phi10-flat", True)):
        capsys.readouterr()
        rc = main(["plan", "feed", str(prog), "--rules", str(out), "--tool", tool, "--stock",
                   "box:0,100,0,60,-10,0", "--spacing", "1",
                   "-o", str(tmp_path / f"{tool}.nc")])  # fmt: skip
        err = capsys.readouterr().err
        assert rc == 0, err
        assert ("derived with tool 'phi30-ball', not 'phi10-flat'" in err) == warned
