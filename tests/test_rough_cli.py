"""`cutlab plan rough`: JSON, the written program, pictures, and errors as one line."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from test_rough_parts import bump_grid, part_toml, write_toml

from planning.nc import interpret
from rig.cli import main


@pytest.fixture()
def small_part(tmp_path):
    x, y, z = bump_grid(40, 45, 18, 26, 30)
    return write_toml(tmp_path, part_toml(x, y, z, top=43.0, tool="phi10-flat"))


@pytest.mark.long
def test_json_program_and_pictures(small_part, tmp_path, capsys):
    out = tmp_path / "out" / "rough.nc"
    code = main(["plan", "rough", str(small_part), "-o", str(out), "--json",
                 "--check-spacing", "1.0"])  # fmt: skip
    res = json.loads(capsys.readouterr().out)
    assert code == 0
    assert res["method"] == "bisection" and set(res["totals"]) == {
        "bisection", "equal", "lee", "optimal"
    }  # fmt: skip
    t = res["totals"]
    assert t["optimal"]["cutting_path_mm"] <= t["bisection"]["cutting_path_mm"] + 1e-6
    assert [lv["order"] for lv in res["levels"]] == list(range(1, len(res["levels"]) + 1))
    row = res["levels"][0]
    assert row["mrr_mm3_min"] == pytest.approx(
        row["area_mm2"] * 300.0 * row["height_mm"] / row["path_mm"], rel=1e-3
    )
    assert res["check"]["ok"] and res["check"]["max_left_mm"] <= 5.05
    motion = interpret(out.read_text())  # planning.nc reads what we wrote
    assert len(motion) > 10 and np.nanmax(motion.spindle_rpm) == 1000.0
    for key in ("levels", "paths", "roughed"):
        png = res["png"][key]
        assert open(png, "rb").read(8) == b"\x89PNG\r\n\x1a\n"


# long: a second whole plan (optimal); `plan rough` is run quick by the JSON test above and the
# optimal method checked quick in tests/test_rough.py (optimal equals brute force)
@pytest.mark.long
def test_table_output_and_other_method(small_part, tmp_path, capsys):
    out = tmp_path / "o.nc"
    code = main(["plan", "rough", str(small_part), "-o", str(out), "--method", "optimal",
                 "--no-png", "--no-check"])  # fmt: skip
    text = capsys.readouterr().out
    assert code == 0
    assert "optimal levels" in text and "totals by method" in text
    assert "bisection_shorter_than_equal_pct" in text
    assert out.read_text().startswith("%")


def test_bad_config_is_one_line_and_exit_2(tmp_path, capsys):
    x, y, z = bump_grid(40, 45, 18, 26, 30)
    bad = write_toml(tmp_path, part_toml(x, y, z, top=43.0, cusp_mm=-1.0), "bad.toml")
    code = main(["plan", "rough", str(bad), "-o", str(tmp_path / "x.nc")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("cutlab: error: ") and "rough.cusp_mm = -1.0" in err
    assert "Traceback" not in err


@pytest.mark.long
def test_the_program_for_each_controller_dialect(small_part, tmp_path, capsys):
    texts = {}
    for dialect in ("fanuc", "linuxcnc", "grbl"):
        out = tmp_path / f"{dialect}.nc"
        code = main(["plan", "rough", str(small_part), "-o", str(out), "--json", "--no-png",
                     "--no-check", "--dialect", dialect])  # fmt: skip
        res = json.loads(capsys.readouterr().out)
        assert code == 0 and res["dialect"] == dialect
        texts[dialect] = out.read_text()
    fanuc, lcnc, grbl = (texts[d].splitlines() for d in ("fanuc", "linuxcnc", "grbl"))
    assert fanuc[0] == "%" and fanuc[1].startswith("O0001 (cutlab plan rough")
    assert lcnc[0] == lcnc[-1] == "%" and lcnc[-2] == "M30"
    assert not any(ln.startswith("O") for ln in lcnc + grbl)
    assert all(len(ln) <= 80 for ln in grbl) and "%" not in grbl
    assert not any(re.search(r"M0?6\b|G4[123]\b|G8[1-9]\b|G9[89]\b", ln) for ln in grbl)
    assert grbl[0].startswith("(cutlab plan rough")  # the title comment, wrapped to fit
    ref = interpret(texts["fanuc"])
    for dialect in ("linuxcnc", "grbl"):
        m = interpret(texts[dialect], dialect=dialect)
        assert len(m) == len(ref)
        np.testing.assert_allclose(m.end, ref.end, atol=1e-6, rtol=0)
        np.testing.assert_allclose(m.feed_mm_min, ref.feed_mm_min, rtol=1e-12)
    # the default is the machine's dialect
    out = tmp_path / "lab.nc"
    code = main(["plan", "rough", str(small_part), "-o", str(out), "--json", "--no-png",
                 "--no-check", "--machine", "lab-grbl"])  # fmt: skip
    assert code == 0 and json.loads(capsys.readouterr().out)["dialect"] == "grbl"
    assert out.read_text() == texts["grbl"]
