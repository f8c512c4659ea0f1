"""The simulated clock's gates: simulated time never passes a gate, never rewinds, and goes on
from the gate (no jump) once it is lifted (issue 31, item 10: a slow host makes a simulated run
take longer, never changes what happens in simulated time)."""

from __future__ import annotations

import threading
import time

from rig.sim.clock import SimClock


def _spin_wall(s: float) -> None:
    end = time.perf_counter() + s
    while time.perf_counter() < end:
        time.sleep(0.001)


def test_time_stands_at_the_lowest_gate_however_long_the_host_takes() -> None:
    clk = SimClock(1000.0, gates={"arm": 0.0})
    _spin_wall(0.02)  # 20 simulated s ungated
    assert clk.now() == 0.0
    clk.gate("arm", 0.25)
    clk.gate("line", 0.5)
    _spin_wall(0.02)
    assert clk.now() == 0.25
    assert clk.gated()


def test_a_lifted_gate_lets_time_go_on_from_it_without_a_jump() -> None:
    clk = SimClock(1.0, gates={"arm": 0.0})
    _spin_wall(0.05)  # 0.05 simulated s would have passed
    assert clk.now() == 0.0
    clk.gate("arm", None)
    t = clk.now()
    # from the gate: far less than the 0.05 s that passed while it held
    assert 0.0 <= t < 0.05


def test_a_gate_behind_the_present_holds_time_where_it_is() -> None:
    clk = SimClock(1000.0)
    _spin_wall(0.01)
    t1 = clk.now()
    clk.gate("late", t1 / 2)
    t2 = clk.now()
    assert t2 >= t1  # never rewinds
    _spin_wall(0.01)
    assert clk.now() == t2


def test_sleep_until_a_gated_time_waits_for_the_gate_and_honours_stop() -> None:
    clk = SimClock(1000.0, gates={"arm": 1.0})
    stop = threading.Event()
    out: list[bool] = []
    th = threading.Thread(target=lambda: out.append(clk.sleep_until(2.0, stop)))
    th.start()
    _spin_wall(0.02)
    assert not out and clk.now() == 1.0
    stop.set()
    th.join(timeout=5.0)
    assert out == [False]
    clk.gate("arm", None)
    assert clk.sleep_until(1.5)
    assert clk.now() >= 1.5
