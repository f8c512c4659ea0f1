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


@pytest.mark.long
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
    from analysis.identify.conditions_arg import parse_conditions

    with pytest.raises(ConfigError) as e:
        parse_conditions(given)
    assert said in str(e.value)
    assert parse_conditions(["fz_mm=0.1", "tool=nano"]) == {"fz_mm": 0.1, "tool": "nano"}


@pytest.mark.long
def test_daq_record_refuses_fz_nan(tmp_path: Path):
    out = tmp_path / "rec.h5"
    proc = cutlab("daq", "record", "--sim", "--seconds", "0.2", "-o", out, "--quiet",
                  "--conditions", "spindle_rpm=600", "fz_mm=nan")  # fmt: skip
    line = one_error_line(proc)
    assert line == ("cutlab: error: --conditions 'fz_mm=nan': fz_mm = nan: not a finite number "
                    "(a condition is a number or a name)")  # fmt: skip
    assert not out.exists()


# ------------------------------------------------------------------- catalogue: queries, dask


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """The catalogue tests' archive (face-milling runs that identify), indexed."""
    from test_catalog import _make_archive

    from analysis.catalog import update_index

    root = tmp_path_factory.mktemp("lab")
    _make_archive(root)
    update_index([root])
    return root


def _main(argv: list[str], capsys) -> tuple[int, str, str]:
    from rig.cli import main

    rc = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def _one_line(rc: int, err: str) -> str:
    assert rc == 2 and "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cutlab: error: "), err
    return lines[0]


def test_a_query_of_8000_terms_is_one_line(lab, capsys):
    from analysis.catalog.query import MAX_QUERY_TERMS

    expr = " or ".join(["fz_mm == 0.1"] * 8000)
    rc, _, err = _main(["catalog", "query", expr, "--index", lab], capsys)
    line = _one_line(rc, err)
    assert f"has 8000 terms (comparisons); at most {MAX_QUERY_TERMS}" in line
    assert len(line) < 300  # the query is cut in the message
    for expr, said in ((" | ".join(["(fz_mm == 0.1)"] * 500), "has 500 terms"),
                       ("not " * 5000 + "fz_mm == 0.1", "nested too deeply"),
                       ("~" * 300 + "(fz_mm == 0.1)", "nests 304 levels deep")):  # fmt: skip
        rc, _, err = _main(["analyze", "forces", "--catalog", lab, "--where", expr], capsys)
        assert said in _one_line(rc, err)
    # as many terms as allowed still run (pandas' own recursion is the limit beyond)
    expr = " or ".join([f"fz_mm == {0.1 + k / 1000:g}" for k in range(MAX_QUERY_TERMS - 1)])
    rc, out, err = _main(["catalog", "query", expr + " or group == 'v'", "--index", lab], capsys)
    assert rc == 0 and "004-v" in out, err


@pytest.fixture(scope="module")
def tcp_scheduler():
    """A real dask scheduler and worker on 127.0.0.1 (an ephemeral port), in this process."""
    import logging

    from distributed import LocalCluster

    logging.getLogger("distributed").setLevel(logging.ERROR)
    where = dict(protocol="tcp", host="127.0.0.1", scheduler_port=0, dashboard_address=None)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, **where) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        yield cluster.scheduler_address


FM_WHERE = "campaign == 'fm' and group == 'g'"


@pytest.mark.long
def test_analyze_on_a_tcp_scheduler_with_and_without_json(lab, tcp_scheduler, capsys):
    import shutil

    shutil.rmtree(lab / ".cutlab-catalog.cache", ignore_errors=True)
    argv = ["analyze", "forces", "--catalog", lab, "--where", FM_WHERE, "--scheduler",
            tcp_scheduler]  # fmt: skip
    rc, out, err = _main(argv, capsys)  # (was ValueError: No clients found, a traceback)
    assert rc == 0 and "Traceback" not in err, err
    assert "100% Completed" in err and "3 reduced" in err  # distributed's bar, on stderr
    assert "facemill fit of 3 run(s)" in out
    rc, out, err = _main([*argv, "--json"], capsys)  # the fit is cached now
    assert rc == 0 and json.loads(out)["catalog"]["fit_cached"], err
    assert json.loads(out)["catalog"]["scheduler"] == tcp_scheduler
    shutil.rmtree(lab / ".cutlab-catalog.cache")
    rc, out, err = _main([*argv, "--json"], capsys)
    assert rc == 0 and json.loads(out)["catalog"]["reduced"] == 3, err


def _closed_port() -> int:
    import socket

    with socket.socket() as s:  # bound and closed: nothing listens there
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("json_out", [False, True])
def test_an_unreachable_scheduler_is_one_line_even_when_cached(lab, capsys, json_out):
    from analysis.catalog import fit_catalog

    fit_catalog(lab, FM_WHERE, scheduler="sync")  # the fit is cached
    address = f"tcp://127.0.0.1:{_closed_port()}"
    argv = ["analyze", "forces", "--catalog", lab, "--where", FM_WHERE, "--scheduler", address]
    rc, out, err = _main(argv + ["--json"] * json_out, capsys)
    line = _one_line(rc, err)
    assert line.startswith(f"cutlab: error: --scheduler {address}: cannot reach the dask "
                           "scheduler within 4 s (ConnectionRefusedError")  # fmt: skip
    assert out == ""


