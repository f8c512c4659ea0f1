"""Block timing through feed holds (issue 31, item 6): the run file's block table and
``Run.executing_block()`` follow the controller's own record, not the streamer's estimate.

A feed hold of 0.5, 2 and 7 simulated s is pressed while the cutting block runs (the simulated
controller's panel button, as an operator would) and released by cycle start. The reference is
the simulated controller's own list of executed blocks (:attr:`SimControllerBase.executed`, the
same object that ran the motion the samples were computed from), not anything the run writer or
the streamer computed.
"""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from analysis.runs import file as rf
from rig.campaign import load_campaign, run_campaign
from rig.campaign.run import StopRequest
from rig.sim.session import SimSession

DATA = Path(__file__).parent / "data" / "campaign"
CUT = "N70 G1 X"  # the cutting block of the quick campaign's face-milling pass
WAIT_WALL_S = 60.0  # deadline of every wait here (a loaded host is slow, never this slow)


def _config(tmp_path: Path) -> Path:
    text = (DATA / "quick.toml").read_text()
    text = text.replace('"OUT"', json.dumps(str(tmp_path / "out"))).replace("FAULTS", "")
    p = tmp_path / "quick.toml"
    p.write_text(text)
    return p


class _Holding:
    """A session factory whose session feed-holds the cutting block ``lead_s`` simulated s after
    it started, for ``hold_s`` simulated s, then presses cycle start."""

    def __init__(self, hold_s: float, lead_s: float = 0.05, stop: StopRequest | None = None
                 ) -> None:  # fmt: skip
        self.hold_s, self.lead_s, self.stop = hold_s, lead_s, stop  # stop: abort, not resume
        self.session: SimSession | None = None
        self.held_at: float | None = None
        self.resumed_at: float | None = None
        self.failed = ""
        self.writer = None  # the run's writer, once started

    def __call__(self, campaign, plan, run_index):  # noqa: ANN001, ANN204
        s = SimSession(campaign, plan, run_index)
        self.session = s
        start = s.start

        def start_and_hold(program, writer):  # noqa: ANN001, ANN202
            start(program, writer)
            self.writer = writer
            threading.Thread(target=self._hold, args=(s,), daemon=True).start()

        s.start = start_and_hold  # type: ignore[method-assign]
        return s

    def _hold(self, s: SimSession) -> None:
        ctl, clk = s.controller, s.sim_clock
        deadline = time.monotonic() + WAIT_WALL_S
        while time.monotonic() < deadline and not s._stop.is_set():
            cur = ctl._cur
            if cur is not None and cur.text.startswith(CUT):
                t_hold = ctl._block_t0 + self.lead_s
                if not clk.sleep_until(t_hold, s._stop):
                    break
                ctl.feed_hold()
                self.held_at = ctl._hold_t
                if not clk.sleep_until(self.held_at + self.hold_s, s._stop):
                    break
                if self.stop is not None:  # held from the console (recorded), then aborted
                    self.writer.event(rf.EV_PAUSE, "console: feed hold", time_s=self.held_at)
                    self.stop.request(kill=True, source="console (client test)")
                    return
                ctl.cycle_start()
                self.resumed_at = clk.now()
                return
            time.sleep(0.001)
        self.failed = "the cutting block never ran"


def _run_with_hold(tmp_path: Path, hold_s: float) -> tuple[rf.Run, _Holding, list]:
    holder = _Holding(hold_s)
    res = run_campaign(
        load_campaign(_config(tmp_path)), progress=False, session_factory=holder,
        only=lambda t: t.index == 0,
    )  # fmt: skip
    assert not holder.failed and holder.resumed_at is not None, holder.failed
    r = res.runs[0]
    assert r.status == "success", r.reason
    assert holder.session is not None
    executed = list(holder.session.controller.executed)
    return rf.load_run(r.file), holder, executed


