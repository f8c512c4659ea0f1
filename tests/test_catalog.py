"""The run catalogue: index, queries, identification over a query on dask (local and a
LocalCluster), the reduction cache, and a worker killed mid-run."""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import sqlite3
import sys
import time
from dataclasses import asdict
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from analysis.catalog import (
    INDEX_NAME,
    CachedMapper,
    check_query,
    fit_catalog,
    load_index,
    query_runs,
    show_run,
    update_index,
)
from analysis.config import FaceMill, FaceMillCoefficients, load_rig
from analysis.errors import AnalysisError
from analysis.identify import RunConditions, fit_files
from analysis.identify.facemill import synthetic_facemill_run
from analysis.modal import DynamometerFilter
from analysis.runs import SAMPLE_FORMAT_VOLTS
from rig.cli import main
from rig.daq import Calibration, DaqInfo
from rig.log import RunWriter

RATE = 10_000.0
TOOL = FaceMill(kind="facemill", diameter_mm=125, inserts=1, lead_angle_deg=15,
                axial_rake_deg=7, radial_rake_deg=0, nose_radius_mm=0.4)  # fmt: skip
TRUE = FaceMillCoefficients(
    K_T_n_mm2=405.4, K_R=1.1, P_T_n_mm=39.7, P_R_n_mm=19.6, K_A=0.35, P_A_n_mm=8.0
)
#: The face-milling runs: (name, group, fz_mm, depth_mm), and the runs of another campaign.
FM_RUNS = [("001-d0.5", "g", 0.236, 0.5), ("002-d1.5", "g", 0.236, 1.5),
           ("003-d3.0", "g", 0.236, 3.0), ("004-v", "v", 0.345, 2.0)]  # fmt: skip
BALL_RUNS = [("001-f400", 0.1, 0.5), ("002-f1000", 0.25, 0.5), ("003-f2200", 0.55, 0.5)]


def _info(rig, rate=RATE):
    return DaqInfo(
        device="Sim1", physical_channels=("ai0", "ai1", "ai2"),
        channel_names=tuple(c.name for c in rig.dynamometer.channels), rate_hz=rate,
        sample_format=SAMPLE_FORMAT_VOLTS, input_range_v=10.0, block_samples=4096,
    )  # fmt: skip


def write_run(path: Path, force_n: np.ndarray, conditions: dict, rig, close=True) -> RunWriter:
    cal = Calibration.from_rig(rig)
    info = _info(rig)
    volts = cal.volts_from_force(force_n)
    w = RunWriter(path, info, cal, clock=lambda: 0.0, overwrite=True)
    w.on_start(info, 0.0)
    w.set_conditions(conditions)
    w.set_rig({"rig": "sim", "machine": "ace-h63"})
    for a in range(0, len(volts), 4096):
        w.put_block(a, volts[a : a + 4096].T.copy())
    if close:
        w.close()
    return w


def _make_archive(root: Path) -> dict[str, int]:
    """Two campaigns: face-milling runs that identify, and short ball-end-mill runs to query.
    Returns each file's number of samples per channel."""
    rig = load_rig()
    modes = DynamometerFilter.from_config(rig.dynamometer, RATE, crosstalk=False)
    rng = np.random.default_rng(7)
    samples = {}
    fm = root / "fm-campaign"
    (fm / "runs").mkdir(parents=True)
    (fm / "campaign.json").write_text(json.dumps({"campaign": "fm", "runs": {}}))
    for name, group, fz, d in FM_RUNS:
        c = RunConditions(spindle_rpm=600, fz_mm=fz, depth_mm=d, width_mm=100.0)
        run = synthetic_facemill_run(name, TOOL, TRUE, c, RATE, cut_s=1.5, dynamometer=modes,
                                     rng=rng, offset_n=(3, -2, 1), phase_rad=d)  # fmt: skip
        cond = {**asdict(c), "feed_mm_min": fz * 600, "tool": "seed003-facemill", "teeth": 1,
                "material": "al6061-t6", "group": group}  # fmt: skip
        # The campaign name only in the manifest (as an older cutlab wrote it).
        write_run(fm / "runs" / f"{name}.h5", run.force_n, cond, rig)
        samples[name] = len(run.force_n)
    ball = root / "sweep"
    ball.mkdir()
    for name, fz, d in BALL_RUNS:
        n = int(0.3 * RATE)
        f = rng.normal(size=(n, 3))
        cond = {"campaign": "sweep", "group": "sweep", "tool": "phi30-ball", "material": "GM241",
                "spindle_rpm": 2000.0, "feed_mm_min": fz * 2000 * 2, "teeth": 2,
                "depth_mm": d, "width_mm": 30.0}  # fmt: skip
        write_run(ball / f"{name}.h5", f, cond, rig)
        samples[name] = n
    return samples


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    root = tmp_path_factory.mktemp("archive")
    samples = _make_archive(root)
    return root, samples


