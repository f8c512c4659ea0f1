"""What the GRBL streamer sends and refuses before the first byte: a Fanuc-style plan (O word,
long comments, M6) is refused with the full list of lines GRBL would answer error:N, nothing
reaching the controller; stripped of what GRBL does not need, the rest streams."""

from __future__ import annotations

import pytest
from _dnc_helpers import GRBL_LINE_B_S, grbl_cfg, grbl_texts

from rig.dnc import DncError, GrblStreamer, MemorySink, program_from_text
from rig.sim import SimClock, SimGrbl

COMMENT = "(" + "roughing pass, tool phi10 flat end mill, stock 100 x 60 x 30 mm " * 3 + ")"
PLAN = f"""%
O0001
{COMMENT}
G21 G90 G17 G54
T1 M6
S8000 M3
G0 X0 Y0 Z5
G1 Z-1 F300
N100 G1 X10 Y0 F600
G1 X10 Y10
T2 M6
G1 X0 Y10
G0 Z5
M5
M30
%
"""


def test_a_plan_with_m6_is_refused_whole_before_sending() -> None:
    prog = program_from_text(PLAN, "plan.nc")
    ctl = SimGrbl(clock=SimClock(10.0))
    with ctl:
        st = GrblStreamer(grbl_cfg(ctl.path), sink=MemorySink())
        with pytest.raises(DncError) as ei:
            st.send(prog)
        assert ctl.received == b""  # not one byte
    msg = str(ei.value)
    assert msg.startswith("plan.nc: GRBL 1.1h would refuse 2 line(s); nothing was sent")
    assert "plan.nc:5:4: M6: GRBL error:20" in msg and "plan.nc:11:4: M6: GRBL error:20" in msg
    assert st.sink.closed


def test_o_words_long_comments_and_n_words_are_stripped() -> None:
    text = PLAN.replace("T1 M6", "T1").replace("T2 M6", "T2")
    assert len(COMMENT) > 127  # would not even fit GRBL's receive buffer as written
    prog = program_from_text(text, "plan.nc")
    ctl = SimGrbl(clock=SimClock(10.0))
    with ctl:
        sink = MemorySink()
        res = GrblStreamer(grbl_cfg(ctl.path), sink=sink, clock=ctl.clock.now,
                           pace_bytes_per_s=GRBL_LINE_B_S * 10).send(prog)  # fmt: skip
    sent = grbl_texts(prog)
    assert sent[:3] == ["G21G90G17G54", "T1", "S8000M3"] and "G1X10Y0F600" in sent
    assert res.ok and ctl.errors == [] and ctl.executed_texts() == sent
    assert res.transform.startswith("stripped comments") and res.bytes_stripped > len(COMMENT)
    assert [r.text for r in sink.rows] == sent
    assert any(k == "stream_start" and "stripped" in d for k, _, d in sink.events)


def test_as_written_the_long_comment_cannot_be_streamed() -> None:
    text = PLAN.replace("T1 M6", "T1").replace("T2 M6", "T2")
    prog = program_from_text(text, "plan.nc")
    st = GrblStreamer(grbl_cfg("loop://"), strip=False)
    with pytest.raises(DncError, match=r"plan.nc:2:1: O0001: GRBL error:20") as ei:
        st.send(prog)
    msg = str(ei.value)
    assert "plan.nc:3:1: GRBL cannot be streamed" in msg and msg.count("plan.nc:3:") == 1
