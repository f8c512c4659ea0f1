"""Small valid inputs for every ``cutlab`` command, made once per test session, and the argv of
each command on them (``RECIPES``). Shared by the strict-JSON test, the fault matrix and the
fuzzing of command arguments; a recipe is the command's valid call from which each of those
tests varies one thing.
"""

from __future__ import annotations

import argparse
import functools
import json
import shutil
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from rig.cli import build_parser, main

ROOT = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent
PROGRAM = ROOT / "data" / "programs" / "demo-part.nc"
#: a 100 mm slot with a phi 30 ball: what the sweep's rule was derived for
SLOT = "G21 G90 G17\nS2000 M3\nG0 X-20 Y30 Z5\nG1 Z-0.3 F1000\nG1 X120\nG0 Z50\nM30\n"


@functools.cache
def _parser() -> argparse.ArgumentParser:
    """The whole parser, built once: a build takes ~40 ms (argparse's help strings through
    gettext), and the fault matrix and fuzzing read a leaf's actions ~500 times, never change it."""
    return build_parser()


def commands() -> list[tuple[str, ...]]:
    """Every leaf command of the parser, e.g. ``("plan", "feed")``."""
    out: list[tuple[str, ...]] = []

    def walk(parser: argparse.ArgumentParser, prefix: tuple[str, ...]) -> None:
        for a in parser._actions:
            if isinstance(a, argparse._SubParsersAction):
                for name, sp in a.choices.items():
                    walk(sp, (*prefix, name))
                return
        out.append(prefix)

    walk(_parser(), ())
    return out


def leaf_parser(cmd: tuple[str, ...]) -> argparse.ArgumentParser:
    p = _parser()
    for name in cmd:
        sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
        p = sub.choices[name]
    return p


def has_json(cmd: tuple[str, ...]) -> bool:
    return any("--json" in a.option_strings for a in leaf_parser(cmd)._actions)


def hammer_csv(path: Path) -> Path:
    """Four hits in x on the dynamometer's three modes (seed 003 Table 2), with noise."""
    from analysis.modal import DynamometerFilter

    fs = 51_200.0
    filt = DynamometerFilter.from_table(fs, [2050, 1810, 3230], [0.02742, 0.0872, 0.10178])
    n = int(fs * 0.5)
    t = np.arange(n) / fs
    ham = np.zeros(n)
    for t0 in (0.02, 0.12, 0.22, 0.32):
        m = (t >= t0) & (t < t0 + 0.00015)
        ham[m] = 100 * np.sin(np.pi * (t[m] - t0) / 0.00015)
    f = np.zeros((n, 3))
    f[:, 0] = ham
    y = filt.apply(f) + np.random.default_rng(0).normal(0, 0.05, (n, 3))
    np.savetxt(path, np.column_stack([t, ham, y]), delimiter=",", fmt="%.7g",
               header="time_s,hammer,Fx,Fy,Fz", comments="")  # fmt: skip
    return path


@dataclass
class Inputs:
    root: Path
    quick: Path  # a two-run face-milling campaign on the simulated rig (already run)
    runs: list[Path]  # its run files
    sweep: list[Path]  # a feed sweep's run files
    rule: Path  # the rule derived from them
    db: Path  # a rule base holding it as "gm241"
    hammer: Path
    part: Path
    orient: Path
    slot: Path

    def out(self, name: str) -> Path:
        """A fresh output path under the session folder."""
        p = self.root / "outs" / f"{time.monotonic_ns()}-{name}"
        p.parent.mkdir(parents=True, exist_ok=True)
        return p


RULE_KEY = ["--part-family", "test/sweep", "--operation", "slotting", "--tool-diameter", "30",
            "--flute-length", "30", "--material", "gm241", "--spindle", "2000", "--depth", "0.3",
            "--tolerance", "0.05"]  # fmt: skip


def _quiet_main(argv: list[str]) -> None:
    import contextlib
    import io

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        rc = main(argv)
    assert rc == 0, argv


@pytest.fixture(scope="session")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    from test_orient_cli import FAN, small
    from test_rough_parts import bump_grid, part_toml, write_toml
    from test_rules_cli import _write_runs

    root = tmp_path_factory.mktemp("cli-inputs")
    text = (TESTS / "data" / "campaign" / "quick.toml").read_text()
    quick = root / "quick.toml"
    quick.write_text(text.replace('"OUT"', json.dumps(str(root / "campaigns"))).replace(
        "FAULTS", ""))  # fmt: skip
    _quiet_main(["campaign", "run", str(quick), "--quiet", "--no-report"])
    runs = sorted((root / "campaigns" / "quick" / "runs").glob("*.h5"))
    (root / "sweep").mkdir()
    sweep = _write_runs(root / "sweep")
    rule, db = root / "gm241.toml", root / "rb.sqlite"
    _quiet_main(["rules", "derive", *map(str, sweep), "-o", str(rule)])
    _quiet_main(["rules", "add", str(rule), *RULE_KEY, "--db", str(db)])
    x, y, z = bump_grid(40, 45, 18, 26, 30)
    (root / "part").mkdir()
    part = write_toml(root / "part", part_toml(x, y, z, top=43.0, tool="phi10-flat"))
    orient = root / "fan.toml"
    orient.write_text(small(FAN.read_text(), "[0.5]", 4))
    slot = root / "slot.nc"
    slot.write_text(SLOT)
    return Inputs(root, quick, runs, sweep, rule, db, hammer_csv(root / "hammer.csv"), part,
                  orient, slot)  # fmt: skip