@pytest.fixture
def indexed(archive, tmp_path):
    """A fresh copy of the archive, indexed (tests change it)."""
    root = tmp_path / "lab"
    shutil.copytree(archive[0], root)
    update_index([root])
    return root


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def test_index_holds_each_runs_metadata(indexed, archive):
    df = load_index(indexed)
    assert len(df) == len(FM_RUNS) + len(BALL_RUNS)
    assert (indexed / INDEX_NAME).is_file()
    fm = df[df["campaign"] == "fm"].set_index("run")
    assert sorted(fm.index) == [r[0] for r in FM_RUNS]  # the campaign from campaign.json
    for name, group, fz, d in FM_RUNS:
        r = fm.loc[name]
        assert (r["group"], r["status"], r["tool"], r["material"]) == (
            group, "success", "seed003-facemill", "al6061-t6")  # fmt: skip
        assert (r["fz_mm"], r["depth_mm"], r["spindle_rpm"]) == (fz, d, 600.0)
        assert r["samples_stored"] == archive[1][name] and r["samples_lost"] == 0
        assert r["sha256"] == _sha(Path(r["file"]))
        assert r["current"] == 1 and r["rig"] == "sim"
    ball = df[df["campaign"] == "sweep"].set_index("run")
    # feed_mm_min recorded, fz_mm from it: feed / (rpm x teeth)
    assert ball.loc["002-f1000", "fz_mm"] == pytest.approx(0.25)
    assert json.loads(ball.loc["002-f1000", "events"])["start"] >= 1


def test_reindex_reads_only_new_and_changed_files_and_drops_deleted_ones(indexed, monkeypatch):
    import analysis.catalog.index as ix

    reads = []
    real = ix.read_row
    monkeypatch.setattr(ix, "read_row", lambda p, *a: reads.append(p.name) or real(p, *a))
    out = update_index([indexed])
    assert (out["unchanged"], out["added"], out["updated"], out["removed"]) == (7, 0, 0, 0)
    assert reads == []
    rig = load_rig()
    (indexed / "sweep" / "001-f400.h5").unlink()
    changed = indexed / "sweep" / "002-f1000.h5"
    write_run(changed, np.ones((500, 3)), {"campaign": "sweep", "tool": "phi30-ball",
                                           "material": "GM241", "fz_mm": 0.3}, rig)  # fmt: skip
    os.utime(changed, ns=(time.time_ns(), time.time_ns() + 10**9))  # a later mtime for sure
    write_run(indexed / "sweep" / "004-new.h5", np.ones((400, 3)), {"campaign": "sweep"}, rig)
    out = update_index([indexed])
    assert (out["unchanged"], out["added"], out["updated"], out["removed"]) == (5, 1, 1, 1)
    assert sorted(reads) == ["002-f1000.h5", "004-new.h5"]
    df = load_index(indexed).set_index("run")
    assert "001-f400" not in df.index
    assert df.loc["002-f1000", "samples_stored"] == 500
    assert df.loc["002-f1000", "sha256"] == _sha(changed)


def test_a_run_being_written_is_indexed_as_running_then_as_closed(indexed):
    rig = load_rig()
    path = indexed / "sweep" / "005-live.h5"
    w = write_run(path, np.ones((8192, 3)), {"campaign": "sweep", "tool": "phi30-ball"}, rig,
                  close=False)  # fmt: skip
    try:
        w.wait_idle()
        update_index([indexed])
        row = show_run("sweep/005-live", indexed)
        assert row["status"] == "running" and row["sha256"] is None
        assert query_runs("status == 'running'", indexed)["run"].tolist() == ["005-live"]
    finally:
        w.close()
    out = update_index([indexed])
    assert out["updated"] == 1  # a running row is read again, changed or not
    row = show_run("005-live", indexed)
    assert row["status"] == "success" and row["sha256"] == _sha(path)


