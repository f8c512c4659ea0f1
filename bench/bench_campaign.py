"""Speed of the simulated rig and of `cutlab demo`'s campaign. Prints figures; asserts nothing.

    .venv/bin/python bench/bench_campaign.py            # physics throughput + the demo campaign
    .venv/bin/python bench/bench_campaign.py --quick    # physics throughput only

Figures:
- physics: simulated machine samples per wall second (engagement + force model + modes +
  amplifier) for the seed 003 face mill at 10 kHz and the phi 30 ball end mill on a Z-map, and
  the real-time factor that allows at that rate;
- campaign: wall time of the facemill-ploughing campaign (23 cuts) and of its report, simulated
  seconds recorded per wall second, samples written, and the identification's largest error
  against the simulator's truth.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def _physics(tool_name: str, material: str, rate_hz: float, seconds: float) -> dict:
    from analysis.config import get_material, get_tool, load_rig
    from planning.stock import SteppedBlock
    from rig.sim import ExecutedSegment
    from rig.sim.machine import BlockStock, SignalSettings, SimMachine, ZMapStock

    tool = get_tool(tool_name)
    block = SteppedBlock(-30.0, 30.0, (0.0, 400.0), (0.0,))
    if tool.kind == "facemill":
        stock = BlockStock(block)
        rpm, feed, depth, y = 600.0, 141.6, 2.0, 0.0
    else:
        stock = ZMapStock(block.to_zmap(tool), tool)
        rpm, feed, depth, y = 2000.0, 1000.0, 0.7, 0.0
    m = SimMachine(tool, get_material(material), load_rig().dynamometer, stock, rate_hz,
                   SignalSettings())  # fmt: skip
    v = feed / 60.0
    x0 = -tool.diameter_mm / 2
    m.on_spindle(0.0, rpm)
    m.on_segment(ExecutedSegment(0.0, seconds, (x0, y, -depth), (x0 + v * seconds, y, -depth),
                                 rpm, 0, feed_mm_min=feed))  # fmt: skip
    block_n = int(rate_hz * 0.1)
    n_blocks = int(seconds / 0.1)
    t0 = time.perf_counter()
    for k in range(n_blocks):
        m.source(k * 0.1, block_n, rate_hz)
    wall = time.perf_counter() - t0
    sps = n_blocks * block_n / wall
    return {"tool": tool_name, "rate_hz": rate_hz, "samples_per_s": sps,
            "realtime_factor": sps / rate_hz}  # fmt: skip


def _campaign() -> dict:
    from analysis.runs import load_run
    from rig.campaign import load_campaign, run_campaign
    from rig.report import write_report

    c = load_campaign("facemill-ploughing")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = run_campaign(c, out_root=tmp, progress=False)
        t_run = time.perf_counter() - t0
        sim_s = samples = 0.0
        for r in res.runs:
            run = load_run(r.file)
            sim_s += run.duration_s
            samples += run.samples_stored
        t1 = time.perf_counter()
        rep = write_report(res.folder)
        t_rep = time.perf_counter() - t1
    fm = rep.summary["facemill-coefficients"]
    return {
        "runs": len(res.runs),
        "ok": res.ok,
        "campaign_wall_s": t_run,
        "report_wall_s": t_rep,
        "simulated_s": sim_s,
        "sim_s_per_wall_s": sim_s / t_run,
        "samples_per_channel": samples,
        "max_error_pct_seed003": fm.get("max_error_pct_seed003"),
        "validation_max_abs_error_pct": fm.get("validation_max_abs_error_pct"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="physics throughput only")
    args = ap.parse_args()
    load = os.getloadavg()[0]
    print(f"cores {os.cpu_count()}, load average {load:.1f}")
    for tool, mat in (("seed003-facemill", "al6061-t6"), ("phi30-ball", "gm241")):
        r = _physics(tool, mat, 10_000.0, 30.0)
        print(f"physics {r['tool']:>17} @ {r['rate_hz']:.0f} Hz: {r['samples_per_s']:,.0f} "
              f"samples/s per channel = {r['realtime_factor']:.0f}x real time")  # fmt: skip
    if args.quick:
        return
    r = _campaign()
    print(f"campaign facemill-ploughing: {r['runs']} runs ({'ok' if r['ok'] else 'NOT ok'}) in "
          f"{r['campaign_wall_s']:.1f} s wall + report {r['report_wall_s']:.1f} s; "
          f"{r['simulated_s']:.0f} simulated s recorded = {r['sim_s_per_wall_s']:.1f} sim s per "
          f"wall s; {r['samples_per_channel']:,.0f} samples per channel")  # fmt: skip
    worst = r["max_error_pct_seed003"]
    print(f"identification: largest error of the identified coefficients vs truth "
          f"{'none identified' if worst is None else f'{worst:.2f} %'}; "
          f"validation mean-force error "
          f"{r['validation_max_abs_error_pct']:.2f} %")  # fmt: skip


if __name__ == "__main__":
    main()
