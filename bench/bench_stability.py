"""Benchmark: stability lobes of the Insperger benchmark (N = 2, Kt = 6e8, Kn = 2e8 N/m^2,
fn = 922 Hz, zeta = 0.011, m = 0.03993 kg), 200 speeds 5000-25000 rpm, by ZOA and SD, 1-DOF and
2-DOF (the same mode in x and y), slot and 5 % down milling; wall and process CPU time (the
machine is shared: CPU time is the steadier figure). Target: 200 speeds x 2-DOF in 2 s.
SD is the default, converged per speed (steps doubled until the limit moves by at most 1 %);
"sd30" is the fixed 30-step count the default used to be.
Then the convergence table: steps per tooth period vs the minimum critical depth and the median
and largest change of the limit against the finest discretisation, at 50 speeds, with the
default (converged) last.

    .venv/bin/python bench/bench_stability.py [--repeat 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np

from analysis.stability import StabilityCase, stability_lobes

K_N_M = 0.03993 * (2 * math.pi * 922.0) ** 2


def case(dof: int, ae: float, points: int = 200) -> StabilityCase:
    return StabilityCase(
        teeth=2, milling="down", radial_immersion=ae, kt_n_m2=6e8, kn_n_m2=2e8,
        f_hz=np.full(dof, 922.0), zeta=np.full(dof, 0.011), k_n_m=np.full(dof, K_N_M),
        direction=("x", "y")[:dof], rpm=np.linspace(5000, 25000, points),
        name=f"{dof}-DOF a/D={ae:g}",
    )  # fmt: skip


def timed(fn, repeat: int):
    best = (math.inf, math.inf, None)
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        best = min(
            best, (time.perf_counter() - w, time.process_time() - c, out), key=lambda b: b[0]
        )
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs per case (best is printed)")
    args = ap.parse_args()
    print("case                method  wall_s  cpu_s  min_depth_mm  at_rpm  flip_speeds")
    for dof in (1, 2):
        for ae in (1.0, 0.05):
            c = case(dof, ae)
            for method in ("zoa", "sd30", "sd"):
                steps = 30 if method == "sd30" else None
                how = "sd" if method == "sd30" else method
                w, cpu, lobes = timed(lambda: stability_lobes(c, how, steps), args.repeat)  # noqa: B023
                rpm, mm = lobes.minimum()
                flips = sum(k == "flip" for k in lobes.kind)
                print(f"{c.name:18s}  {method:6s}  {w:6.2f}  {cpu:5.2f}  {mm:12.4f}  {rpm:6.0f}"
                      f"  {flips:11d}")  # fmt: skip
    print("(zoa also runs sd: it checks for the flip lobes ZOA misses)")
    print("\nconvergence, 50 speeds: steps per tooth period vs the limit (ref: 120 steps)")
    print("case                steps  min_depth_mm  median_change  max_change  wall_s")
    for dof, ae in ((1, 1.0), (1, 0.05), (2, 1.0), (2, 0.05)):
        c = dataclasses.replace(case(dof, ae), rpm=np.linspace(5000, 25000, 50))
        ref = stability_lobes(c, "sd", 120).depth_limit_mm
        for m in (8, 15, 30, 60):
            t = time.perf_counter()
            got = stability_lobes(c, "sd", m).depth_limit_mm
            w = time.perf_counter() - t
            ok = np.isfinite(ref) & np.isfinite(got)
            ch = np.abs(got[ok] / ref[ok] - 1)
            print(f"{c.name:18s}  {m:5d}  {got.min():12.4f}  {np.median(ch):13.1e}"
                  f"  {ch.max():10.1e}  {w:6.2f}")  # fmt: skip
        print(f"{c.name:18s}  {120:5d}  {ref.min():12.4f}  {'(ref)':>13s}")
        t = time.perf_counter()
        conv = stability_lobes(c, "sd")
        w = time.perf_counter() - t
        ok = np.isfinite(ref) & np.isfinite(conv.depth_limit_mm)
        ch = np.abs(conv.depth_limit_mm[ok] / ref[ok] - 1)
        print(f"{c.name:18s}  {'conv':>5s}  {conv.depth_limit_mm.min():12.4f}  "
              f"{np.median(ch):13.1e}  {ch.max():10.1e}  {w:6.2f}  (steps "
              f"{conv.steps.min()}-{conv.steps.max()}, doubling check "
              f"{conv.convergence()['max_change_pct']:.2f} %)")  # fmt: skip


if __name__ == "__main__":
    main()
