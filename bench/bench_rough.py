"""Benchmark: planning the shipped seed-000 part by each roughing method (seconds per method).

Each method runs on a fresh planner (so no method profits from sections another one cached),
timed by wall clock and by process CPU time (the machine is shared: CPU time is the steadier
figure). Also timed: the shared set-up (offset surface, cusp table), writing the NC program and the
Z-map check of the bisection program. Prints the path lengths and the comparisons the issue asks
for. Targets: bisection under 10 s, optimal under 60 s.

    .venv/bin/python bench/bench_rough.py [--part configs/parts/seed000-bump.toml] [--repeat 1]
"""

from __future__ import annotations

import argparse
import time

from analysis.config import REPO_ROOT
from planning._rough_gcode import MoveSettings, plan_motion, plan_program
from planning.part_config import load_part
from planning.rough_check import check_program
from planning.roughing import METHODS, RoughPlanner


def timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", default=str(REPO_ROOT / "configs/parts/seed000-bump.toml"))
    ap.add_argument("--repeat", type=int, default=1, help="runs per method (best is printed)")
    args = ap.parse_args()
    part = load_part(args.part)
    _, w, c = timed(lambda: RoughPlanner(part))
    print(
        f"part {part.config.name}: set-up (offset surface, cusp table) {w:.2f} s wall {c:.2f} s cpu"
    )
    plans, rows = {}, []
    for m in METHODS:
        best = None
        for _ in range(args.repeat):
            planner = RoughPlanner(part)
            if m == "optimal":
                # As the CLI does: the other methods' heights join the candidate grid (their time
                # is counted here too, so this is the full cost of getting the optimum).
                def run(planner=planner):
                    return planner.plan_all()["optimal"]
            else:

                def run(planner=planner, m=m):
                    return planner.plan(m)

            plan, w, c = timed(run)
            if best is None or w < best[1]:
                best = (plan, w, c)
        plans[m] = best[0]
        rows.append((m, best[1], best[2], best[0]))
    print(f"{'method':<10} {'wall_s':>7} {'cpu_s':>7} {'levels':>6} {'path_mm':>9} {'max_cusp':>8}")
    for m, w, c, p in rows:
        print(f"{m:<10} {w:7.2f} {c:7.2f} {len(p.levels):6d} {p.path_mm:9.1f} {p.max_cusp_mm:8.3f}")
    b = plans["bisection"].path_mm
    print(
        f"bisection shorter than equal: {100 * (1 - b / plans['equal'].path_mm):.1f} % (paper 34.4)"
    )
    print(
        f"bisection shorter than lee:   {100 * (1 - b / plans['lee'].path_mm):.1f} % (paper 11.0)"
    )
    o = plans["optimal"].path_mm
    print(f"optimal shorter than bisection: {100 * (1 - o / b):.1f} % ({b - o:.1f} mm)")
    planner = RoughPlanner(part)
    prog, w, c = timed(
        lambda: plan_program(plans["bisection"], part, plan_motion(plans["bisection"], part))
    )
    print(f"NC program (bisection): {len(prog.lines)} lines in {w:.2f} s wall {c:.2f} s cpu")
    st = part.config.stock
    for spacing in (1.0, 0.5):
        res, w, c = timed(
            lambda spacing=spacing: check_program(
                prog.text(), planner.offset_surface,
                (st.x_min_mm, st.x_max_mm, st.y_min_mm, st.y_max_mm, st.z_min_mm, st.z_max_mm),
                part.tool.radius_mm, part.config.rough.cusp_mm, MoveSettings.of(part).safe_z_mm,
                spacing_mm=spacing,
            )
        )  # fmt: skip
        print(
            f"Z-map check {spacing} mm: {w:.2f} s wall {c:.2f} s cpu; max left "
            f"{res.max_left_mm:.3f} mm, gouge {res.max_gouge_mm:.4f} mm, ok {res.ok}"
        )


if __name__ == "__main__":
    main()