def test_query_selects_like_pandas_and_refuses_code(indexed):
    df = load_index(indexed)
    got = query_runs("material == 'GM241' and 0.2 <= fz_mm <= 0.6", indexed)
    assert sorted(got["run"]) == ["002-f1000", "003-f2200"]
    want = df[(df["campaign"] == "fm") & (df["group"].isin(["g"])) & (df["depth_mm"] > 1)]
    got = query_runs("campaign == 'fm' and group in ['g'] and not depth_mm <= 1", indexed)
    assert sorted(got["run"]) == sorted(want["run"]) == ["002-d1.5", "003-d3.0"]
    assert len(query_runs("", indexed)) == len(df)
    assert len(query_runs("(tool == 'phi30-ball') | (fz_mm > 0.3) & ~(depth_mm < 0)",
                          indexed)) == 4  # fmt: skip
    for expr, why in [
        ("@os", "not an expression"),
        ("__import__('os').system('true')", "not allowed"),
        ("run.str.len() > 3", "not allowed"),
        ("campaign.__class__ == 1", "not allowed"),
        ("fz_mm + 1 > 0", "not allowed"),
        ("[c for c in run]", "not allowed"),
        ("lambda: 1", "not allowed"),
        ("speed > 3", "unknown column 'speed'"),
        ("fz_mm >", "not an expression"),
    ]:
        with pytest.raises(AnalysisError, match=why) as exc:
            check_query(expr, df.columns)
        assert "\n" not in str(exc.value)


QUERIES = [
    "material == 'GM241' and 0.2 <= fz_mm <= 0.6", "0.6 >= fz_mm > 0.2", "-1 < depth_mm",
    "campaign == 'fm' and group in ['g', 'x'] and not depth_mm <= 1", "width_mm != 20",
    "group != 'g' and fz_mm >= 0", "not (tool == 'phi30-ball')", "tool not in ['phi30-ball']",
    "(tool == 'phi30-ball') | (fz_mm > 0.3) & ~(depth_mm < 0)", "fz_mm < depth_mm",
    "status == 'success' and current == True", "samples_lost == 0 and rate_hz in [10000, 1e4]",
    "group in [] or run >= '002'", "tool == 5", "spindle_rpm == 'fast' or fz_mm > 0",
    "fz_mm > 0.3 and fz_mm < 0.2", "depth_mm >= +0.5 and campaign in ('fm',)",
]


@pytest.mark.parametrize("expr", QUERIES)
def test_a_query_selects_what_pandas_selects_from_the_whole_index(indexed, expr):
    """SQLite reads only rows that can match (sql_prefilter); the rows returned are those pandas'
    own DataFrame.query picks from the whole index, missing values and mixed types included
    (three rows with NULLs are added to the index)."""
    with sqlite3.connect(indexed / ".cutlab-catalog.sqlite") as con:
        cols = [r[1] for r in con.execute("PRAGMA table_info(runs)")]
        row = list(con.execute("SELECT * FROM runs").fetchone())
        for k, nulls in enumerate((("fz_mm", "width_mm"), ("group", "tool"), ("depth_mm",))):
            r = [None if c in nulls else v for c, v in zip(cols, row)]
            r[cols.index("path")] = f"nulls-{k}.h5"
            con.execute(f"INSERT INTO runs VALUES ({', '.join('?' * len(r))})", r)
    df = load_index(indexed)
    try:
        want = df.query(expr, engine="python", local_dict={}, global_dict={})
    except Exception:  # noqa: BLE001 - pandas refuses it: so must the query, in one line
        with pytest.raises(AnalysisError):
            query_runs(expr, indexed)
        return
    got = query_runs(expr, indexed)
    assert sorted(got["path"]) == sorted(want["path"]), expr


