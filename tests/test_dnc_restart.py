"""Restart from block N (property): the preamble followed by blocks N.. moves exactly like the
whole program from block N on, whatever modal state N inherits."""

from __future__ import annotations

import numpy as np
import pytest
from _dnc_helpers import ARCS as ARCS_BODY
from hypothesis import given, settings
from hypothesis import strategies as st

from planning.nc import interpret, state_at_block
from rig.dnc import program_from_text, restart_blocks, restart_plan

coord = st.integers(-2000, 2000).map(lambda v: v / 100)  # 0.01 steps: written exactly


@st.composite
def programs(draw):  # noqa: ANN001, ANN201
    lines = ["G21 G90 G17", "T1 M6", "S1000 M3", "G0 X0 Y0 Z5", "G1 Z0 F300"]
    for _ in range(draw(st.integers(3, 25))):
        kind = draw(st.sampled_from(["move", "move", "move", "mode", "spindle", "coolant"]))
        if kind == "move":
            g = draw(st.sampled_from(["G0", "G1"]))
            words = [f"{a}{draw(coord):g}" for a in "XYZ" if draw(st.booleans())] or ["X1"]
            feed = f" F{draw(st.integers(50, 3000))}" if g == "G1" and draw(st.booleans()) else ""
            lines.append(f"{g} {' '.join(words)}{feed}")
        elif kind == "mode":
            lines.append(draw(st.sampled_from(["G90", "G91", "G20", "G21", "G17", "G18"])))
        elif kind == "spindle":
            lines.append(draw(st.sampled_from(["S2000 M3", "S1500 M4", "M5", "S800"])))
        else:
            lines.append(draw(st.sampled_from(["M8", "M9"])))
    lines.append("M30")
    return lines


@settings(max_examples=40, deadline=None)
@given(lines=programs(), data=st.data())
def test_preamble_then_rest_moves_like_the_original(lines, data) -> None:
    text = "\n".join(lines) + "\n"
    prog = program_from_text(text, "h.nc")
    n = data.draw(st.integers(5, len(lines) - 1), label="restart block")
    pre = restart_blocks(prog, n, "fanuc")
    full = interpret(text)
    part = interpret("\n".join(pre + lines[n:]) + "\n")
    a = full[full.block >= n]
    b = part[part.block >= len(pre)]
    assert len(a) == len(b)
    # the preamble writes the position with 4 decimals in the units in force: exact in mm for
    # these programs, to the control's 0.0001 in resolution (<= 1.27 um) in inch
    tol = 0.5e-4 * 25.4 + 1e-9 if state_at_block(text, n).inch else 1e-6
    np.testing.assert_allclose(b.start, a.start, atol=tol, rtol=0)
    np.testing.assert_allclose(b.end, a.end, atol=tol * 2, rtol=0)
    np.testing.assert_array_equal(b.kind, a.kind)
    inch = tol > 1e-6  # F is written with 4 decimals of in/min too
    np.testing.assert_allclose(b.feed_mm_min, a.feed_mm_min, rtol=1e-5 if inch else 1e-9)
    np.testing.assert_array_equal(b.spindle_rpm, a.spindle_rpm)
    np.testing.assert_array_equal(b.coolant, a.coolant)
    np.testing.assert_array_equal(b.tool, a.tool)
    # the approach ends where block n starts, coming down from the safe height
    approach = part[part.block < len(pre)]
    if len(approach) and len(a):
        np.testing.assert_allclose(approach.end[-1], a.start[0], atol=tol, rtol=0)


# -- arcs and the Fanuc drip feed -------------------------------------------------------------

ARCS = "%\n" + ARCS_BODY + "%\n"  # as a Fanuc program is framed