@pytest.mark.parametrize("hold_s", [0.5, 2.0, 7.0])
def test_block_table_follows_the_controller_through_a_feed_hold(
    tmp_path: Path, hold_s: float
) -> None:
    run, holder, executed = _run_with_hold(tmp_path, hold_s)
    assert holder.held_at is not None and holder.resumed_at is not None
    blocks = run.blocks
    assert len(executed) == len(blocks)
    # every block's start is the controller's, to the bit, and its end is the next one's start
    # wherever the controller ran them back to back
    exec_s = blocks["exec_s"].to_numpy()
    starts = np.array([b.t_start_s for b in executed])
    ends = np.array([b.t_end_s for b in executed])
    assert np.array_equal(exec_s, starts)
    # a block starts when the one before it ended, or later (the first blocks wait for their
    # bytes at 9600 baud)
    assert np.all(starts[1:] >= ends[:-1])
    # the hold lies inside the cutting block's record, and the block after it starts after it
    k = next(i for i, b in enumerate(executed) if b.text.startswith(CUT))
    assert starts[k] < holder.held_at and ends[k] > holder.resumed_at
    assert ends[k] - starts[k] > hold_s  # the hold is part of the block's time
    # force samples during the hold are tied to the held block, and every sample of a block's
    # span to that block
    t = run.time_s
    held = (t > holder.held_at) & (t < holder.resumed_at)
    assert held.sum() >= int(hold_s * run.rate_hz) - 2
    assert set(run.executing_block(t[held]).tolist()) == {int(blocks["block"].iloc[k])}
    for i, b in enumerate(executed):
        inside = (t > b.t_start_s) & (t < b.t_end_s)
        if inside.any():
            got = set(run.executing_block(t[inside]).tolist())
            assert got == {int(blocks["block"].iloc[i])}, b.text
    # the notes carry the same record (printed to the microsecond)
    notes = run.events[run.events["message"].str.startswith("executed block")]["message"]
    for m, b in zip(notes, executed, strict=True):
        t0, t1 = (float(x) for x in m.split(" ", 3)[3].split(" s:")[0].split(".."))
        assert math.isclose(t0, b.t_start_s, abs_tol=1e-6)
        assert math.isclose(t1, b.t_end_s, abs_tol=1e-6)
    assert holder.session is not None
    predicted = {blk: t0 for blk, t0, _, _ in holder.session.streamer.executed_blocks()}
    err_before = max(abs(predicted[int(b)] - s) for b, s in zip(blocks["block"], starts)
                     if int(b) in predicted)  # fmt: skip
    print(f"hold {hold_s} s: streamer's estimate off by up to {err_before:.3f} s; table 0 s")


def test_a_run_aborted_in_a_feed_hold_keeps_the_held_block_s_start(tmp_path: Path) -> None:
    """Abort while the cutting block is held: the stop's reset drops that block from the
    controller's finished ones, but it ran, so the block table keeps its start, and the browsed
    toolpath (the console's, from the run file alone) ends where the tool was held: the estimate
    stops through the hold the run file records. (Without the start, a run aborted in its first
    cutting block browsed with an empty path: the Chromium tier's flake.)"""
    from rig.console.run_path import run_toolpath

    stop = StopRequest()
    holder = _Holding(0.5, lead_s=0.3, stop=stop)
    res = run_campaign(
        load_campaign(_config(tmp_path)), progress=False, session_factory=holder,
        only=lambda t: t.index == 0, stop=stop,
    )  # fmt: skip
    assert not holder.failed and holder.held_at is not None, holder.failed
    r = res.runs[0]
    assert r.status == "abort", (r.status, r.reason)
    assert holder.session is not None
    ctl = holder.session.controller
    assert not any(b.text.startswith(CUT) for b in ctl.executed)  # it never finished
    run = rf.load_run(r.file)
    blocks = run.blocks
    cut = blocks[blocks["text"].str.startswith(CUT)]
    assert len(cut) == 1 and np.isfinite(cut["exec_s"].iloc[0])
    assert cut["exec_s"].iloc[0] < holder.held_at  # started before the hold, 0.3 s before
    path = run_toolpath(Path(r.file))
    trail = path["trail"]
    assert trail and trail[-1][0] > cut["exec_s"].iloc[0], trail[-3:]
    # the tool stood still from the hold to the end: the path ends where the controller held it
    assert np.allclose(trail[-1][1:4], ctl._pos, atol=2e-3), (trail[-1], ctl._pos)
    assert trail[-1][0] <= holder.held_at + 1e-3  # (the end's point: the hold's start)


def test_the_browsed_path_s_clock_stands_still_through_the_recorded_holds() -> None:
    """Held 2-5 s and from 7 s to the end (pause, resume, pause events): by hand, motion time
    runs 0-2, stands, runs 2-4 from 5 to 7 s, then stands."""
    from types import SimpleNamespace

    import pandas as pd

    from rig.console.run_path import _HoldClock

    events = pd.DataFrame({"kind": ["start", "pause", "resume", "note", "pause", "stop"],
                           "time_s": [0.0, 2.0, 5.0, 6.0, 7.0, 9.0]})  # fmt: skip
    clock = _HoldClock(SimpleNamespace(events=events))  # type: ignore[arg-type]
    t = np.array([1.0, 2.0, 3.0, 5.0, 6.0, 7.0, 9.0])
    assert clock.moving(t).tolist() == [1.0, 2.0, 2.0, 2.0, 3.0, 4.0, 4.0]
    assert [clock.run(m) for m in (1.0, 2.0, 2.5, 4.0)] == [1.0, 2.0, 5.5, 7.0]
