"""The type check of tests/test_types.py, started in the background as soon as the test is
collected, so that its minute of CPU on a cold cache fills the time other tests spend waiting on
simulated controllers' real-time pacing instead of holding a worker: one process per test run
(the first xdist worker to claim it), at a lower priority than the tests, its output and exit code
left in a folder every worker of the run finds by the pid of the run's main process."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TEST_ID = "tests/test_types.py::test_mypy_strict_on_analysis_and_planning_and_rig_within_ceilings"
COMMAND = [sys.executable, "-m", "mypy", "--config-file", "pyproject.toml", "--cache-dir",
           ".mypy_cache", "--no-color-output", "--no-error-summary"]  # fmt: skip
NICE = 10  # below the tests: it takes the CPU they leave idle
_started: list[subprocess.Popen[bytes]] = []


def _folder(config: pytest.Config) -> Path:
    """The run's folder: named by the main pytest process (an xdist worker's parent)."""
    main_pid = os.getppid() if hasattr(config, "workerinput") else os.getpid()
    return Path(tempfile.gettempdir()) / f"cutlab-mypy-{main_pid}"


def clear(config: pytest.Config) -> None:
    """At the start, in the run's main process: a folder left by a killed run whose main process
    had this pid is not this run's answer."""
    if not hasattr(config, "workerinput"):
        shutil.rmtree(_folder(config), ignore_errors=True)


def start_if_selected(session: pytest.Session) -> None:
    """Start mypy once per run when the type-check test is among this session's items."""
    if not any(item.nodeid == TEST_ID for item in session.items):
        return
    folder = _folder(session.config)
    folder.mkdir(exist_ok=True)
    try:  # the first worker to create the claim starts it; the others find its output
        os.close(os.open(folder / "claim", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return
    out = open(folder / "output", "wb")  # noqa: SIM115 - closed by the thread when mypy ends
    proc = subprocess.Popen(COMMAND, cwd=ROOT, stdout=out, stderr=subprocess.STDOUT,
                            preexec_fn=lambda: os.nice(NICE))  # fmt: skip
    _started.append(proc)

    def _record_exit() -> None:
        code = proc.wait()
        out.close()
        (folder / "exit.tmp").write_text(str(code))
        (folder / "exit.tmp").replace(folder / "exit")  # whole or absent for the reader

    threading.Thread(target=_record_exit, daemon=True).start()


def result(config: pytest.Config, deadline_s: float) -> tuple[int, str]:
    """mypy's exit code and output: the background run's, or a run of its own here if none was
    started (the test called some other way)."""
    folder = _folder(config)
    if not (folder / "claim").exists():
        proc = subprocess.run(COMMAND, cwd=ROOT, capture_output=True, text=True,
                              timeout=deadline_s)  # fmt: skip
        return proc.returncode, proc.stdout + proc.stderr
    end = time.monotonic() + deadline_s
    while not (folder / "exit").exists():
        if time.monotonic() > end:
            pytest.fail(f"mypy gave no answer within {deadline_s:.0f} s")
        time.sleep(0.2)
    return int((folder / "exit").read_text()), (folder / "output").read_text()


def finish(session: pytest.Session) -> None:
    """At a session's end. The worker that started mypy waits for it (another worker's test may
    still be reading it) unless the run is stopping early (-x, --maxfail): then it stops it. The
    main process, after every worker, removes the folder."""
    for proc in _started:
        if session.shouldstop or session.shouldfail:
            proc.kill()
        try:
            proc.wait(timeout=900)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
    clear(session.config)
