"""Every ``--json`` output is strict JSON: no NaN or Infinity (a strict parser fails on them).

The commands come from the parser, so a new command with ``--json`` is covered as soon as it
exists (and fails here until tests/_cli_inputs.py gives it a valid call).
"""

from __future__ import annotations

import json
import math

import pytest
from _cli_inputs import PORT_COMMANDS, commands, has_json, inputs, recipe, with_port

from analysis.output import finite_json
from rig.cli import main
from rig.cli.common import print_json

__all__ = ["inputs"]  # the session fixture

JSON_COMMANDS = [c for c in commands() if has_json(c)]


def _strict(text: str) -> object:
    def refuse(name: str) -> None:
        raise ValueError(f"{name} in the JSON output")

    return json.loads(text, parse_constant=refuse)


# the whole-part commands take a minute or more each: in CI's command, not in a plain `pytest`
_LONG = {("plan", "rough"), ("demo",), ("plan", "orient")}


@pytest.mark.parametrize(
    "cmd",
    [pytest.param(c, marks=pytest.mark.long) if tuple(c) in _LONG else c for c in JSON_COMMANDS],
    ids=" ".join,
)
def test_json_output_is_strict(cmd, inputs, capsys) -> None:
    if cmd in PORT_COMMANDS:
        code = with_port(cmd, inputs, ["--json"], main)
    else:
        argv = recipe(cmd, inputs)
        assert argv is not None, f"tests/_cli_inputs.py has no valid call of `cutlab {cmd}`"
        code = main([*argv, "--json"])
    out, err = capsys.readouterr()
    assert code in (0, 1, 3, 4), err[-800:]  # 3 / 4: plan check's violations / unchecked
    assert "Traceback" not in err
    if cmd == ("dnc", "sim-controller"):  # its first line is the pty's path, for the sender
        out = out.split("\n", 1)[1]
    _strict(out)


def test_the_printer_turns_nonfinite_into_null_with_a_reason(capsys) -> None:
    import numpy as np

    print_json({"r2": float("nan"), "limit": np.float64(np.inf), "r2_reason": None,
                "xs": [1.0, -math.inf], "n": np.int64(3)})  # fmt: skip
    got = _strict(capsys.readouterr().out)
    assert got == {"r2": None, "r2_reason": None, "limit": None,
                   "limit_reason": "unbounded (+infinity)", "xs": [1.0, None], "n": 3}  # fmt: skip
    # a producer's own reason is kept
    assert finite_json({"r2": math.nan, "r2_reason": "one run"}) == {
        "r2": None, "r2_reason": "one run"}  # fmt: skip
