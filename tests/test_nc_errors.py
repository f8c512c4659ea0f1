"""Malformed programs give one clear NCError (file:line:column, word, why), never a traceback —
in the API and through the CLI; random text raises nothing but NCError."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planning.nc import Interpreter, NCError, Program, interpret, interpret_file
from rig.cli import main as cli_main

BAD = Path(__file__).parent / "data" / "nc" / "bad"
EXPECTED = tomllib.loads((BAD / "expected.toml").read_text(encoding="utf-8"))


def test_every_bad_program_has_an_expectation():
    assert sorted(p.stem for p in BAD.glob("*.nc")) == sorted(EXPECTED)
    assert len(EXPECTED) >= 25


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_bad_program_gives_one_clear_error(name):
    exp = EXPECTED[name]
    path = BAD / f"{name}.nc"
    with pytest.raises(NCError) as info:
        interpret_file(path)
    err = info.value
    assert (err.file, err.line, err.column, err.word) == (
        str(path),
        exp["line"],
        exp["column"],
        exp["word"],
    )
    assert exp["reason"] in err.reason
    assert str(err).startswith(f"{path}:{exp['line']}:{exp['column']}: ")
    assert "\n" not in str(err)
    # the layout-keeping reader + interpreter report the same place
    with pytest.raises(NCError) as again:
        interpret(Program.read(path, check=False))
    assert (again.value.line, again.value.column) == (err.line, err.column)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_bad_program_through_cli_is_one_line_exit_2(name, capsys):
    path = BAD / f"{name}.nc"
    assert cli_main(["nc", "check", str(path)]) == 2
    out, errtext = capsys.readouterr()
    assert out == ""
    lines = errtext.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"cutlab: error: {path}:")


def test_console_script_exit_code_and_message():
    path = BAD / "arc_r_too_small.nc"
    proc = subprocess.run(
        [sys.executable, "-m", "rig.cli", "nc", "check", str(path), "--json"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip() == (
        f"cutlab: error: {path}:6:11: 'R4': arc radius |R| = 4 mm is smaller than half the chord "
        "(10 mm) by more than the tolerance 0.002 mm"
    )


def test_missing_file_is_an_nc_error(tmp_path):
    with pytest.raises(NCError, match="cannot read"):
        interpret_file(tmp_path / "nope.nc")
    with pytest.raises(NCError, match="cannot read"):
        Program.read(tmp_path / "nope.nc")


NC_ALPHABET = "GMXYZIJKRFSTPQLNODHABCEUgxyz0123456789.-+ ()/;%#\t\u00e4"


@pytest.mark.long
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.text(alphabet=NC_ALPHABET, max_size=30), max_size=8), st.booleans())
def test_fuzz_random_text_raises_only_nc_error(lines, strict):
    it = Interpreter(strict=strict, arc_tolerance_mm=0.01)
    try:
        it.run(["G1 F100", *lines])
    except NCError as err:
        assert err.line >= 1 and err.column >= 1 and err.reason


@pytest.mark.long
@settings(max_examples=200, deadline=None)
@given(st.text(max_size=200))
def test_fuzz_any_unicode_raises_only_nc_error(text):
    try:
        interpret(text, strict=False)
        Program.parse(text)
    except NCError:
        pass


G_CODES = (
    "0 1 2 3 4 17 18 19 20 21 28 30 40 41 43 49 53 54 80 81 82 83 90 91 90.1 91.1 93 94 98 99 7"
)
G_CODES = G_CODES.split()
M_CODES = ["0", "1", "2", "3", "4", "5", "6", "8", "9", "30", "98"]
NUMBERS = st.one_of(
    st.sampled_from(["0", "-0", ".5", "1.", "-1", "10", "1e", "0.0001", "999999999999"]),
    st.floats(-200, 200, allow_nan=False).map(lambda v: f"{v:.4f}"),
)


@st.composite
def near_valid_blocks(draw):
    words = []
    for _ in range(draw(st.integers(1, 6))):
        letter = draw(st.sampled_from("GGGMXYZXYZIJKRFFSTPQLDHA"))
        if letter == "G":
            words.append("G" + draw(st.sampled_from(G_CODES)))
        elif letter == "M":
            words.append("M" + draw(st.sampled_from(M_CODES)))
        else:
            words.append(letter + draw(NUMBERS))
    return " ".join(words)


@pytest.mark.long
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(near_valid_blocks(), min_size=1, max_size=12), st.booleans())
def test_fuzz_near_valid_programs_raise_only_nc_error(blocks, strict):
    """Deep paths (arcs, canned cycles, dwell, G53, units) with odd values: NCError or motion."""
    from planning.nc import motion_stats, restart_preamble

    it = Interpreter(strict=strict)
    try:
        m = it.run(blocks)
    except NCError as err:
        assert err.line >= 1 and err.reason
        return
    st_ = motion_stats(m)  # stats and linearisation must cope with whatever came out
    assert st_.time_s >= 0 or st_.time_s != st_.time_s
    try:
        restart_preamble(it.state)
    except NCError:
        pass
