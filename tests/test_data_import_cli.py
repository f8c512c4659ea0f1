"""`cutlab data import` and `cutlab analyze forces` on DynoWare exports, as scripts call them:

    cutlab analyze forces FILE... --model endmill --tool NAME --tools MYTOOLS.toml \\
        --conditions CONDITIONS.csv --axes x=-Fy,y=Fx,z=-Fz --json
    cutlab data import FILE... --conditions CONDITIONS.csv --axes ... -o DIR

Exports from tests/_dynoware_files.py (forces from Altintas' model, written independently of
cutlab's code); the run files written by the import must give the same coefficients as the
exports, and `data info` / `data plot` read both.
"""

from __future__ import annotations

import json

import pytest
from _dynoware_files import TOOL, TOOLS_TOML, TRUTH, conditions_csv, write_slot_exports

from rig.cli import main

AXES = "x=-Fy,y=Fx,z=-Fz"


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """Exports without conditions in their header (a table gives them), decimal commas, air
    before and after; the lab's tool catalogue and conditions table beside them."""
    d = tmp_path_factory.mktemp("exports")
    tools = d / "my_tools.toml"
    tools.write_text(TOOLS_TOML)
    files = write_slot_exports(d, AXES, header=False, decimal=",", cut_s=0.6)
    table = conditions_csv(d / "conditions.csv", files, extra="mode=slot")
    return {"dir": d, "tools": tools, "files": [str(f) for f in files], "table": str(table)}


def _forces(args, capsys):
    rc = main(["analyze", "forces", *args, "--json"])
    cap = capsys.readouterr()
    return rc, json.loads(cap.out), cap.err


def test_contract_command_on_exports(lab, capsys):
    rc, out, _ = _forces([*lab["files"], "--model", "endmill", "--tool", TOOL, "--tools",
                          str(lab["tools"]), "--conditions", lab["table"], "--axes", AXES],
                         capsys)  # fmt: skip
    assert rc == 0 and out["success"], out["message"]
    for k, v in TRUTH.items():
        assert out["coefficients"][k] == pytest.approx(v, rel=0.01, abs=0.3), k
    assert out["coefficients"]["Ktc_n_mm2"] == out["coefficients"]["Ktc"]
    assert out["axes"] == AXES and out["warnings"] == []
    assert [r["axes"] for r in out["per_run"]] == [AXES] * 4
    # The text result names the mapping too.
    rc = main(["analyze", "forces", *lab["files"], "--tool", TOOL, "--tools",
               str(lab["tools"]), "--conditions", lab["table"], "--axes", AXES])  # fmt: skip
    assert rc == 0 and f"axes: {AXES} (x feed" in capsys.readouterr().out


