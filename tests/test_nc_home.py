"""G28 / G30 reference-point returns (Fanuc semantics): intermediate point by G90/G91 and the work
offset, reference point in machine coordinates from the machine config, only the named axes move;
restart across a return; the machine config fields that hold the points."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.config import load_machine
from analysis.errors import ConfigError
from planning.nc import (
    LINE,
    RAPID,
    Interpreter,
    NCError,
    Program,
    interpret,
    restart_preamble,
    state_at_block,
)
from rig.cli import main

REF = (100.0, 200.0, 300.0)
POST = Path(__file__).parent / "data" / "nc" / "fanuc-post.nc"


def run(text: str, **kw):
    it = Interpreter(reference_mm=REF, **kw)
    return it, it.run(text.splitlines())


def test_g90_form_goes_through_the_intermediate_point_named_axes_only():
    _, m = run("G0 X10 Y20 Z5\nG28 X50 Z30")
    home = m[m.line == 2]
    assert home.kind.tolist() == [RAPID, RAPID]
    np.testing.assert_array_equal(home.start, [[10, 20, 5], [50, 20, 30]])
    np.testing.assert_array_equal(home.end, [[50, 20, 30], [100, 20, 300]])  # Y stays at 20
    _, m = run("G20 G0 X1 Y1\nG28 X2")  # inch intermediate point, reference in mm
    np.testing.assert_allclose(m.end[-2:], [[50.8, 25.4, 0], [100, 25.4, 0]])


def test_g91_z0_goes_straight_up_and_g91_form_is_incremental():
    it, m = run("G0 X10 Y20 Z5\nG91 G28 Z0")
    assert len(m[m.line == 2]) == 1  # intermediate point = here: one move
    np.testing.assert_array_equal(m.end[-1], [10, 20, 300])
    assert it.state.absolute is False  # G91 stays in force
    _, m = run("G0 X10 Y20 Z5\nG91 G28 X5 Z2")
    np.testing.assert_array_equal(m.end[-2:], [[15, 20, 7], [100, 20, 300]])


def test_intermediate_point_uses_the_work_offset_reference_does_not():
    _, m = run("G55 G0 X0 Y0 Z0\nG28 X10 Z10", work_offsets_mm={55: (1.0, 2.0, 3.0)})
    np.testing.assert_array_equal(m.end, [[1, 2, 3], [11, 2, 13], [100, 2, 300]])


def test_g28_then_a_feed_move_continues_from_the_reference_point():
    _, m = run("G0 X10 Y20 Z5\nG28 Z0\nG1 X40 F100\nG91 G1 Y-5")
    np.testing.assert_array_equal(m.start[-2:], [[10, 20, 300], [40, 20, 300]])
    np.testing.assert_array_equal(m.end[-2:], [[40, 20, 300], [40, 15, 300]])
    assert m.kind[-1] == LINE and m.feed_mm_min[-1] == 100


def test_g30_second_reference_from_the_machine_and_p2():
    machine = load_machine("ace-h63")
    m = interpret("G0 X1 Y2 Z3\nG91 G30 P2 Y0 Z0", machine)
    np.testing.assert_array_equal(m.end[-1], [1, 0, 600])  # second_reference_mm = [630, 0, 600]
    m = interpret("G0 X1 Y2 Z3\nG91 G28 Y0 Z0", machine)
    np.testing.assert_array_equal(m.end[-1], [1, 560, 600])
    with pytest.raises(NCError, match="unused|not used"):
        interpret("G28 P2 Z0", machine)  # P belongs to G30 only


def test_no_axis_word_fanuc_error_grbl_all_axes():
    with pytest.raises(NCError, match="needs the axes to return"):
        interpret("G28", reference_mm=REF)
    _, m = run("G0 X1 Y2 Z3\nG28", dialect="grbl")
    np.testing.assert_array_equal(m.end, [[1, 2, 3], [100, 200, 300]])


def test_without_a_machine_machine_zero_and_one_warning():
    it = Interpreter()
    m = it.run(["G0 X5 Y5 Z5", "G91 G28 Z0", "G28 X0 Y0"])
    np.testing.assert_array_equal(m.end[-1], [0, 0, 0])
    assert len(it.warnings) == 1 and "machine zero = work zero" in it.warnings[0].reason
    assert (it.warnings[0].line, it.warnings[0].column, it.warnings[0].word) == (2, 5, "G28")
    # a restart there would approach a guessed position: refused
    with pytest.raises(NCError, match="reference point .* is unknown"):
        restart_preamble(it.state)
    assert not state_at_block(Program.read(POST), 21, load_machine("ace-h63")).reference_assumed


@settings(max_examples=60, deadline=None)
@given(
    start=st.tuples(*[st.integers(-50, 50)] * 3),
    words=st.dictionaries(st.sampled_from("XYZ"), st.integers(-50, 50), min_size=1),
    incremental=st.booleans(),
)
def test_property_named_axes_reach_the_reference_others_stay(start, words, incremental):
    text = " ".join(f"{a}{v}" for a, v in words.items())
    mode = "G91" if incremental else "G90"
    _, m = run(f"G0 X{start[0]} Y{start[1]} Z{start[2]}\n{mode} G28 {text}")
    end = m.end[-1] if len(m[m.line == 2]) else np.array(start, float)
    for a, name in enumerate("XYZ"):
        if name in words:
            assert end[a] == REF[a]
            mid = start[a] + words[name] if incremental else words[name]
            # the path passes the intermediate point on this axis (start or end of a segment)
            home = m[m.line == 2]
            assert mid in np.concatenate([home.start[:, a], home.end[:, a]]) or mid == REF[a]
        else:
            assert end[a] == start[a]
            assert (m.end[m.line == 2, a] == start[a]).all()


@pytest.mark.parametrize("n", [5, 6, 13, 19, 20, 21])
def test_restart_across_a_reference_return_reproduces_the_rest(n):
    machine = load_machine("ace-h63")
    prog = Program.read(POST)
    whole = interpret(prog, machine)
    st_n = state_at_block(prog, n, machine)
    pre = restart_preamble(st_n)
    resumed = Interpreter(machine).run(pre + prog.lines[n:], first_line=1 - len(pre))
    rest = resumed[resumed.line >= 1]
    assert rest.same_path(whole[whole.block >= n], atol_mm=1e-9)
    if n >= 20:  # after N170 G91 G28 Z0. (line 20, block 19): Z at the reference, G91
        assert st_n.position_mm[2] == 600 and not st_n.absolute


def test_cutlab_nc_check_strict_on_a_post_processor_program(capsys):
    assert main(["nc", "check", str(POST), "--json", "--machine", "ace-h63"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["warnings"] == []
    assert out["bbox"]["max_mm"] == [630, 560, 600] and out["bbox"]["min_mm"] == [-20, -10, -1]
    assert out["cutting_length_mm"] == pytest.approx(106.0)
    # feeds 6 mm at 200 + 100 mm at 500; rapids: longest axis travel per move at 30000 mm/min
    rapid_mm = 600 + 20 + 585 + 10 + 16 + 585 + 650
    assert out["time_s"] == pytest.approx((6 / 200 + 100 / 500 + rapid_mm / 30000) * 60)
    assert main(["nc", "check", str(POST)]) == 0  # strict, no machine: runs, warns once
    assert capsys.readouterr().err.count("machine zero = work zero") == 1


def test_reference_points_in_the_machine_config(tmp_path):
    base = Path(__file__).resolve().parents[1] / "configs" / "machines" / "mill-5axis.toml"
    text = base.read_text().replace("reference_mm = [400, 300, 400]\n", "")
    p = tmp_path / "m.toml"
    p.write_text(text)
    m = load_machine(p)
    assert m.reference_point_mm == (400, 300, 400) == m.second_reference_point_mm  # travel max
    p.write_text(text.replace('dialect = "fanuc"', 'dialect = "fanuc"\nreference_mm = [0, 0, 401]'))
    with pytest.raises(ConfigError, match=r"reference_mm Z = 401.0 mm is outside the z travel"):
        load_machine(p)


def test_g29_returns_through_the_last_intermediate_point() -> None:
    text = "G90 G54 G0 X10 Y20 Z5\nG28 Z50\nG28 X0 Y0\nG29 X30 Y40\nG29 Z10"
    m = interpret(text, reference_mm=REF)
    ends = [tuple(p) for p in m.end[m.block >= 3]]
    # X, Y: to their intermediate point (0, 0) at the reference Z, then to (30, 40); Z alone the
    # same way through its own intermediate point 50.
    assert ends == [(0.0, 0.0, 300.0), (30.0, 40.0, 300.0), (30.0, 40.0, 50.0), (30.0, 40.0, 10.0)]
    assert np.all(m.kind == RAPID)
    # G91: the increment counts from the intermediate point, not from the reference point.
    m = interpret("G0 X10 Y20 Z5\nG91 G28 Z0\nG29 Z-3", reference_mm=REF)
    assert tuple(m.end[-1]) == (10.0, 20.0, 2.0) and tuple(m.end[-2]) == (10.0, 20.0, 5.0)


@pytest.mark.parametrize(
    "text,dialect,why",
    [
        ("G0 X1\nG29 X5", "fanuc", "no G28/G30 has set an intermediate point"),
        ("G28 Z10\nG29 X5", "fanuc", "G29 X: no G28/G30"),
        ("G28 Z10\nG29", "fanuc", "G29 needs the axes"),
        ("G28 Z10\nG29 Z5", "grbl", "not a GRBL command"),
    ],
)
def test_g29_without_its_intermediate_point_is_refused(text, dialect, why) -> None:
    with pytest.raises(NCError, match=r"p\.nc:2:") as e:
        interpret(text, reference_mm=REF, dialect=dialect, file="p.nc")
    assert why in str(e.value)