def test_a_port_that_is_no_dask_scheduler_is_an_error(lab, capsys):
    """A port that accepts and never answers (a wrong --scheduler): distributed's Client waits
    for its answer for ever; cutlab says so within its deadline, the fit cached or not."""
    import socket

    from analysis.catalog import CONNECT_TIMEOUT_S, fit_catalog

    fit_catalog(lab, FM_WHERE, scheduler="sync")
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(4)
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        argv = ["analyze", "forces", "--catalog", lab, "--where", FM_WHERE, "--scheduler",
                address, "--json"]  # fmt: skip
        rc, out, err = _main(argv, capsys)
    line = _one_line(rc, err)
    assert f"no dask scheduler answered in {CONNECT_TIMEOUT_S:g} s" in line and out == ""


# --------------------------------------------------------------------- campaign matrix size


def _matrix_campaign(tmp_path: Path, n_fz: int, n_depth: int) -> Path:
    text = (DATA / "campaign" / "quick.toml").read_text()
    text = text.replace('"OUT"', json.dumps(str(tmp_path / "out"))).replace("FAULTS", "")
    fz = ", ".join(f"{0.1 + k * 1e-4:.4f}" for k in range(n_fz))
    depth = ", ".join(f"{0.5 + k * 1e-3:.3f}" for k in range(n_depth))
    text = text.replace("fz_mm = 0.3", f"fz_mm = [{fz}]")
    text = text.replace("depth_mm = [1.0, 2.0]", f"depth_mm = [{depth}]")
    cfg = tmp_path / f"m{n_fz}x{n_depth}.toml"
    cfg.write_text(text)
    return cfg


@pytest.mark.long
def test_a_matrix_of_4_million_runs_is_one_line_at_once(tmp_path: Path):
    cfg = _matrix_campaign(tmp_path, 2000, 2000)
    line = one_error_line(cutlab("campaign", "run", cfg, "--dry-run"))
    assert line == (f"cutlab: error: {cfg}:30: matrix[0] makes 4000000 runs (2000 fz_mm x 2000 "
                    "depth_mm), the campaign 4000000; at most 10000 runs in a campaign (split "
                    "it)")  # fmt: skip
    assert not (tmp_path / "out").exists()


@pytest.mark.long
def test_the_matrix_cap_counts_every_table(tmp_path: Path):
    from analysis.errors import ConfigError
    from rig.campaign import load_campaign
    from rig.campaign.config import MAX_CAMPAIGN_RUNS

    assert len(load_campaign(_matrix_campaign(tmp_path, 100, 100)).tests) == MAX_CAMPAIGN_RUNS
    cfg = _matrix_campaign(tmp_path, 100, 100)
    cfg.write_text(cfg.read_text() + '\n[[tests]]\ngroup = "g"\nspindle_rpm = 1200\n'
                   "fz_mm = 0.3\ndepth_mm = 1.0\n")  # fmt: skip
    with pytest.raises(ConfigError, match=r"the campaign 10001; at most 10000 runs"):
        load_campaign(cfg)


# ---------------------------------------------------------------- analyze a killed attempt

_KILLED_WRITER = """
import os, signal, sys
sys.path.insert(0, {tests!r})
from test_catalog import _info
from analysis.config import load_rig
from rig.daq import Calibration
from rig.log import RunWriter

rig = load_rig()
info = _info(rig)
w = RunWriter({path!r}, info, Calibration.from_rig(rig), clock=lambda: 0.0)
w.on_start(info, 0.0)
w.set_rig({{"rig": "sim", "machine": "ace-h63"}})
w.flush() if hasattr(w, "flush") else None
os.kill(os.getpid(), signal.SIGKILL)  # as a campaign killed before the run's conditions
"""


@pytest.mark.long
def test_analyze_forces_on_a_killed_attempt_names_it(tmp_path: Path, capsys):
    path = tmp_path / "001-g-n001.attempt-1.h5"
    script = _KILLED_WRITER.format(tests=str(Path(__file__).parent), path=str(path))
    proc = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)  # fmt: skip
    assert proc.returncode == -9 and path.exists(), proc.stderr
    rc, out, err = _main(["analyze", "forces", path], capsys)
    line = _one_line(rc, err)  # (was "<conditions>: missing condition 'spindle_rpm'")
    assert line.startswith(f"cutlab: error: {path}: an interrupted attempt (status interrupted: "
                           "the writer was killed or crashed; 0 samples per channel kept): "
                           "missing condition 'spindle_rpm'")  # fmt: skip
