"""Property-based fuzzing (hypothesis): config loading and the arguments of every command end in
a result or one ``cutlab: error:`` line, never a traceback or a hang.

The fast tier runs :data:`FAST` examples per config kind and per command; ``-m slow`` runs
:data:`SLOW` each. A hang is caught by pytest-timeout; commands that wait by design (a
simulated controller, a DNC server, a recording) get short limits appended after the fuzzed
arguments (argparse keeps the last).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import tomllib
from pathlib import Path

import pytest
from _cli_inputs import PROGRAM, ROOT, commands, inputs, leaf_parser
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis.errors import CutlabError
from analysis.validation import validate
from rig import configref
from rig.cli import main

__all__ = ["inputs"]  # the session fixture

FAST, SLOW = 50, 2000

# ------------------------------------------------------------------ config loading

SAMPLES = {  # a valid file of each kind the reference documents
    "configs/machines/*.toml": ROOT / "configs/machines/mill-5axis.toml",
    "configs/tools.toml": ROOT / "configs/tools.toml",
    "configs/materials.toml": ROOT / "configs/materials.toml",
    "configs/rig.toml": ROOT / "configs/rig.toml",
    "configs/campaigns/*.toml": ROOT / "configs/campaigns/facemill-ploughing.toml",
    "configs/parts/*.toml": ROOT / "configs/parts/seed000-bump.toml",
    "configs/orient/*.toml": ROOT / "configs/orient/fan.toml",
    "data/plans/*.toml": ROOT / "data/plans/demo-plan.toml",
}
KINDS = [(pat, model) for pat, _, model in configref.files() if pat in SAMPLES]

values = st.one_of(
    st.booleans(), st.integers(-(10**20), 10**20), st.floats(), st.text(max_size=8),
    st.sampled_from([math.nan, math.inf, -math.inf, 0, -1, 1e300, 5e9, "", "nan", "1"]),
    st.lists(st.floats(), max_size=4), st.dictionaries(st.text(max_size=4), st.integers(),
                                                       max_size=2),
)  # fmt: skip


def _leaves(data, path=()):  # noqa: ANN001, ANN202
    if isinstance(data, dict):
        for k, v in data.items():
            yield from _leaves(v, (*path, k))
    elif isinstance(data, list) and data and isinstance(data[0], dict | list):
        for i, v in enumerate(data[:3]):
            yield from _leaves(v, (*path, i))
    yield path


def _fuzz_config(kind: str, model, data: st.DataObject) -> None:  # noqa: ANN001
    base = tomllib.loads(SAMPLES[kind].read_text())
    paths = [p for p in _leaves(base) if p]
    for _ in range(data.draw(st.integers(1, 3))):
        path = data.draw(st.sampled_from(paths))
        cur = base
        for k in path[:-1]:  # an earlier draw may have replaced a table on the way: skip
            ok = (
                isinstance(cur, dict)
                and k in cur
                or (isinstance(cur, list) and isinstance(k, int) and k < len(cur))
            )
            cur = cur[k] if ok else None
        last = path[-1]
        if (
            isinstance(cur, dict)
            or isinstance(cur, list)
            and isinstance(last, int)
            and last < len(cur)
        ):
            cur[path[-1]] = data.draw(values)
    try:
        validate(model, base, SAMPLES[kind].name, "")
    except CutlabError as exc:
        assert str(exc).strip()


def _explore(n: int) -> dict:
    """The slow tier draws new examples every run; the default tier takes the profile's (fixed,
    see conftest.py), so a clean clone's run is reproducible."""
    return {"derandomize": False} if n == SLOW else {}


def _config_test(n: int):  # noqa: ANN202
    @pytest.mark.parametrize("kind,model", KINDS, ids=[k for k, _ in KINDS])
    @settings(max_examples=n, deadline=None, database=None, **_explore(n))
    @given(data=st.data())
    def test(kind, model, data) -> None:  # noqa: ANN001
        _fuzz_config(kind, model, data)

    return test


test_config_loading_fuzz = _config_test(FAST)
test_config_loading_fuzz_long = pytest.mark.slow(_config_test(SLOW))


# ------------------------------------------------------------------ command arguments

#: appended after the fuzzed arguments so a command that waits by design ends soon
LIMITS = {
    ("dnc", "sim-controller"): ["--duration", "0.2"],
    ("dnc", "send"): ["--timeout", "1", "--no-progress"],
    ("dnc", "unlock"): ["--timeout", "1"],
    ("dnc", "reset"): ["--timeout", "1"],
    ("dnc", "serve"): ["--port", "/dev/ttyNOPE-cutlab", "--once"],
    ("daq", "record"): ["--seconds", "0.05", "--speed", "0", "--quiet"],
    ("plan", "rough"): ["--no-png", "--no-check"],
    ("plan", "orient"): ["--no-plot"],
    ("campaign", "run"): ["--dry-run"],
    ("demo",): ["--quiet"],
    ("console",): ["--port", "0", "--linger-s", "0", "--quiet"],
}
CMDS = [c for c in commands()]


def _pool(i, tmp: Path) -> list[str]:  # noqa: ANN001
    """Paths a fuzzed argument may name: inputs of every kind, missing, empty and junk."""
    (tmp / "empty").write_bytes(b"")
    (tmp / "junk.h5").write_bytes(bytes(range(256)) * 4)
    return [str(p) for p in (PROGRAM, i.runs[0], i.rule, i.part, i.orient, i.hammer, i.slot,
                             tmp / "missing.toml", tmp / "empty", tmp / "junk.h5",
                             tmp / "out.png", tmp / "out.nc", tmp / "out.h5")]  # fmt: skip


