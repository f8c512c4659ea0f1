"""Every option that names a file to write, given a folder instead: one ``cutlab: error:`` line
naming it (the argument fuzzer found ``nc motions --output FOLDER`` ending in a traceback)."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest
from _cli_inputs import commands, inputs, leaf_parser, recipe, with_port

from rig.cli import main

__all__ = ["inputs"]  # the session fixture

WRITES = {"output", "out", "png", "report", "record", "plot"}  # (as tests/test_fuzz_cli.py)
CASES = [(cmd, a.option_strings[-1]) for cmd in commands() for a in leaf_parser(cmd)._actions
         if a.option_strings and a.dest in WRITES and a.nargs != 0]  # fmt: skip
# plan orient --out names a folder by design: the case is the command's ordinary whole run (7
# CPU-s), in CI's command (long), not in a plain pytest (test_orient_cli.py runs it in the quick
# tier). demo --out, a folder too, stays: the quick tier's only whole run of `cutlab demo`.
BY_DESIGN = {(("plan", "orient"), "--out")}
PARAMS = [pytest.param(c, o, id=f"{' '.join(c)} {o}",
                       marks=[pytest.mark.long] if (c, o) in BY_DESIGN else [])
          for c, o in CASES]  # fmt: skip


@pytest.mark.parametrize("cmd,option", PARAMS)
def test_a_folder_where_a_file_is_written_is_one_line(inputs, tmp_path: Path, cmd, option) -> None:  # noqa: ANN001
    folder = tmp_path / "a-folder"
    folder.mkdir()
    err = io.StringIO()

    def run(argv: list[str]) -> int:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                return main(argv)
            except SystemExit as exc:
                return int(exc.code or 0)

    base = recipe(cmd, inputs)
    extra = [option, str(folder)]
    code = with_port(cmd, inputs, extra, run) if base is None else run([*base, *extra])
    text = err.getvalue()
    assert "Traceback" not in text, text[-2000:]
    # 0/1: a result (some write into a folder by design: demo --out; 1 is a result that failed,
    # as the recipe's own: too few runs for a face-mill fit); 2: one error line
    assert code in (0, 1, 2, 3, 4), (code, text)  # 3 / 4: plan check's verdicts
    if code == 2:
        assert text.count("cutlab: error:") == 1 and str(folder) in text, text
