"""The smaller faults of issue 31, each through the command a lab would use:

* a resume refused after a change to the tool or material of ``--tools`` / ``--materials`` names
  that file (it named the shipped configs/tools.toml);
* ``data import`` of an export with an ``inf`` sample is refused naming file, line, column, value;
* a NaN in an error message reads ``nan`` (it read ``np.float64(nan)``);
* ``--conditions fz_mm=nan`` is refused (it was stored as the text "nan");
* a query of 8000 ``or`` terms is refused in one line (it ended in RecursionError);
* a campaign matrix of 4 million runs is refused in one line, its ``--dry-run`` at once;
* ``analyze forces`` on an interrupted (killed) attempt names the file and says so.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.faults
ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).parent / "data"
CUTLAB = [sys.executable, "-m", "rig.cli"]


def cutlab(*args: object, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([*CUTLAB, *map(str, args)], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)  # fmt: skip


def one_error_line(proc: subprocess.CompletedProcess) -> str:
    """The refusal: exit 2, one ``cutlab: error:`` line, no traceback."""
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cutlab: error: "), proc.stderr
    return lines[0]


# ------------------------------------------------------------ --tools / --materials on a resume


def _user_catalogues(tmp_path: Path) -> tuple[Path, Path, Path]:
    """The quick campaign with its tool and material in the lab's own catalogues."""
    tools = (ROOT / "configs" / "tools.toml").read_text()
    start = tools.index("[tools.seed003-facemill]")
    block = tools[start : tools.index("\n\n", start)]
    my_tools = tmp_path / "my_tools.toml"
    my_tools.write_text(block.replace("seed003-facemill", "lab-facemill") + "\n")
    mats = (ROOT / "configs" / "materials.toml").read_text()
    start = mats.index("[materials.al6061-t6]")
    block = mats[start : mats.index("\n\n", mats.index("[materials.al6061-t6.endmill]"))]
    my_mats = tmp_path / "my_materials.toml"
    my_mats.write_text(block.replace("al6061-t6", "lab-al") + "\n")
    text = (DATA / "campaign" / "quick.toml").read_text()
    text = text.replace('"OUT"', json.dumps(str(tmp_path / "out"))).replace("FAULTS", "")
    text = text.replace('"seed003-facemill"', '"lab-facemill"').replace('"al6061-t6"', '"lab-al"')
    cfg = tmp_path / "quick.toml"
    cfg.write_text(text)
    return cfg, my_tools, my_mats


def test_a_changed_user_catalogue_is_named_on_resume(tmp_path: Path):
    from analysis.config import user_catalogs
    from rig.campaign import load_campaign, run_campaign

    cfg, my_tools, my_mats = _user_catalogues(tmp_path)
    with user_catalogs(my_tools, my_mats):  # what --tools / --materials do around a command
        first = run_campaign(load_campaign(cfg), progress=False,
                             only=lambda t: t.index == 0)  # fmt: skip
    assert [r.status for r in first.runs] == ["success"]
    my_tools.write_text(my_tools.read_text().replace("nose_radius_mm = 0.4",
                                                     "nose_radius_mm = 0.8"))  # fmt: skip
    my_mats.write_text(my_mats.read_text().replace("K_R = 1.1", "K_R = 1.2"))
    from analysis import config
    from analysis.errors import CutlabError

    config._tool_library.cache_clear()  # a new command reads the files anew
    config._material_library.cache_clear()
    with pytest.raises(CutlabError) as refused, user_catalogs(my_tools, my_mats):
        run_campaign(load_campaign(cfg), progress=False)
    msg = str(refused.value)  # (the CLI prints it as one line, exit 2: test_campaign_resume)
    assert f"tool changed: {my_tools} [tools.lab-facemill]: sha256" in msg
    assert f"material changed: {my_mats} [materials.lab-al]: sha256" in msg
    assert "configs/tools.toml" not in msg and "configs/materials.toml" not in msg, msg


# ------------------------------------------------------------------ exports: inf and NaN samples


def _export(tmp_path: Path, line_25: str) -> tuple[Path, Path]:
    """The shipped DynoWare example with line 25 (a sample) replaced, and its conditions row."""
    src = (ROOT / "data" / "dynoware" / "cut_300.txt").read_text().splitlines(keepends=True)
    assert src[24].startswith("0,001500\t")
    src[24] = line_25 + "\n"
    export = tmp_path / "cut_bad.txt"
    export.write_text("".join(src))
    rows = (ROOT / "data" / "dynoware" / "conditions.csv").read_text().splitlines()
    table = tmp_path / "conditions.csv"
    table.write_text(rows[0] + "\n" + rows[1].replace("cut_300,", "cut_bad,") + "\n")
    return export, table


