"""Restart from block N (property): the preamble followed by blocks N.. moves exactly like the
whole program from block N on, whatever modal state N inherits."""

from __future__ import annotations

import numpy as np
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
