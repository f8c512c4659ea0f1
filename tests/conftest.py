"""Hypothesis profiles, and the default run in parallel.

The default run draws the same examples every time (``derandomize``), so
a clean clone's test run is reproducible; ``--hypothesis-profile=explore`` draws new ones each
run, as the slow fuzzing tier does, to look for what the fixed examples miss."""

from pathlib import Path

import pytest
from hypothesis import settings

from tests import _mypy_background

settings.register_profile("fixed", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile("fixed")  # pytest's --hypothesis-profile, read later, overrides this


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook, which reads these options
def pytest_cmdline_main(config: pytest.Config) -> None:
    """Run in parallel by default when pytest-xdist (the `test` extra) is installed: one worker per
    core and one more (with one core, in this process), each test file on one worker (``--dist
    loadfile``: a module's fixtures are built once, and test_readme_commands.py's commands, which
    build on each other in one scratch folder, stay in order). Set here, not in addopts, so ``-p
    no:xdist`` still works; an explicit ``-n`` (``-n 0``: in this process) or ``--dist`` wins."""
    if not config.pluginmanager.hasplugin("xdist") or hasattr(config, "workerinput"):
        return  # no xdist, or a worker (whose options xdist has reset)
    missing = [a for a in config.args if not Path(a.split("::")[0]).exists()]
    if missing:  # xdist's workers would drop this error and say only "no tests ran" (exit 5)
        raise pytest.UsageError(f"file or directory not found: {missing[0]}")
    if config.option.numprocesses is not None or config.option.collectonly:
        return
    if config.getoption("usepdb", False):
        return
    cores = config.hook.pytest_xdist_auto_num_workers(config=config)
    if cores < 2:
        return  # one core: in this process, as without xdist
    # One more worker than cores: the workers spend about a third of their time waiting on the
    # simulated controllers' real-time pacing (serial lines, feed holds, timeouts). On 2 cores
    # the quick tier took 3 min 54 s with 2 workers and 3 min 14 s with 3, the same CPU.
    config.option.numprocesses = cores + 1
    if config.option.dist == "no":
        config.option.dist = "loadfile"


def pytest_configure(config: pytest.Config) -> None:
    _mypy_background.clear(config)


def pytest_collection_finish(session: pytest.Session) -> None:
    _mypy_background.start_if_selected(session)


def pytest_sessionfinish(session: pytest.Session) -> None:
    _mypy_background.finish(session)
