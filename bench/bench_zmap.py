"""Benchmark: Z-map simulation + feed post-processing of a generated 100,000-block roughing program.

The program is a "3D drive" Z-level roughing (seed 001 Table 4's kind) of a dome in a 200 x 200 mm
block with a phi 10 flat end mill: levels 1 mm apart, zigzag passes 5 mm apart, 2 mm blocks, the
tool lifted over the dome (plus 0.5 mm allowance), so the cut changes from full slots to side cuts
to ramps over the island and air. Grid 0.25 mm (800 x 800 points).

Prints: blocks, pieces, grid, time of each stage, blocks/s and cells/s (grid points in the patches
the moves touched), peak memory, and the cycle-time change the post-processor gives with a seed 001
rule shaped like seed 001 Table 4 (programmed at a constant 400 mm/min; rule min 150, base 400
for a full slot at the level depth, max 1000 mm/min).

    .venv/bin/python bench/bench_zmap.py [--blocks 100000] [--spacing 0.25]
"""

from __future__ import annotations

import argparse
import math
import resource
import sys
import time
import tracemalloc

import numpy as np

from analysis.config import get_tool, load_machine
from analysis.rules import derive_rule, slot_load_percent
from planning.feed import FeedPostOptions, post_process
from planning.nc import Program, interpret
from planning.stock import ZMap, simulate_motion
from planning.stock import compiled as _numba


