"""Restart from block N (property): the preamble followed by blocks N.. moves exactly like the
whole program from block N on, whatever modal state N inherits."""

from __future__ import annotations

import numpy as np
from _dnc_helpers import ARCS as ARCS_BODY
from hypothesis import given, settings
from hypothesis import strategies as st

from planning.nc import interpret, state_at_block
from rig.dnc import program_from_text, restart_blocks

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
