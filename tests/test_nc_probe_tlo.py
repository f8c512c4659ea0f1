"""G43.1 (dynamic tool length offset) and G38.2..G38.5 (probing) in the GRBL and LinuxCNC
dialects: the errors of the real controls (LinuxCNC's rs274 agrees on the motion: see
tests/data/nc/rs274/tool_length_dynamic.ngc and probing.ngc in the differential tier)."""

from __future__ import annotations

import pytest

from planning.nc import NCError, Program, interpret
from planning.nc.restart import restart_preamble
from planning.nc.run import state_at_block


def _run(text: str, dialect: str = "linuxcnc", **kw):  # noqa: ANN003, ANN202
    return interpret(Program.parse("G21 G90 G17\n" + text + "M2\n", "t.nc"), dialect=dialect,
                     **kw)  # fmt: skip


def test_g43_1_shifts_the_position_by_the_offset_change_not_the_tool() -> None:
    m = _run("G0 X0 Y0 Z10\nG43.1 Z2.5\nG91 G0 Z-1\nG90 G49\nG91 G0 Z0\n")
    assert m.end[1].tolist() == pytest.approx([0, 0, 6.5])  # 10 - 2.5 - 1
    assert m.start[2].tolist() == pytest.approx([0, 0, 9.0])  # G49: back by the 2.5


@pytest.mark.parametrize("text,dialect,words", [
    ("G43.1 X1 Z2\n", "grbl", ["X1", "Z and only Z", "error:37"]),
    ("G43.1\n", "grbl", ["Z and only Z"]),
    ("G43.1 Z1 A2\n", "linuxcnc", ["A2", "rotary"]),
    ("G43.1 Z1 G1 X5 F10\n", "linuxcnc", ["G43.1 and G1", "axis words"]),
    ("G43.1 Z1 G92 X0\n", "linuxcnc", ["G92", "G43.1"]),
    ("G43.1 Z1\n", "fanuc", ["unknown G-code G43.1"]),
    ("G38.2 Z-5\n", "grbl", ["no feed rate"]),
    ("G93 G38.2 Z-5 F1\n", "linuxcnc", ["inverse-time"]),
    ("G38.3 Z0.2 F10\n", "linuxcnc", ["too close", "0.254"]),
    ("G38.3 Z0 F10\n", "grbl", ["too close"]),
    ("G41 D1\nG38.2 Z-5 F10\n", "linuxcnc", ["cutter compensation"]),
    ("G38.2 Z-5 F10\n", "fanuc", ["unknown G-code G38.2"]),
])  # fmt: skip
def test_errors_name_the_place_and_the_rule(text: str, dialect: str, words: list[str]) -> None:
    with pytest.raises(NCError) as e:
        _run(text, dialect)
    msg = str(e.value)
    assert msg.startswith("t.nc:") and all(w in msg for w in words), msg


def test_probes_are_feed_moves_to_their_target_and_modal() -> None:
    m = _run("G0 X1 Y1 Z5\nG38.2 Z-2 F60\nZ-4\nG0 Z5\n", "grbl")
    assert m.kind.tolist() == [0, 1, 1, 0]
    assert m.end[2].tolist() == pytest.approx([1, 1, -4]) and m.feed_mm_min[1] == 60.0


def test_the_stock_simulations_refuse_probing_and_a_restart_inside_it() -> None:
    text = "G0 X1 Y1 Z5\nG38.2 Z-2 F60\nG0 Z5\n"
    with pytest.raises(NCError, match="where it stops depends on the part"):
        _run(text, "grbl", probing="refuse")
    prog = Program.parse("G21 G90\nG0 X1 Y1 Z5\nG38.2 Z-2 F60\nZ-3\nG0 Z5\nM2\n", "t.nc")
    with pytest.raises(NCError, match="probe move mode"):
        restart_preamble(state_at_block(prog, 4, dialect="linuxcnc"), safe_z_mm=5.0)


def test_a_restart_after_g43_1_sets_it_again_on_its_own_block() -> None:
    prog = Program.parse("G21 G90\nG0 X1 Y1 Z5\nG43.1 Z2\nG0 X3\nG0 X4\nM2\n", "t.nc")
    lines = restart_preamble(state_at_block(prog, 4, dialect="grbl"), safe_z_mm=5.0)
    assert "G43.1 Z2" in lines and not any("G43.1" in ln and "G0" in ln for ln in lines)
