"""The fault matrix: bad numbers, wrong types, missing and foreign files, truncated HDF5, huge
inputs and a lost device, over every command (``pytest -m faults``).

Each case has its expected exit status and checks the message: the error is one line
``cutlab: error: ...`` naming the field or file, with no traceback; where it matters, what was
there before the command survives it. Commands run in-process (``rig.cli.main``).
"""

from __future__ import annotations

import argparse
import math
import shutil
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from _cli_inputs import PROGRAM, ROOT, commands, inputs, leaf_parser, recipe

from rig.cli import main

__all__ = ["inputs"]  # the session fixture

pytestmark = pytest.mark.faults


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    """Exit status, stdout and stderr of ``cutlab argv`` (a usage error exits through
    SystemExit)."""
    capsys.readouterr()
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(err: str, *names: str) -> None:
    """The error is one line ``cutlab: error: ...`` (the last of stderr) naming ``names``."""
    assert "Traceback" not in err, err[-2000:]
    lines = err.strip().splitlines()
    assert lines and lines[-1].startswith("cutlab: error:"), err[-2000:]
    assert err.count("cutlab: error:") == 1, err[-2000:]
    for n in names:
        assert n in lines[-1], f"{n!r} not named in: {lines[-1]}"


# ------------------------------------------------------------------ bad numbers on the command


def _numeric_options() -> list[tuple[tuple[str, ...], str, argparse.Action]]:
    out = []
    for cmd in commands():
        for a in leaf_parser(cmd)._actions:
            if a.option_strings and getattr(a.type, "__name__", "") in ("float", "int"):
                out.append((cmd, a.option_strings[-1], a))
    return out


def minimal_argv(cmd: tuple[str, ...]) -> list[str]:
    """``cmd`` with a dummy for every positional and required option (parse-time tests)."""
    argv = list(cmd)
    for a in leaf_parser(cmd)._actions:
        if a.option_strings and not a.required:
            continue
        if isinstance(a, argparse._HelpAction):
            continue
        number = getattr(a.type, "__name__", "") in ("float", "int")
        val = str(a.choices[0]) if a.choices else "1" if number else "x"
        argv += [*a.option_strings[-1:], val] if a.option_strings else [val]
    return argv


BAD_NUMBERS = ["nan", "inf", "-inf", "1e400", "true", "", "5e9"]


def _validated(action: argparse.Action) -> bool:
    """The option parses with rig.cli.common.number (finite, in range), not bare float/int."""
    return getattr(action.type, "__qualname__", "").startswith("number.")


def _option_cases():
    for cmd, opt, action in _numeric_options():
        for bad in BAD_NUMBERS:
            name = f"{' '.join(cmd)} {opt}={bad or 'empty'}"
            yield pytest.param(cmd, opt, action, bad, id=name)


@pytest.mark.parametrize("cmd,opt,action,bad", list(_option_cases()))
def test_a_bad_number_option_is_one_line(cmd, opt, action, bad, capsys) -> None:
    assert _validated(action), f"{opt} is not parsed by rig.cli.common.number"
    code, _, err = run([*minimal_argv(cmd), f"{opt}={bad}"], capsys)
    assert code == 2
    assert_one_line_error(err, opt)
    assert len(err.strip().splitlines()) == 1, err  # refused at parse time: nothing else said


def test_the_command_and_the_configs_share_one_magnitude_limit() -> None:
    from analysis.validation import MAGNITUDE_LIMIT
    from rig.cli import common

    assert common.MAGNITUDE_LIMIT == MAGNITUDE_LIMIT


# ------------------------------------------------------------------ bad numbers in config files


@dataclass
class ConfigFault:
    """A config file (``src``) with the value at ``path`` replaced, fed to a command."""

    name: str
    src: Path
    path: tuple
    argv: Callable  # (inputs, bad file, tmp) -> argv
    in_config_dir: str | None = None  # the file replaces this one in a copy of configs/
    fix: Callable | None = None  # (data, inputs) -> None: make the valid file self-contained
    marks: list = field(default_factory=list)


def _out(i, tmp, name="o"):  # noqa: ANN001, ANN202
    return str(tmp / name)