def test_restart_at_arcs_completes_the_block_for_both_protocols() -> None:
    from rig.dnc import restart_plan

    prog = program_from_text(ARCS, "a.nc")
    lines = ARCS.splitlines()
    full = interpret(ARCS)
    for n in range(6, 11):
        for protocol in ("fanuc", "grbl"):
            plan = restart_plan(prog, n, protocol)
            assert plan.preamble[-1].split()[-1] not in ("G2", "G3")
            rest = [plan.replaced.get(i, t) for i, t in enumerate(lines) if i >= n]
            part = interpret("\n".join(plan.preamble + rest) + "\n")
            a, b = full[full.block >= n], part[part.block >= len(plan.preamble)]
            np.testing.assert_allclose(b.end, a.end, atol=1e-9)
            np.testing.assert_array_equal(b.kind, a.kind)
    assert restart_plan(prog, 7, "fanuc").replaced == {7: "G17 G90 G2 X30 Y0 Z-1 I5 J0 F300"}


def test_fanuc_restart_at_an_arc_and_the_predicted_execution() -> None:
    """Drip feed to the simulated Fanuc from an arc: the control runs the original path; the
    record's predicted execution starts follow the control's within the line's slack."""
    from _dnc_helpers import FANUC_LINE_B_S, EventWaiter, fanuc_cfg, fanuc_sim

    from rig.dnc import FanucStreamer, MemorySink, restart_plan

    prog = program_from_text(ARCS, "a.nc")
    plan = restart_plan(prog, 7, "fanuc")
    ctl = fanuc_sim(4.0)
    done = EventWaiter(ctl, "program_end")
    with ctl:
        sink = MemorySink()
        st = FanucStreamer(fanuc_cfg(ctl.path), sink=sink, clock=ctl.clock.now,
                           pace_bytes_per_s=FANUC_LINE_B_S * 4)  # fmt: skip
        res = st.send(prog, 7, plan.preamble, replaced=plan.replaced)
        assert done.wait(60)
    assert res.ok and ctl.alarm == ""
    sent = [r.text for r in sink.rows]
    assert ctl.executed_texts() == sent and plan.replaced[7] in sent
    ex = np.array([b.t_start_s for b in ctl.executed])
    got = np.array([r.exec_time_s for r in sink.rows])
    assert np.all(np.isfinite(got))
    assert np.max(np.abs(got - ex)) < 0.2  # predicted from the time model, no acceleration
    assert res.last_executed_block <= prog.blocks[-1].index


# -- the approach: the program's clearance and plunge feed (issue 31, item 3) --------------------

# clearance Z5 (the only rapid height), plunges at F600, cuts at F3000; the part spans X0-50 Y0-10
CLEAR = """G21 G90 G17
S3000 M3
G0 X0 Y0 Z5
G1 Z-1 F600
G1 X20 F3000
G1 Y10
G1 X0
G0 Z5
G0 X30 Y0
G1 Z-1 F600
G1 X50 F3000
G0 Z5
M5
M30
"""