#: options that write: they only ever get paths under the test's folder
WRITES = {"output", "out", "png", "report", "record", "plot"}


def _value(action: argparse.Action, pool: list[str], writes: bool = False) -> st.SearchStrategy:
    # junk never climbs out of the test's folder: `catalog index /` once indexed the whole
    # machine and left a catalogue at / that every later `catalog query` found
    junk = st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=6).filter(
        lambda s: "/" not in s and ".." not in s and "~" not in s
    )
    if writes or action.dest in WRITES:  # (pool[-1] is a file in the test's folder)
        return st.sampled_from([p for p in pool if "/out." in p] + [str(Path(pool[-1]).parent)])
    if action.choices:
        return st.one_of(st.sampled_from([str(c) for c in action.choices]), junk)
    if getattr(action.type, "__name__", "") in ("float", "int"):
        nums = st.one_of(st.floats(), st.integers(-(10**12), 10**12))
        return st.one_of(nums.map(repr), st.sampled_from(["nan", "-inf", "1e400", "0"]), junk)
    return st.one_of(st.sampled_from(pool), junk)


def _argv(cmd, pool: list[str], tmp: Path) -> st.SearchStrategy[list[str]]:  # noqa: ANN001
    acts = [a for a in leaf_parser(cmd)._actions if not isinstance(a, argparse._HelpAction)]
    pos = [a for a in acts if not a.option_strings]
    opts = [a for a in acts if a.option_strings]

    @st.composite
    def build(draw):  # noqa: ANN001, ANN202
        argv = list(cmd)
        for a in pos:  # the folders `catalog index` reads are also where it writes
            argv.append(draw(_value(a, pool, writes=cmd == ("catalog", "index"))))
        for a in draw(st.lists(st.sampled_from(opts), max_size=4)) if opts else []:
            argv.append(a.option_strings[-1])
            if a.nargs != 0:
                argv.append(draw(_value(a, pool, writes=cmd == ("catalog", "index"))))
        extra = list(LIMITS.get(cmd, []))
        if cmd[0] == "rules":  # never the lab's rule base
            extra += ["--db", str(tmp / "rb.sqlite")] if cmd[1] != "derive" else []
        if cmd == ("demo",):
            extra += ["--campaign", str(tmp / "missing.toml"), "--out", str(tmp / "demo")]
        return argv + extra

    return build()


def _cli_test(n: int):  # noqa: ANN202
    @pytest.mark.parametrize("cmd", CMDS, ids=" ".join)
    @settings(max_examples=n, deadline=None, database=None, **_explore(n),
              suppress_health_check=[HealthCheck.function_scoped_fixture,
                                     HealthCheck.too_slow])  # fmt: skip
    @given(data=st.data())
    def test(cmd, inputs, tmp_path, monkeypatch, data) -> None:  # noqa: ANN001
        monkeypatch.chdir(tmp_path)  # relative defaults (out/...) land here, not in the repo
        argv = data.draw(_argv(cmd, _pool(inputs, tmp_path), tmp_path))
        if cmd[0] == "rules" and cmd[1] in ("list", "show", "lookup", "export"):
            argv = [a if a != str(tmp_path / "rb.sqlite") else str(inputs.db) for a in argv]
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = main(argv)
            except SystemExit as exc:
                code = exc.code
        text = err.getvalue()
        assert "Traceback" not in text, (argv, text[-2000:])
        # 3 / 4: plan check's verdicts (violations / unchecked)
        assert code in (0, 1, 2, 3, 4, None), (argv, code, text[-2000:])
        if "cutlab: error:" in text:  # (exit 2 is also `nc check --dialect`'s answer)
            # one line per problem (a config with several says each), nothing after them
            lines = text.strip().splitlines()
            first = next(i for i, ln in enumerate(lines) if ln.startswith("cutlab: error:"))
            assert all(ln.startswith("cutlab: error:") for ln in lines[first:]), (argv, text)

    return test


test_cli_arguments_fuzz = pytest.mark.long(_cli_test(FAST))  # seconds per command
test_cli_arguments_fuzz_long = pytest.mark.slow(_cli_test(SLOW))


@pytest.mark.parametrize("ch", ["\x1e", "\x1c", "\x85", "\u2028", "\r", "\x0b", "\x1b"])
def test_error_line_shows_control_characters_escaped(ch, tmp_path, capsys) -> None:  # noqa: ANN001
    """A control character typed into an argument or a file name is shown escaped, so the error
    stays one line for every reader (Python's splitlines breaks at U+001E and U+2028; found by
    the fuzzer in CI: ``analyze modal ... --rpm '-\\x1e'``)."""
    folder = tmp_path / f"d{ch}"
    folder.mkdir()
    cases = (
        ["analyze", "modal", str(PROGRAM), "--rpm", f"-{ch}"],  # argparse
        ["nc", "check", str(tmp_path / f"a{ch}b.nc")],  # a CutlabError naming the file
        ["nc", "motions", str(PROGRAM), "--csv", "-o", str(folder)],  # an OSError
    )
    for argv in cases:
        with contextlib.suppress(SystemExit):
            main(argv)
        text = capsys.readouterr().err
        assert len(text.splitlines()) == 1 and text.startswith("cutlab: error:"), (argv, text)