SLOT_FEED = ["--tool", "phi30-ball", "--stock", "box:0,100,0,60,-10,0", "--spacing", "1"]
CONFIG_FAULTS = [
    ConfigFault("machine", ROOT / "configs/machines/ace-h63.toml", ("feed_max_mm_min",),
                lambda i, f, t: ["nc", "check", PROGRAM, "--machine", f]),
    ConfigFault("machine", ROOT / "configs/machines/ace-h63.toml", ("x", "max_mm"),
                lambda i, f, t: ["nc", "check", PROGRAM, "--machine", f]),
    ConfigFault("machine", ROOT / "configs/machines/ace-h63.toml", ("serial", "baudrate"),
                lambda i, f, t: ["nc", "check", PROGRAM, "--machine", f]),
    ConfigFault("5-axis pivot", ROOT / "configs/machines/mill-5axis.toml",
                ("five_axis", "pivot_mm", 2),
                lambda i, f, t: ["nc", "check", PROGRAM, "--machine", f]),
    ConfigFault("tools", ROOT / "configs/tools.toml", ("tools", "phi30-ball", "diameter_mm"),
                lambda i, f, t: ["plan", "simulate", i.slot, *SLOT_FEED], "tools.toml"),
    ConfigFault("tools", ROOT / "configs/tools.toml", ("tools", "phi30-ball", "flutes"),
                lambda i, f, t: ["plan", "simulate", i.slot, *SLOT_FEED], "tools.toml"),
    ConfigFault("materials", ROOT / "configs/materials.toml",
                ("materials", "gm241", "endmill", "Ktc_n_mm2"),
                lambda i, f, t: ["plan", "feed", i.slot, "--rules", i.rule, *SLOT_FEED,
                                 "--material", "gm241", "-o", _out(i, t, "o.nc")],
                "materials.toml"),
    ConfigFault("rig", ROOT / "configs/rig.toml", ("daq", "rate_hz"),
                lambda i, f, t: ["daq", "record", "--sim", "--rig", f, "--seconds", "0.1",
                                 "--speed", "0", "-o", _out(i, t, "r.h5")]),
    ConfigFault("rig", ROOT / "configs/rig.toml", ("dynamometer", "channels", 0, "range_n_v"),
                lambda i, f, t: ["daq", "record", "--sim", "--rig", f, "--seconds", "0.1",
                                 "--speed", "0", "-o", _out(i, t, "r.h5")]),
    ConfigFault("campaign", None, ("program", "block_length_mm"),
                lambda i, f, t: ["campaign", "run", f, "--dry-run"]),
    ConfigFault("campaign", None, ("matrix", 0, "spindle_rpm"),
                lambda i, f, t: ["campaign", "run", f, "--dry-run"]),
    ConfigFault("part", None, ("rough", "cusp_mm"),
                lambda i, f, t: ["plan", "rough", f, "-o", _out(i, t, "r.nc"), "--no-png"]),
    ConfigFault("part", None, ("stock", "z_max_mm"),
                lambda i, f, t: ["plan", "rough", f, "-o", _out(i, t, "r.nc"), "--no-png"]),
    ConfigFault("orient", None, ("planner", "feed_mm_min"),
                lambda i, f, t: ["plan", "orient", f, "-o", _out(i, t), "--no-plot"]),
    ConfigFault("orient", None, ("paths", "points_per_line"),
                lambda i, f, t: ["plan", "orient", f, "-o", _out(i, t), "--no-plot"]),
    ConfigFault("plan", ROOT / "data/plans/demo-plan.toml", ("stock", "top_mm"),
                lambda i, f, t: ["plan", "simulate", f]),
    ConfigFault("plan", ROOT / "data/plans/demo-plan.toml", ("stock", "spacing_mm"),
                lambda i, f, t: ["plan", "simulate", f]),
    ConfigFault("rule", None, ("rule", "base_feed_mm_min"),
                lambda i, f, t: ["plan", "feed", i.slot, "--rules", f, *SLOT_FEED,
                                 "-o", _out(i, t, "o.nc")]),
    ConfigFault("rule", None, ("bins", 3, "feed_mm_min"),
                lambda i, f, t: ["plan", "feed", i.slot, "--rules", f, *SLOT_FEED,
                                 "-o", _out(i, t, "o.nc")]),
]  # fmt: skip

BAD_VALUES = {"true": True, "nan": math.nan, "inf": math.inf, "text": "5", "huge": 1e12}


def _source(c: ConfigFault, i) -> Path:  # noqa: ANN001
    return c.src or {"campaign": i.quick, "part": i.part, "orient": i.orient,
                     "rule": i.rule}[c.name]  # fmt: skip