def test_data_import_refuses_an_inf_sample(tmp_path: Path):
    export, table = _export(tmp_path, "0,001500\t1,5\tinf\t-13,866939")
    out = tmp_path / "runs"
    proc = cutlab("data", "import", export, "--conditions", table, "--axes", "x=-Fy,y=Fx,z=-Fz",
                  "--tools", ROOT / "data" / "dynoware" / "my_tools.toml", "-o", out)  # fmt: skip
    line = one_error_line(proc)
    assert line == f"cutlab: error: {export}:25: column Fy = inf: not a finite number"
    assert not out.exists() or not list(out.iterdir())  # nothing written


@pytest.mark.parametrize(
    ("cell", "shown", "why"),
    [
        ("-inf", "-inf", "not a finite number"),
        ("+Infinity", "+Infinity", "not a finite number"),
        ("nan", "nan", "not a number"),
        ("NaN", "NaN", "not a number"),
        ("", "(empty)", "not a number"),
    ],
)
def test_a_bad_sample_is_named_as_written(tmp_path: Path, cell: str, shown: str, why: str):
    from analysis.errors import AnalysisError
    from analysis.runs import read_force_table

    export, _ = _export(tmp_path, f"0,001500\t{cell}\t-182,962515\t-13,866939")
    with pytest.raises(AnalysisError) as e:
        read_force_table(export)
    assert str(e.value) == f"{export}:25: column Fx = {shown}: {why}"
    # a blank line among the samples (pandas skips it) does not shift the line named
    text = export.read_text().replace("0,001400\t", "\n0,001400\t")
    export.write_text(text)
    with pytest.raises(AnalysisError, match=f":26: column Fx = {re.escape(shown)}: "):
        read_force_table(export)


def test_data_info_of_a_nan_sample_says_nan(tmp_path: Path):
    export, _ = _export(tmp_path, "0,001500\tnan\t-182,962515\t-13,866939")
    line = one_error_line(cutlab("data", "info", export))
    assert line == f"cutlab: error: {export}:25: column Fx = nan: not a number"


def test_numpy_values_read_plain_in_messages():
    import numpy as np

    from analysis.config import Material
    from analysis.errors import AnalysisError, ConfigError
    from analysis.identify.conditions import resolve_conditions
    from analysis.validation import validate

    with pytest.raises(ConfigError) as e:
        validate(Material, {"density_kg_m3": np.float64("nan")}, "m.toml")
    assert str(e.value).startswith("m.toml: density_kg_m3 = nan: ") and "np." not in str(e.value)
    given = {"spindle_rpm": np.float64(6000), "fz_mm": 0.1, "depth_mm": np.int64(3),
             "width_mm": 25, "teeth": np.float64("nan")}  # fmt: skip
    with pytest.raises(AnalysisError) as e:
        resolve_conditions([("run.h5 (conditions)", given)], lambda tool: 2, "lab-phi25-2f")
    assert "teeth = nan but tool 'lab-phi25-2f' has 2 teeth" in str(e.value)
    assert "np." not in str(e.value)


# ---------------------------------------------------------------------- --conditions KEY=nan


@pytest.mark.parametrize(
    ("given", "said"),
    [
        (["fz_mm=nan"], "--conditions 'fz_mm=nan': fz_mm = nan: not a finite number"),
        (["spindle_rpm=600", "depth_mm=-inf"], "depth_mm = -inf: not a finite number"),
        (["fz_mm=Infinity"], "fz_mm = inf: not a finite number"),
        (['{"fz_mm": NaN}'], "--conditions: fz_mm = nan: not a finite number"),
    ],
)
def test_non_finite_conditions_are_refused(given: list[str], said: str):
    from analysis.errors import ConfigError
    from rig.cli._common import parse_conditions

    with pytest.raises(ConfigError) as e:
        parse_conditions(given)
    assert said in str(e.value)
    assert parse_conditions(["fz_mm=0.1", "tool=nano"]) == {"fz_mm": 0.1, "tool": "nano"}


def test_daq_record_refuses_fz_nan(tmp_path: Path):
    out = tmp_path / "rec.h5"
    proc = cutlab("daq", "record", "--sim", "--seconds", "0.2", "-o", out, "--quiet",
                  "--conditions", "spindle_rpm=600", "fz_mm=nan")  # fmt: skip
    line = one_error_line(proc)
    assert line == ("cutlab: error: --conditions 'fz_mm=nan': fz_mm = nan: not a finite number "
                    "(a condition is a number or a name)")  # fmt: skip
    assert not out.exists()