def dome_mm(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Part surface: a dome of radius 70 mm, 18 mm high, centred in the block, on a -20 floor."""
    r2 = (x - 100) ** 2 + (y - 100) ** 2
    return np.where(r2 < 70**2, -20 + 18 * np.sqrt(np.maximum(1 - r2 / 70**2, 0)), -20.0)


def roughing_program(blocks: int, step_mm: float = 5.0, block_mm: float = 2.0) -> tuple[str, float]:
    """Z-level zigzag roughing with ``blocks`` G1 blocks (about), 3D-drive lift over the dome.

    Returns the program text and the level depth, mm.
    """
    xs = np.arange(-6.0, 206.0 + 1e-9, block_mm)
    ys = np.arange(0.0, 200.0 + 1e-9, step_mm)
    per_level = len(xs) * len(ys)
    levels = max(1, math.ceil(blocks / per_level))
    dz = 20.0 / levels
    lines = ["%", "O5000 (bench: 3D-drive Z-level roughing, phi 10 flat)", "G21 G90 G17 G94"]
    lines += ["T2 M6", "S8000 M3", "G0 X-6. Y0. Z5.", "G1 Z0. F400"]
    n = 0
    for k in range(levels):
        z = -(k + 1) * dz
        for j, y in enumerate(ys):
            xrow = xs if j % 2 == 0 else xs[::-1]
            zz = np.maximum(z, dome_mm(xrow, np.full_like(xrow, y)) + 0.5)
            for x, zi in zip(xrow, zz):
                lines.append(f"X{x:.3f} Y{y:.3f} Z{zi:.3f}")
                n += 1
                if n >= blocks:
                    break
            if n >= blocks:
                break
        lines.append("G0 Z5.")
        lines.append("X-6. Y0.")
        lines.append("G1 F400")
        if n >= blocks:
            break
    lines += ["G0 Z50.", "M30", "%"]
    return "\n".join(lines) + "\n", dz


def patch_cells(p0: np.ndarray, p1: np.ndarray, r: float, s: float) -> float:
    """Grid points in the footprint patches of the pieces (what the kernel evaluates)."""
    w = (np.abs(p1[:, 0] - p0[:, 0]) + 2 * r) / s + 1
    h = (np.abs(p1[:, 1] - p0[:, 1]) + 2 * r) / s + 1
    return float(np.sum(np.floor(w) * np.floor(h)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=100_000)
    ap.add_argument("--spacing", type=float, default=0.25)
    args = ap.parse_args()

    tool = get_tool("phi10-flat")
    machine = load_machine("ace-h63")
    text, level_mm = roughing_program(args.blocks)
    rule = derive_rule("bench-rough", 150, 400, 1000, slot_load_percent("flat", 10, level_mm, 22))
    tw = time.perf_counter()
    _numba.warm_up()  # compile, or load the cached machine code
    print(
        f"kernel: {'numba (compiled)' if _numba.AVAILABLE else 'numpy'}; warm-up "
        f"{time.perf_counter() - tw:.2f} s (not counted below)"
    )
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

    t0 = time.perf_counter()
    prog = Program.parse(text, "bench.nc")
    motion = interpret(prog, machine, file="bench.nc")
    t1 = time.perf_counter()
    stock = ZMap.box(0, 200, 0, 200, -25, 0, args.spacing)
    tracemalloc.start()
    sim = simulate_motion(stock, tool, motion)
    t2 = time.perf_counter()
    sim_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    stock2 = ZMap.box(0, 200, 0, 200, -25, 0, args.spacing)
    t3 = time.perf_counter()
    res = post_process(prog, motion, tool, rule, stock2, machine, FeedPostOptions(min_piece_mm=5))
    t4 = time.perf_counter()
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

    nblk = len(prog)
    nseg = len(motion)
    ny, nx = stock.shape
    cells_sim = patch_cells(sim.piece_start_mm, sim.piece_end_mm, 5.0, args.spacing)
    cells_post = patch_cells(
        res.simulation.piece_start_mm, res.simulation.piece_end_mm, 5.0, args.spacing
    )
    print(f"program: {nblk} blocks, {nseg} motion segments, {len(text) / 1e6:.1f} MB text")
    print(f"grid: {nx} x {ny} points at {args.spacing} mm ({stock.heights_mm.nbytes / 1e6:.1f} MB)")
    print(f"parse + interpret:            {t1 - t0:7.3f} s  {nblk / (t1 - t0):10.0f} blocks/s")
    print(
        f"simulation (Z-map only):      {t2 - t1:7.3f} s  {nblk / (t2 - t1):10.0f} blocks/s  "
        f"{cells_sim / (t2 - t1) / 1e6:7.1f} M cells/s"
    )
    print(
        f"post-process (sim + loads + feeds + splits + write + re-interpret check): "
        f"{t4 - t3:7.3f} s  {nblk / (t4 - t3):10.0f} blocks/s  "
        f"{cells_post / (t4 - t3) / 1e6:7.1f} M cells/s  ({len(res.simulation.piece_removed_mm3)} "
        "pieces)"
    )
    total = (t1 - t0) + (t4 - t3)
    print(f"parse + interpret + post-process: {total:7.3f} s  {nblk / total:10.0f} blocks/s")
    per_piece = sum(
        a.nbytes for a in (sim.piece_start_mm, sim.piece_end_mm, sim.piece_removed_mm3,
                           sim.piece_depth_mm, sim.piece_segment)
    )  # fmt: skip
    print(
        f"simulation peak allocation {sim_peak / 1e6:.1f} MB (tracemalloc; time above includes "
        f"its overhead): grid {stock.heights_mm.nbytes / 1e6:.1f} MB untouched in size, results "
        f"{per_piece / 1e6:.1f} MB ({per_piece / len(sim.piece_segment):.0f} B per piece); "
        "no per-cell-per-move storage"
    )
    print(
        f"peak RSS growth, whole run (program text, blocks, motion, output program): "
        f"{(rss1 - rss0) / 1024:.0f} MB"
    )
    print(
        f"removed {sim.removed_total_mm3 / 1e3:.1f} cm^3; stock left "
        f"{stock.volume_mm3() / 1e3:.1f} cm^3; holder contacts {len(sim.contacts)}"
    )
    print(
        f"cycle time at constant 400 mm/min: {res.time_before_s / 60:.1f} min; adjusted: "
        f"{res.time_after_s / 60:.1f} min; change {-res.time_saved_pct:+.1f} % "
        f"({res.split_blocks} blocks split)"
    )
    before, after = res.load_rate_max()
    print(f"highest load x feed: constant {before:.0f}, adjusted {after:.0f} (% mm/min)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