@pytest.mark.parametrize("protocol", ["fanuc", "grbl"])
def test_restart_approaches_at_the_clearance_and_plunges_at_the_programs_feed(protocol) -> None:
    """Restart at block 5 ('G1 Y10', the tool at X20 Y0 Z-1 in the cut): the preamble, read by
    planning.nc's interpreter, rapids no lower than Z5 (the program's clearance) and comes down
    at F600 (its plunge feed), never F3000; the block then cuts at F3000 as in the program."""
    from planning.nc import LINE, RAPID

    prog = program_from_text(CLEAR, "c.nc")
    plan = restart_plan(prog, 5, protocol)
    assert "clearance Z5" in plan.notes[0] and "line 3" in plan.notes[0]
    assert "plunge F600" in plan.notes[1] and "line 4" in plan.notes[1]
    lines = CLEAR.splitlines()
    part = interpret("\n".join(plan.preamble + lines[5:]) + "\n", dialect=protocol)
    n = len(plan.preamble)
    app = part[part.block < n]
    kind, start, end, feed = (np.asarray(a) for a in (app.kind, app.start, app.end,
                                                       app.feed_mm_min))  # fmt: skip
    rap = kind == RAPID
    moves_xy = np.hypot(*(end[:, :2] - start[:, :2]).T) > 1e-9
    # no rapid ends below the clearance (hand-computed: Z5; the first one rises straight up from
    # wherever the machine stands, the interpreter's Z0), none moves in X Y below it
    assert rap.any() and np.all(end[rap, 2] >= 5.0 - 1e-9)
    assert np.all(np.minimum(start[rap & moves_xy, 2], end[rap & moves_xy, 2]) >= 5.0 - 1e-9)
    assert not moves_xy[0] and end[0, 2] == 5.0
    # the XY move is at Z5 and ends over the restart point (X20 Y0)
    xy = np.flatnonzero(rap & moves_xy)
    np.testing.assert_allclose(end[xy[-1]], [20.0, 0.0, 5.0], atol=1e-9)
    # the only descent below Z5: a feed move straight down X20 Y0 Z5 -> Z-1 at F600
    below = end[:, 2] < 5.0 - 1e-9
    assert np.flatnonzero(below).tolist() == [len(kind) - 1]
    assert kind[-1] == LINE and feed[-1] == 600.0
    np.testing.assert_allclose(start[-1], [20.0, 0.0, 5.0], atol=1e-9)
    np.testing.assert_allclose(end[-1], [20.0, 0.0, -1.0], atol=1e-9)
    # block 5 itself: the cut at the program's F3000 from where the approach left the tool
    blk = part[part.block == n]
    assert int(blk.kind[0]) == LINE and float(blk.feed_mm_min[0]) == 3000.0
    np.testing.assert_allclose(blk.start[0], [20.0, 0.0, -1.0], atol=1e-9)
    np.testing.assert_allclose(blk.end[0], [20.0, 10.0, -1.0], atol=1e-9)


def test_restart_keeps_a_modal_rapid_after_the_plunge() -> None:
    """The plunge is a G1; a program in G0 at block N gets its G0 back (block N stays a rapid)."""
    from planning.nc import RAPID

    text = "G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F600\nG0 X10\nX20\nM30\n"
    plan = restart_plan(program_from_text(text, "g0.nc"), 4, "grbl")
    part = interpret("\n".join(plan.preamble + text.splitlines()[4:]) + "\n", dialect="grbl")
    blk = part[part.block == len(plan.preamble)]
    assert int(blk.kind[0]) == RAPID
    np.testing.assert_allclose(blk.end[0], [20.0, 0.0, -1.0], atol=1e-9)


def test_restart_clearance_and_plunge_refused_or_given() -> None:
    from rig.dnc import DncError

    no_rapid = "G21 G90\nG1 X0 Y0 Z-1 F600\nG1 X10 F3000\nG1 X20\nM30\n"
    prog = program_from_text(no_rapid, "nr.nc")
    with pytest.raises(DncError, match="no rapid move before that block.*--safe-z"):
        restart_plan(prog, 3, "fanuc")
    plan = restart_plan(prog, 3, "fanuc", safe_z_mm=10.0)
    assert "G90 G0 Z10" in plan.preamble and "G1 Z-1 F600" in plan.preamble
    assert "--safe-z" in plan.notes[0]
    no_plunge = "G21 G90\nG0 X0 Y0 Z5\nG0 Z-1\nG1 X10 F3000\nG1 X20\nM30\n"
    prog = program_from_text(no_plunge, "np.nc")
    with pytest.raises(DncError, match="no Z-descending feed move.*--plunge-feed"):
        restart_plan(prog, 4, "grbl")
    plan = restart_plan(prog, 4, "grbl", plunge_feed_mm_min=250.0)
    assert plan.preamble[-4:] == ["X10 Y0", "G1 Z-1 F250", "F3000", "G90 G1"]
    assert "--plunge-feed" in plan.notes[1]