def _set(data, path, value) -> None:  # noqa: ANN001
    for k in path[:-1]:
        data = data.setdefault(k, {}) if isinstance(data, dict) else data[k]
    data[path[-1]] = value


@pytest.mark.parametrize("bad", list(BAD_VALUES))
@pytest.mark.parametrize(
    "c", CONFIG_FAULTS, ids=[f"{c.name}:{'.'.join(map(str, c.path))}" for c in CONFIG_FAULTS]
)
def test_a_bad_number_in_a_config_is_one_line(c, bad, inputs, tmp_path, capsys, monkeypatch):
    data = tomllib.loads(_source(c, inputs).read_text())
    if c.name == "plan":  # programs relative to the shipped plan's folder
        for op in data["operations"]:
            op["program"] = str((ROOT / "data/plans" / op["program"]).resolve())
    _set(data, c.path, BAD_VALUES[bad])
    name = c.in_config_dir or f"bad-{c.name.replace(' ', '-')}.toml"
    if c.in_config_dir:
        shutil.copytree(ROOT / "configs", tmp_path / "configs")
        monkeypatch.setenv("CUTLAB_CONFIG_DIR", str(tmp_path / "configs"))
        f = tmp_path / "configs" / name
    else:
        f = tmp_path / name
    f.write_text(tomli_w.dumps(data))
    code, _, err = run(c.argv(inputs, f, tmp_path), capsys)
    assert code == 2, err[-2000:]
    key = next(k for k in reversed(c.path) if isinstance(k, str))
    assert_one_line_error(err, f.name, key)


# ------------------------------------------------------------------ files, sizes and devices


