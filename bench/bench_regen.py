"""Benchmark: the regenerative twin (rig.sim._regen) against real time.

Seed 001's feed-sweep cut as the campaign runs it: a phi 30 ball end mill (the tool library's
modes, or 1150 Hz / zeta 0.03 / 2.5e7 N/m in x and y when it has none) slotting 0.3 mm deep in
GM241 at 2000 rpm and 1000 mm/min through a 40 mm block held as a Z-map, 16 axial slices, read
by the DAQ at 10 kHz in 0.1 s blocks. Prints the simulated seconds, the wall seconds, the ratio
(simulated / wall, and on CPU time, which a busy machine does not skew; the
issue asks for at least 5) and the internal steps per second of cut.

    .venv/bin/python bench/bench_regen.py [--rate 10000] [--seconds 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from analysis.config import ToolMode, get_material, get_tool, load_rig
from planning.stock import SteppedBlock
from rig.sim import ExecutedSegment
from rig.sim.machine import SignalSettings, SimMachine, ZMapStock


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=10_000.0, help="DAQ rate, Hz")
    ap.add_argument("--seconds", type=float, default=3.0, help="simulated s of cutting")
    args = ap.parse_args()
    tool = get_tool("phi30-ball")
    modes = tool.modes or tuple(
        ToolMode(axis=a, f_hz=1150.0, zeta=0.03, k_N_m=2.5e7) for a in ("x", "y")
    )
    rpm, feed, depth = 2000.0, 1000.0, 0.3
    block = SteppedBlock(-30.0, 30.0, (0.0, 40.0), (0.0,))
    machine = SimMachine(
        tool, get_material("gm241"), load_rig().dynamometer,
        ZMapStock(block.to_zmap(tool), tool), args.rate, SignalSettings(), tool_modes=modes,
    )  # fmt: skip
    x0 = -tool.radius_mm - 1.0
    x1 = x0 + feed / 60.0 * (args.seconds + 0.5)
    machine.on_segment(
        ExecutedSegment(0.0, (x1 - x0) / (feed / 60.0), (x0, 0.0, -depth), (x1, 0.0, -depth),
                        rpm, 0, feed_mm_min=feed)
    )  # fmt: skip
    n = int(round(0.1 * args.rate))
    reads = int(round(args.seconds / 0.1))
    machine.source(0.0, n, args.rate)  # compile the kernel outside the timing
    t0, c0 = time.perf_counter(), time.process_time()
    for k in range(1, reads + 1):
        machine.source(k * 0.1, n, args.rate)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    dt, _ = machine.regen._dt(rpm)
    sim_s = reads * 0.1
    print(f"simulated {sim_s:.1f} s at {args.rate:g} Hz in {wall:.2f} s wall: "
          f"{sim_s / wall:.1f} x real time ({sim_s / cpu:.1f} x on CPU time; "
          f"internal {1 / dt:,.0f} steps/s; "
          f"peak force {machine.peak_force_n:.0f} N; "
          f"tool at {np.round(machine.regen.displacement_mm() * 1e3, 2)} um)")  # fmt: skip


if __name__ == "__main__":
    main()
