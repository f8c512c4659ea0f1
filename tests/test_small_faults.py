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