def _truncated_run(i, tmp):  # noqa: ANN001, ANN202
    src = i.runs[0].read_bytes()
    p = tmp / "truncated.h5"
    p.write_bytes(src[: len(src) // 2])
    return p


def _nan_run(i, tmp):  # noqa: ANN001, ANN202
    """A run file with one NaN sample in its force record."""
    import h5py

    p = tmp / "nan.h5"
    shutil.copy(i.runs[0], p)
    with h5py.File(p, "r+") as f:
        volts = f["forces/volts"]
        volts[len(volts) // 2, 0] = np.nan
    return p


def _long_line(i, tmp):  # noqa: ANN001, ANN202
    p = tmp / "long.nc"
    p.write_text("G21 G90\nG1 X1 F100 (" + "x" * 70_000 + ")\nM30\n")
    return p


def _t2(i, tmp):  # noqa: ANN001, ANN202
    p = tmp / "t2.nc"
    p.write_text("G21 G90 G17\nT1 M6\nS2000 M3\nG0 X-20 Y30 Z5\nG1 Z-0.3 F1000\nG1 X50\n"
                 "G0 Z50\nT2 M6\nG0 X60 Y30 Z5\nG1 Z-2 F100\nG0 Z50\nM30\n")  # fmt: skip
    return p


def _nan_word(i, tmp):  # noqa: ANN001, ANN202
    p = tmp / "nanword.nc"
    p.write_text("G21 G90\nG0 Xnan Y0 Z5\nM30\n")
    return p


def _huge_word(i, tmp):  # noqa: ANN001, ANN202
    p = tmp / "huge.nc"
    p.write_text("G21 G90\nG1 X1e300 Y0 Z5 F100\nM30\n")
    return p


def _part(**rough):  # noqa: ANN003, ANN202
    def make(i, tmp):  # noqa: ANN001, ANN202
        data = tomllib.loads(i.part.read_text())
        for k, v in rough.items():
            sec, key = k.split("__")
            data[sec][key] = v
        p = tmp / "extreme.toml"
        p.write_text(tomli_w.dumps(data))
        return p

    return make


def _rough(i, f, t):  # noqa: ANN001, ANN202
    """plan rough on an extreme part (the argv of the plan-rough faults)."""
    return ["plan", "rough", f, "-o", t / "r.nc", "--no-png"]


@dataclass
class FileFault:
    id: str
    make: Callable  # (inputs, tmp) -> Path
    argv: Callable  # (inputs, path, tmp) -> argv
    code: int = 2
    names: tuple = ()  # what the message must name besides the file
    marks: list = field(default_factory=list)


FILE_FAULTS = [
    FileFault("data info truncated h5", _truncated_run, lambda i, f, t: ["data", "info", f]),
    FileFault("data plot truncated h5", _truncated_run,
              lambda i, f, t: ["data", "plot", f, "-o", t / "d.png"]),
    FileFault("analyze forces truncated h5", _truncated_run,
              lambda i, f, t: ["analyze", "forces", f, i.runs[1], "--tool", "seed003-facemill"]),
    FileFault("rules derive truncated h5", _truncated_run,
              lambda i, f, t: ["rules", "derive", f, *i.sweep[1:], "-o", t / "r.toml"]),
    FileFault("campaign status missing", lambda i, t: t / "nope.toml",
              lambda i, f, t: ["campaign", "status", f]),
    FileFault("nc check line over 65536", _long_line, lambda i, f, t: ["nc", "check", f],
              names=("65",)),
    FileFault("nc check Xnan", _nan_word, lambda i, f, t: ["nc", "check", f], names=("nan",)),
    FileFault("nc check X1e300", _huge_word, lambda i, f, t: ["nc", "check", f]),
    FileFault("plan simulate Xnan", _nan_word,
              lambda i, f, t: ["plan", "simulate", f, "--tool", "phi10-flat"]),
    FileFault("plan simulate T2 with one tool", _t2,
              lambda i, f, t: ["plan", "simulate", f, "--tool", "phi10-flat", "--stock",
                               "box:0,100,0,60,-10,0", "--spacing", "1"],
              names=("block 8", "T2")),
    FileFault("plan feed T2 with one tool", _t2,
              lambda i, f, t: ["plan", "feed", f, "--rules", i.rule, "--tool", "phi10-flat",
                               "--stock", "box:0,100,0,60,-10,0", "--spacing", "1",
                               "-o", t / "o.nc"], names=("block 8", "T2")),
    FileFault("plan rough stock 1e8 tall", _part(stock__z_max_mm=1e8),
              _rough,
              names=("dh_mm",)),
    FileFault("plan rough dh 1e-6", _part(rough__dh_mm=1e-6),
              _rough,
              names=("dh_mm",)),
    FileFault("plan rough optimal_dh 1e-6", _part(rough__optimal_dh_mm=1e-6),
              _rough,
              names=("optimal_dh_mm",)),
    FileFault("plan rough step 1e-6", _part(rough__step_factor=1e-6),
              _rough,
              names=("step_factor",)),
    FileFault("plan rough contour tol 1e-9", _part(rough__contour_tolerance_mm=1e-9),
              _rough,
              names=("contour_tolerance_mm",)),
    FileFault("plan rough ramp 1e-6", _part(rough__ramp_angle_deg=1e-6),
              _rough,
              names=("ramp_angle_deg",)),
    FileFault("plan rough plunge 1e-9", _part(cutting__plunge_feed_mm_min=1e-9),
              _rough,
              names=("plunge_feed_mm_min",)),
    FileFault("plan rough stock 1e8 wide", _part(stock__x_max_mm=1e8, stock__y_max_mm=1e8),
              _rough),
    FileFault("plan rough depth true", _part(rough__cusp_mm=True),
              _rough,
              names=("cusp_mm", "boolean")),
    FileFault("nc plot unknown image type", lambda i, t: PROGRAM,
              lambda i, f, t: ["nc", "plot", f, "-o", t / "p.png-x"], names=("png-x",)),
    FileFault("data plot unknown image type", lambda i, t: i.runs[0],
              lambda i, f, t: ["data", "plot", f, "-o", t / "d.png-x"], names=("png-x",)),
    FileFault("data info NaN sample", _nan_run, lambda i, f, t: ["data", "info", f], code=0),
    # the fit is refused naming the sample (exit 2), no traceback
    FileFault("analyze forces NaN sample", _nan_run,
              lambda i, f, t: ["analyze", "forces", f, i.runs[1], "--tool", "seed003-facemill"],
              names=("sample", "finite")),
    FileFault("dnc send lost port", lambda i, t: i.slot,
              lambda i, f, t: ["dnc", "send", f, "--port", "/dev/ttyNOPE-cutlab",
                               "--protocol", "grbl", "--no-progress"], names=("ttyNOPE",)),
    FileFault("dnc unlock lost port", lambda i, t: i.slot,
              lambda i, f, t: ["dnc", "unlock", "--port", "/dev/ttyNOPE-cutlab"],
              names=("ttyNOPE",)),
    FileFault("dnc reset lost port", lambda i, t: i.slot,
              lambda i, f, t: ["dnc", "reset", "--port", "/dev/ttyNOPE-cutlab"],
              names=("ttyNOPE",)),
    FileFault("daq record no NI device", lambda i, t: t / "r.h5",
              lambda i, f, t: ["daq", "record", "--seconds", "0.1", "-o", f]),
    FileFault("rules show missing db", lambda i, t: t / "typo.sqlite",
              lambda i, f, t: ["rules", "show", "gm241", "--db", f]),
    FileFault("plan feed rule not in db", lambda i, t: i.db,
              lambda i, f, t: ["plan", "feed", i.slot, "--rules", "nope", "--db", f,
                               *SLOT_FEED, "-o", t / "o.nc"], names=("nope",)),
]  # fmt: skip


@pytest.mark.parametrize("c", [pytest.param(c, id=c.id, marks=c.marks) for c in FILE_FAULTS])
def test_a_bad_file_or_device_is_one_line(c, inputs, tmp_path, capsys) -> None:
    f = c.make(inputs, tmp_path)
    code, _, err = run(c.argv(inputs, f, tmp_path), capsys)
    assert code == c.code, err[-2000:]
    assert "Traceback" not in err
    if c.code == 2:
        assert_one_line_error(err, *c.names)


# ------------------------------------------------------------------ what must survive


def test_a_refused_recording_keeps_the_file_it_would_overwrite(inputs, tmp_path, capsys):
    out = tmp_path / "run.h5"
    shutil.copy(inputs.runs[0], out)
    before = out.read_bytes()
    code, _, err = run(["daq", "record", "--sim", "--seconds", "0.1", "-o", out], capsys)
    assert code == 2 and out.read_bytes() == before
    assert_one_line_error(err, "run.h5")


def test_a_refused_rule_keeps_the_rule_base(inputs, tmp_path, capsys):
    db = tmp_path / "rb.sqlite"
    shutil.copy(inputs.db, db)
    before = db.read_bytes()
    argv = recipe(("rules", "add"), inputs)
    argv[argv.index("--db") + 1] = str(db)
    code, _, err = run(argv, capsys)  # the same group again without --replace
    assert code == 2 and db.read_bytes() == before
    assert_one_line_error(err)


@pytest.mark.parametrize("opt,bad", [("--min-piece", "nan"), ("--force-limit", "inf"),
                                     ("--spacing", "0"), ("--spindle", "-1")])  # fmt: skip
def test_a_refused_feed_plan_writes_nothing(opt, bad, inputs, tmp_path, capsys):
    out = tmp_path / "o.nc"
    argv = [*recipe(("plan", "feed"), inputs), opt, bad]
    argv[argv.index("-o") + 1] = str(out)
    code, _, err = run(argv, capsys)
    assert code == 2 and not out.exists() and not list(tmp_path.iterdir())
    assert_one_line_error(err, opt)


# ------------------------------------------------------------------ honest outputs


@pytest.mark.long
def test_plan_feed_says_when_the_result_is_slower(inputs, tmp_path, capsys) -> None:
    """A 3000 mm/min slot through a rule whose base feed is 1000 mm/min: about 3x slower."""
    import json

    prog = tmp_path / "fast.nc"
    prog.write_text(inputs.slot.read_text().replace("F1000", "F3000"))
    argv = ["plan", "feed", prog, "--rules", inputs.rule, *SLOT_FEED, "-o", tmp_path / "o.nc"]
    code, out, err = run([*argv, "--json"], capsys)
    assert code == 0, err
    s = json.loads(out)
    ratio = s["time_after_s"] / s["time_before_s"]
    assert ratio > 2
    assert s["slower_than_input"] and f"({ratio:.2f}x)" in s["slower_than_input"]
    assert "warning: the adjusted program is slower than its input" in err
    code, out, err = run(recipe(("plan", "feed"), inputs) + ["--json"], capsys)
    assert code == 0 and json.loads(out)["slower_than_input"] is None


def test_progress_prints_plain_lines_when_stderr_is_no_terminal(capsys, monkeypatch) -> None:
    from rig.terminal import Progress

    monkeypatch.setattr(Progress, "interval_s", 0.0)
    with Progress("reducing runs", "run", total=23) as bar:
        bar(12)
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("reducing runs: 12/23 run (52 %), ") and err[0].endswith(" s")
    assert err[-1].startswith("reducing runs: 12/23 run (52 %)")


def test_a_usage_error_is_one_line(capsys) -> None:
    code, _, err = run(["plan", "rough"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("cutlab: error: plan rough: the following arguments are required")