def recipe(cmd: tuple[str, ...], i: Inputs) -> list[str] | None:
    """A valid call of ``cmd`` on small inputs (None: needs a controller, see :func:`with_port`)."""
    o = i.out
    # the phi 30 ball on the 100 mm slot: plan feed and plan simulate
    slot_ball = [str(i.slot), "--tool", "phi30-ball", "--stock", "box:0,100,0,60,-10,0",
                 "--spacing", "1"]  # fmt: skip
    r = {
        ("demo",): ["--campaign", str(i.quick), "--out", str(o("demo")), "--quiet"],
        ("nc", "check"): [str(PROGRAM)],
        ("nc", "motions"): [str(PROGRAM)],
        ("nc", "plot"): [str(PROGRAM), "-o", str(o("p.png"))],
        ("daq", "record"): [
            "--sim",
            "--seconds",
            "0.2",
            "--speed",
            "0",
            "--quiet",
            "-o",
            str(o("r.h5")),
        ],  # fmt: skip
        ("data", "info"): [str(i.runs[0])],
        ("data", "plot"): [str(i.runs[0]), "-o", str(o("d.png"))],
        ("analyze", "forces"): [*map(str, i.runs), "--tool", "seed003-facemill"],
        ("analyze", "modal"): [str(i.hammer), "--rpm", "600", "--teeth", "4"],
        ("rules", "derive"): [*map(str, i.sweep), "-o", str(o("r.toml"))],
        ("rules", "add"): [str(i.rule), *RULE_KEY, "--db", str(o("rb.sqlite"))],
        ("rules", "list"): ["--db", str(i.db)],
        ("rules", "show"): ["gm241", "--db", str(i.db)],
        ("rules", "lookup"): [*RULE_KEY, "--db", str(i.db)],
        ("rules", "export"): ["gm241", "-o", str(o("x.toml")), "--db", str(i.db)],
        ("campaign", "run"): [str(i.quick), "--quiet", "--no-report"],
        ("campaign", "status"): [str(i.quick)],
        ("campaign", "report"): [str(i.quick), "--out", str(_copy_campaign(i))],
        ("plan", "rough"): [str(i.part), "-o", str(o("r.nc")), "--no-png"],
        ("plan", "feed"): [*slot_ball, "--rules", str(i.rule), "-o", str(o("f.nc"))],
        ("plan", "simulate"): slot_ball,
        ("plan", "orient"): [str(i.orient), "-o", str(o("orient")), "--no-plot"],
    }
    r |= {
        ("data", "import"): [str(TESTS / "data/analysis/dynoware_de.txt"), "-o", str(o("imp"))],
        ("analyze", "stability"): [
            str(ROOT / "configs/stability/insperger-1dof-down-005.toml"),
            "-o",
            str(o("lobes.csv")),
        ],  # fmt: skip
        ("catalog", "index"): [str(i.runs[0].parent), "--index", str(o("cat.sqlite"))],
        ("catalog", "query"): ["", "--index", _catalog(i)],
        ("catalog", "show"): [str(i.runs[0]), "--index", _catalog(i)],
        ("plan", "check"): [
            str(i.slot),
            "--tool",
            "phi30-ball",
            "--material",
            "gm241",
            "--stock",
            "box:0,100,0,60,-10,0",
            "--spacing",
            "1",
        ],  # fmt: skip
    }
    args = r.get(cmd)
    return None if args is None else [*cmd, *args]


def _catalog(i: Inputs) -> str:
    """A catalogue of the quick campaign's runs (made on first use)."""
    p = i.root / "catalog.sqlite"
    if not p.exists():
        _quiet_main(["catalog", "index", str(i.runs[0].parent), "--index", str(p)])
    return str(p)


def _copy_campaign(i: Inputs) -> Path:
    """A copy of the quick campaign's folder (a report writes into it)."""
    dst = i.out("campaigns")
    shutil.copytree(i.root / "campaigns", dst)
    return dst


PORT_COMMANDS = {("dnc", "send"), ("dnc", "unlock"), ("dnc", "reset"), ("dnc", "serve"),
                 ("dnc", "sim-controller")}  # fmt: skip


def with_port(cmd: tuple[str, ...], i: Inputs, extra: list[str], run) -> object:  # noqa: ANN001
    """Run ``run(argv)`` for a dnc command against an in-process simulated controller."""
    from rig.sim import SimClock, SimFanuc, SimGrbl

    if cmd == ("dnc", "sim-controller"):
        return run(["dnc", "sim-controller", "--protocol", "grbl", "--duration", "0.3", *extra])
    if cmd == ("dnc", "serve"):
        folder = i.out("programs")
        folder.mkdir()
        (folder / "O4321.nc").write_text("%\nO4321\nG21 G90 G0 X1 Y1\nG1 X2 F300\nM30\n%\n")
        with SimFanuc(clock=SimClock(20.0)) as ctl:
            t = threading.Timer(1.0, ctl.request_program, ("4321",))
            t.start()
            try:
                return run(["dnc", "serve", "--once", "--port", ctl.path, "--folder",
                            str(folder), "--machine", "ace-h63", *extra])  # fmt: skip
            finally:
                t.cancel()
    with SimGrbl(clock=SimClock(20.0)) as ctl:
        if cmd == ("dnc", "send"):
            nc = i.out("g.nc")
            nc.write_text("G21 G90\nG0 X1 Y1\nG1 X2 F300\nM2\n")
            return run(["dnc", "send", str(nc), "--port", ctl.path, "--protocol", "grbl",
                        "--no-progress", *extra])  # fmt: skip
        return run([*cmd, "--port", ctl.path, "--timeout", "5", *extra])