def test_show_names_a_run_by_name_campaign_and_path(indexed):
    r = show_run("fm/003-d3.0", indexed)
    assert r["depth_mm"] == 3.0 and r["conditions"]["group"] == "g"
    assert show_run(r["file"], indexed)["run"] == "003-d3.0"
    with pytest.raises(AnalysisError, match="not in the catalogue"):
        show_run("nope", indexed)


def test_cli_index_query_show(indexed, tmp_path, capsys, monkeypatch):
    assert main(["catalog", "index", str(indexed), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["files"] == 7 and out["unchanged"] == 7 and out["statuses"] == {"success": 7}
    monkeypatch.chdir(indexed / "sweep")  # the index of a parent folder is found
    assert main(["catalog", "query", "material == 'GM241'", "--csv"]) == 0
    df = pd.read_csv(pd.io.common.StringIO(capsys.readouterr().out))
    for col in ("campaign", "run", "group", "status", "tool", "material", "spindle_rpm",
                "feed_mm_min", "fz_mm", "depth_mm"):  # fmt: skip
        assert col in df.columns
    assert len(df) == 3
    assert main(["catalog", "query", "depth_mm > 2", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["run"] for r in rows] == ["003-d3.0"] and rows[0]["conditions"]["depth_mm"] == 3.0
    assert main(["catalog", "show", "004-v"]) == 0
    assert "0.345" in capsys.readouterr().out
    # another index file for several folders
    other = tmp_path / "elsewhere.sqlite"
    assert main(["catalog", "index", str(indexed / "sweep"), str(indexed / "fm-campaign"),
                 "--index", str(other), "--json"]) == 0  # fmt: skip
    assert json.loads(capsys.readouterr().out)["added"] == 7
    assert main(["catalog", "query", "group == 'v'", "--index", str(other)]) == 0
    assert "004-v" in capsys.readouterr().out


@pytest.mark.parametrize("argv, msg", [
    (["catalog", "query", "fz_mm.max() > 1"], "not allowed"),
    (["catalog", "query", "x == 1"], "unknown column 'x'"),
    (["catalog", "show", "nope"], "not in the catalogue"),
    (["catalog", "index", "/nonexistent-folder"], "not a folder"),
    (["analyze", "forces", "--catalog", ".", "--where", "fz_mm > 9", "--json"], "no run"),
    (["analyze", "forces", "--where", "fz_mm > 9"], "--where needs --catalog"),
    (["analyze", "forces"], "give run files, or --catalog"),
    (["analyze", "forces", "--catalog", ".", "--scheduler", "nonsense"], "tcp://HOST:PORT"),
    (["analyze", "forces", "x.h5", "--catalog", "."], "give one or the other"),
])  # fmt: skip
def test_cli_bad_input_is_one_line(indexed, monkeypatch, capsys, argv, msg):
    monkeypatch.chdir(indexed)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("cutlab: error:") and msg in err and "\n" not in err


def test_no_catalogue_is_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["catalog", "query", ""]) == 2
    assert "no run catalogue" in capsys.readouterr().err
    (tmp_path / "x.sqlite").write_text("not a database")
    assert main(["catalog", "query", "", "--index", str(tmp_path / "x.sqlite")]) == 2
    assert "not a readable run catalogue" in capsys.readouterr().err


def _coefficients(argv, capsys):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


FM_WHERE = "campaign == 'fm' and group == 'g'"


@pytest.mark.long
def test_analyze_over_a_query_matches_the_files_and_caches(indexed, capsys, monkeypatch):
    files = sorted(str(p) for p in (indexed / "fm-campaign" / "runs").glob("00[123]*.h5"))
    want = _coefficients(["analyze", "forces", *files, "--json"], capsys)
    assert want["success"]
    argv = ["analyze", "forces", "--catalog", str(indexed), "--where", FM_WHERE, "--json"]
    got = _coefficients(argv, capsys)
    assert got["coefficients"] == want["coefficients"]
    assert got["runs"] == want["runs"]
    assert got["catalog"]["reduced"] == 3 and got["catalog"]["cached"] == 0
    # The second query over overlapping runs opens no run file: all from the cache.
    opened = []
    real = h5py.File
    monkeypatch.setattr(h5py, "File", lambda *a, **k: opened.append(a[0]) or real(*a, **k))
    argv[5] = "campaign == 'fm' and fz_mm < 0.3"
    again = _coefficients(argv, capsys)
    assert again["catalog"]["cached"] == 3 and again["catalog"]["reduced"] == 0
    assert opened == []
    assert again["coefficients"] == want["coefficients"]
    # A changed file is refused until it is indexed again.
    os.utime(files[0], ns=(time.time_ns(), time.time_ns() + 10**9))
    with pytest.raises(AnalysisError, match="changed since it was indexed"):
        fit_catalog(indexed, FM_WHERE)


@pytest.mark.long
def test_the_same_query_again_returns_the_stored_fit(indexed, tmp_path, monkeypatch):
    """The fit's result is kept with everything it depends on: asked again over unchanged files
    it is returned as it was; without it the reductions alone are reused; a config file whose
    content changed, or plots to write, make it fit again."""
    configs = tmp_path / "configs"
    shutil.copytree(Path(__file__).parent.parent / "configs", configs)
    monkeypatch.setenv("CUTLAB_CONFIG_DIR", str(configs))
    first = fit_catalog(indexed, FM_WHERE)
    assert not first["catalog"]["fit_cached"] and first["catalog"]["reduced"] == 3
    again = fit_catalog(indexed, FM_WHERE)
    assert again["catalog"]["fit_cached"] and again["catalog"]["reduced"] == 0
    np.testing.assert_equal({k: v for k, v in again.items() if k != "catalog"},
                            {k: v for k, v in first.items() if k != "catalog"})  # fmt: skip
    cache = indexed / ".cutlab-catalog.cache"
    for entry in cache.glob("fit-*.pkl"):
        entry.unlink()
    refit = fit_catalog(indexed, FM_WHERE)
    assert not refit["catalog"]["fit_cached"] and refit["catalog"]["cached"] == 3
    assert refit["coefficients"] == first["coefficients"]
    with (configs / "materials.toml").open("a") as fh:
        fh.write("\n# an edit\n")
    assert not fit_catalog(indexed, FM_WHERE)["catalog"]["fit_cached"]
    plots = fit_catalog(indexed, FM_WHERE, plot_dir=tmp_path / "plots")
    assert not plots["catalog"]["fit_cached"] and plots["plots"]


@pytest.mark.long
def test_progress_is_dasks_bar_on_stderr(indexed, capsys):
    assert main(["analyze", "forces", "--catalog", str(indexed), "--where", FM_WHERE]) == 0
    cap = capsys.readouterr()
    assert "Completed" in cap.err and "[" in cap.err
    assert "facemill fit of 3 run(s)" in cap.out


@pytest.fixture(scope="module")
def quiet_dask():
    logging.getLogger("distributed").setLevel(logging.ERROR)


@pytest.mark.long
def test_local_cluster_gives_the_local_result(indexed, quiet_dask):
    import dask
    from distributed import LocalCluster

    local = fit_catalog(indexed, FM_WHERE, scheduler="sync")
    shutil.rmtree(indexed / ".cutlab-catalog.cache")
    with LocalCluster(n_workers=3, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster:  # fmt: skip
        out = fit_catalog(indexed, FM_WHERE, scheduler=cluster.scheduler_address)
        shutil.rmtree(indexed / ".cutlab-catalog.cache")
        with dask.config.set({"scheduler-address": cluster.scheduler_address}):
            by_config = fit_catalog(indexed, FM_WHERE)  # the dask config names the cluster
    for res in (out, by_config):
        assert res["catalog"]["reduced"] == 3
        assert res["coefficients"] == local["coefficients"]
        np.testing.assert_equal(res["per_run"], local["per_run"])


class KillOnce:
    """A reducer wrapper whose first call (any run) kills the worker process running it."""

    def __init__(self, reducer, marker: str) -> None:
        self.reducer, self.marker = reducer, marker

    def __call__(self, path):
        if not os.path.exists(self.marker):
            Path(self.marker).touch()
            os._exit(1)  # the worker dies mid-task, no cleanup
        return self.reducer(path)


@pytest.mark.long
def test_a_worker_killed_mid_run_is_retried_with_the_same_result(indexed, tmp_path, quiet_dask):
    import cloudpickle
    from distributed import LocalCluster

    me = sys.modules[__name__]  # the workers unpickle KillOnce by value

    rows = query_runs(FM_WHERE, indexed)
    files = list(rows["file"])
    local = fit_files(files)
    marker = tmp_path / "killed"
    cloudpickle.register_pickle_by_value(me)
    try:
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster:  # fmt: skip
            inner = CachedMapper(tmp_path / "cache", {}, cluster.scheduler_address)
            out = fit_files(files, mapper=lambda red, paths: inner(KillOnce(red, str(marker)),
                                                                    paths))  # fmt: skip
    finally:
        cloudpickle.unregister_pickle_by_value(me)
    assert marker.exists()  # a worker did die
    assert out["coefficients"] == local["coefficients"]
    np.testing.assert_equal(out["per_run"], local["per_run"])


@pytest.mark.long
def test_a_simulated_campaign_is_indexed_with_its_names_and_attempts(tmp_path):
    from rig.campaign import load_campaign, run_campaign

    data = Path(__file__).parent / "data" / "campaign"
    text = (data / "quick.toml").read_text().replace('"OUT"', json.dumps(str(tmp_path / "out")))
    (tmp_path / "q.toml").write_text(text.replace("FAULTS", ""))
    res = run_campaign(load_campaign(tmp_path / "q.toml"), progress=False)
    assert res.ok
    runs = Path(res.folder) / "runs"
    first = sorted(runs.glob("*.h5"))[0]
    shutil.copy(first, runs / f"{first.stem}.attempt-1.h5")  # as a resume keeps an attempt
    (Path(res.folder) / "before-20240101T000000Z" / "runs").mkdir(parents=True)
    shutil.copy(first, Path(res.folder) / "before-20240101T000000Z" / "runs" / first.name)
    out = update_index([tmp_path / "out"])
    assert out["added"] == 4 and out["statuses"] == {"success": 4}
    df = query_runs("campaign == 'quick' and current == 1", tmp_path / "out")
    # quick.toml: group g, 1200 rpm, 0.3 mm/tooth, depths 1 and 2 mm, one insert
    assert df["group"].tolist() == ["g", "g"] and df["depth_mm"].tolist() == [1.0, 2.0]
    assert (df["spindle_rpm"] == 1200).all() and (df["fz_mm"] == 0.3).all()
    assert (df["feed_mm_min"] == 0.3 * 1200).all() and (df["tool"] == "seed003-facemill").all()
    assert len(query_runs("current == 0", tmp_path / "out")) == 2


def test_a_query_reads_the_index_while_an_indexer_writes(indexed):
    import sqlite3

    con = sqlite3.connect(indexed / INDEX_NAME)
    try:
        con.execute("BEGIN IMMEDIATE")
        con.execute("DELETE FROM runs")  # not committed: readers still see every row
        assert len(load_index(indexed)) == 7
    finally:
        con.rollback()
        con.close()


@pytest.mark.long
def test_the_cache_key_is_the_same_in_every_process(tmp_path):
    """A later command (another process, another hash seed) finds the cached reductions."""
    import subprocess

    table = tmp_path / "t.csv"
    table.write_text("file,spindle_rpm,fz_mm,depth_mm,width_mm\na.h5,600,0.2,1,100\n")
    code = (
        "from analysis.catalog.compute import reduction_key\n"
        "from analysis.config import load_rig\n"
        "from analysis.identify.reading import FileReducer, ImportOptions\n"
        f"o = ImportOptions(axes='x=-Fy,y=Fx,z=Fz', table={str(table)!r}).loaded()\n"
        "r = FileReducer({'depth_mm': 2.0, 'mode': 'slot'}, load_rig().dynamometer, None,\n"
        "                'seed003-facemill', '--tool', 0.02, o)\n"
        "print(reduction_key(r))\n"
    )
    keys = {
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                       env={**os.environ, "PYTHONHASHSEED": seed}).stdout  # fmt: skip
        for seed in ("1", "2")
    }
    assert len(keys) == 1 and len(keys.pop().strip()) == 24
