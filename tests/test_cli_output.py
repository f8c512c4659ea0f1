"""CLI output (issue 32, item 4): wide tables fold, the dry run lists one problem per line,
catalog query shows the path and takes the archive folder, progress lines on a non-terminal
stderr, the dask dashboard with the console extra."""

from __future__ import annotations

import io
import subprocess
import sys
import time
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import pytest

from analysis.output import TABLE_CELL_MAX
from rig.cli.common import print_table
from rig.terminal import Heartbeat, progress_note

ROOT = Path(__file__).resolve().parents[1]


def _table(rows: list[dict], **kw: object) -> list[str]:
    out = io.StringIO()
    with redirect_stdout(out):
        print_table(rows, **kw)  # type: ignore[arg-type]
    return out.getvalue().splitlines()


def test_a_long_cell_is_folded_not_padded_into_every_row() -> None:
    conditions = {f"condition_{k}": k * 0.25 for k in range(60)}  # ~1,200 characters as text
    lines = _table([{"quantity": "status", "value": "success"},
                    {"quantity": "conditions", "value": conditions}])  # fmt: skip
    assert max(len(ln) for ln in lines) <= len("conditions") + 2 + TABLE_CELL_MAX
    assert lines[1].split() == ["status", "success"]
    folded = "".join(ln[len("conditions") + 2 :].strip() + " " for ln in lines[2:])
    # every key=value is there, in order, across the continuation lines
    assert " ".join(folded.split()) == ", ".join(f"{k}={v:g}" for k, v in conditions.items())


def test_a_short_table_is_unchanged() -> None:
    assert _table([{"a": 1.0, "bb": "x"}, {"a": 2.5, "bb": "yy"}]) == [
        "a    bb",
        "1    x ",
        "2.5  yy",
    ]


def _run(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)  # fmt: skip


@pytest.mark.faults
def test_dry_run_prints_one_problem_per_line(tmp_path: Path) -> None:
    src = (ROOT / "configs/campaigns/feed-sweep.toml").read_text()
    bad = src.replace("[campaign]", "[campaign]\nbogus_one = 1\nbogus_two = 2", 1)
    assert bad != src
    cfg = tmp_path / "bad.toml"
    cfg.write_text(bad)
    p = _run("campaign", "run", str(cfg), "--dry-run")
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    lines = [ln for ln in p.stderr.splitlines() if ": working, " not in ln]  # progress lines
    assert all(ln.startswith("cutlab: error: ") for ln in lines), lines
    assert (
        sum("bogus_one" in ln for ln in lines) == 1 and sum("bogus_two" in ln for ln in lines) == 1
    )
    assert not any("bogus_one" in ln and "bogus_two" in ln for ln in lines)


def test_heartbeat_prints_on_a_non_terminal_stderr_and_stops() -> None:
    err = io.StringIO()  # not a terminal
    with redirect_stderr(err):
        hb = Heartbeat("cutlab test")
        hb.interval_s = 0.2
        with hb:
            time.sleep(0.6)
            assert err.getvalue() == ""  # nothing before the work starts (input checks)
            progress_note(lambda: "3 of 8 runs ended")
            deadline = time.monotonic() + 20
            while "working" not in err.getvalue() and time.monotonic() < deadline:
                time.sleep(0.05)
        n = err.getvalue().count("\n")
        time.sleep(0.5)
    assert "cutlab test: working," in err.getvalue() and "[3 of 8 runs ended]" in err.getvalue()
    assert err.getvalue().count("\n") == n  # nothing after close
    assert not hb._thread.is_alive()  # type: ignore[union-attr]


def test_heartbeat_is_silent_when_quiet() -> None:
    hb = Heartbeat("x", quiet=True)
    assert hb._thread is None
    hb.close()


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two copies of a small archive (one recorded run each) under one folder, indexed."""
    root = tmp_path_factory.mktemp("archive")
    for copy in ("copy-a", "copy-b"):
        (root / copy).mkdir()
        p = _run("daq", "record", "--sim", "--seconds", "0.2", "--speed", "0", "-o",
                 str(root / copy / "run.h5"), "--conditions", "tool=phi10-flat")  # fmt: skip
        assert p.returncode == 0, p.stderr
    p = _run("catalog", "index", str(root))
    assert p.returncode == 0, p.stderr
    return root


@pytest.mark.long
def test_catalog_query_takes_the_archive_folder_and_shows_the_path(
    archive: Path, tmp_path: Path
) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    p = _run("catalog", "query", "tool == 'phi10-flat'", cwd=elsewhere)
    assert p.returncode == 2 and "no run catalogue" in p.stderr  # the contract without DIR
    for args in ((str(archive),), ("--index", str(archive)), (str(archive), "--index",
                                                              str(archive))):  # fmt: skip
        p = _run("catalog", "query", "tool == 'phi10-flat'", *args, cwd=elsewhere)
        assert p.returncode == 0, p.stderr
        header, *rows = p.stdout.splitlines()
        assert "path" in header.split()
        assert len(rows) == 2 and "copy-a/run.h5" in rows[0] and "copy-b/run.h5" in rows[1]
    p = _run("catalog", "show", "copy-a/run.h5", str(archive), cwd=elsewhere)
    assert p.returncode == 0 and "copy-a/run.h5" in p.stdout, p.stderr
    p = _run("catalog", "query", "", str(archive), "--index", str(elsewhere), cwd=elsewhere)
    assert p.returncode == 2 and "name two catalogues" in p.stderr


def test_the_dask_dashboard_answers_with_the_console_extra() -> None:
    pytest.importorskip("bokeh", reason="the console extra (bokeh) is not installed")
    import urllib.request

    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                           dashboard_address="127.0.0.1:0")  # fmt: skip
    with cluster, Client(cluster) as client:
        port = cluster.scheduler.http_server.port
        assert "bokeh" in client.dashboard_link or port
        url = f"http://127.0.0.1:{port}/status"
        with urllib.request.urlopen(url, timeout=30) as r:
            assert r.status == 200 and b"bokeh" in r.read().lower()