def test_import_then_every_command_on_the_run_files(lab, tmp_path, capsys):
    runs = tmp_path / "runs"
    rc = main(["data", "import", *lab["files"], "--conditions", lab["table"], "--axes", AXES,
               "--tools", str(lab["tools"]), "-o", str(runs), "--json"])  # fmt: skip
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    written = json.loads(cap.out)["written"]
    assert [w["axes"] for w in written] == [AXES] * 4 and {w["zero"] for w in written} == {"air"}
    assert f"axes {AXES}; offset: air" in cap.err
    h5 = sorted(str(p) for p in runs.glob("*.h5"))
    assert len(h5) == 4

    assert main(["data", "info", h5[0], "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["status"] == "success" and info["channels"] == ["Fx", "Fy", "Fz"]
    assert info["conditions"]["tool"] == TOOL and info["conditions"]["mode"] == "slot"
    assert main(["data", "plot", h5[0], "-o", str(tmp_path / "run.png")]) == 0
    assert (tmp_path / "run.png").stat().st_size > 1000
    capsys.readouterr()

    # Run files hold cutlab's frame and their conditions: no --axes, no table.
    rc, from_runs, _ = _forces([*h5, "--tool", TOOL, "--tools", str(lab["tools"])], capsys)
    export_args = ["--tools", str(lab["tools"]), "--conditions", lab["table"], "--axes", AXES]
    rc2, from_exports, _ = _forces([*lab["files"], "--tool", TOOL, *export_args], capsys)
    assert rc == rc2 == 0
    for k in TRUTH:
        assert from_runs["coefficients"][k] == pytest.approx(from_exports["coefficients"][k],
                                                             rel=1e-3, abs=1e-3), k  # fmt: skip
    assert from_runs["axes"] == "x=Fx,y=Fy,z=Fz" and from_runs["warnings"] == []

    # An existing run file is not replaced without --force.
    rc = main(["data", "import", lab["files"][0], "--conditions", lab["table"], "--axes", AXES,
               "--tools", str(lab["tools"]), "-o", str(runs)])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "cut_300.h5: file exists (--force replaces it)" in err


def test_info_and_plot_read_exports(lab, tmp_path, capsys):
    assert main(["data", "info", lab["files"][0], "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["format"] == "export" and info["columns"] == ["Time", "Fx", "Fy", "Fz"]
    assert info["rate_hz"] == 10_000 and info["decimal"] == "," and info["samples"] == 12_000
    assert main(["data", "info", lab["files"][0]]) == 0
    assert "Fx [N]" in capsys.readouterr().out
    png = tmp_path / "export.png"
    assert main(["data", "plot", lab["files"][0], "-o", str(png)]) == 0
    assert png.stat().st_size > 1000


def test_steady_only_exports_are_zeroed_and_say_so(tmp_path, capsys):
    (tmp_path / "t.toml").write_text(TOOLS_TOML)
    files = write_slot_exports(tmp_path, AXES, air_s=0.0, cut_s=0.5, offset_n=(0.0, 0.0, 0.0))
    rc, out, err = _forces([*map(str, files), "--tool", TOOL, "--tools",
                            str(tmp_path / "t.toml"), "--axes", AXES], capsys)  # fmt: skip
    assert rc == 0 and out["success"], out["message"]
    assert out["coefficients"]["Ktc"] == pytest.approx(TRUTH["Ktc"], rel=0.01)
    assert len(out["warnings"]) == 4 and "no air in the record: taken as zeroed" in err
    assert {r["zero"] for r in out["per_run"]} == {out["warnings"][0].split(": ", 1)[1]}


def test_wrong_axes_warn_on_stderr_and_in_json(lab, capsys):
    rc = main(["analyze", "forces", *lab["files"], "--tool", TOOL, "--tools", str(lab["tools"]),
               "--conditions", lab["table"], "--json"])  # fmt: skip
    cap = capsys.readouterr()
    out, err = cap.out or None, cap.err
    # refused (issue 27): exit 2, one line naming the mapping that fits
    assert rc == 2 and out is None and len(err.strip().splitlines()) == 1
    assert "axes x=Fx,y=Fy,z=Fz give a negative cutting coefficient (Krc" in err
    assert "give --axes" in err and "Validation" not in err


@pytest.mark.parametrize(
    ("table", "expect"),
    [
        ("file,spindle_rpm,feed_mm_min,ap_mm,ae_mm,flute\n{rows}", "unknown condition 'flute'"),
        ("file,spindle_rpm,feed_mm_min,ap_mm,ae_mm,teeth\n{rows}",
         "teeth = 3 but tool 'lab-phi25-2f' has 2 teeth"),
        ("file,spindle_rpm,feed_mm_min,ap_mm,ae_mm\nother,6000,300,3,25\n",
         "no row for cut_300.txt (field file"),
    ],
)  # fmt: skip
def test_bad_tables_are_one_line_naming_file_and_field(lab, tmp_path, capsys, table, expect):
    rows = "".join(f"cut_{f},6000,{f},3,25,3\n" for f in (300, 600, 1000, 1500))
    p = tmp_path / "bad.csv"
    p.write_text(table.format(rows=rows))
    for cmd in (["analyze", "forces", *lab["files"], "--tool", TOOL],
                ["data", "import", *lab["files"], "-o", str(tmp_path / "o"), "--tool", TOOL]):
        rc = main([*cmd, "--tools", str(lab["tools"]), "--conditions", str(p), "--axes", AXES])
        err = capsys.readouterr().err
        assert rc == 2 and "Traceback" not in err, err
        line = err.strip().splitlines()[-1]
        assert line.startswith("cutlab: error: ") and "bad.csv" in line and expect in line
    assert not (tmp_path / "o").exists()


def test_the_catalogue_keeps_what_the_conditions_table_said(lab, tmp_path, capsys):
    """The table gives feed_mm_min (not fz) and no mode; the cuts are as wide as the cutter:
    the catalogue's row keeps the feed the table gave, the teeth and the mode "slot" (imported
    runs were catalogued with feed_mm_min NaN and a full slot as "down")."""
    table = tmp_path / "conditions.csv"
    rows = [r for r in (lab["dir"] / "conditions.csv").read_text().splitlines() if r]
    head = rows[0].split(",")
    keep = [i for i, k in enumerate(head) if k != "mode"]
    table.write_text("\n".join(",".join(r.split(",")[i] for i in keep) for r in rows) + "\n")
    runs = tmp_path / "runs"
    assert main(["data", "import", *lab["files"], "--conditions", str(table), "--axes", AXES,
                 "--tools", str(lab["tools"]), "-o", str(runs)]) == 0  # fmt: skip
    assert main(["catalog", "index", str(runs)]) == 0
    capsys.readouterr()
    assert main(["catalog", "query", "spindle_rpm > 0", "--index", str(runs), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    rows_out = got["rows"] if isinstance(got, dict) else got
    stated = {r.split(",")[0]: r.split(",") for r in rows[1:]}
    assert len(rows_out) == 4
    for r in rows_out:
        src = stated[r["run"]]
        feed = float(src[head.index("feed_mm_min")]) if "feed_mm_min" in head else None
        if feed is not None:
            assert r["feed_mm_min"] == pytest.approx(feed)
        assert r["feed_mm_min"] == r["feed_mm_min"]  # not NaN
        assert r["mode"] == "slot"
