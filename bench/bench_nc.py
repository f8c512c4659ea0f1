"""Benchmark: parse + interpret a generated N-block NC program (default 1,000,000 blocks).

Prints blocks/s, segments, wall time, and the process memory growth during interpretation next to
the size of the resulting segment arrays (the streaming path should need little more than those).

    .venv/bin/python bench/bench_nc.py [--blocks 1000000] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from planning.nc import interpret_file


def write_program(path: Path, n_blocks: int, seed: int = 1) -> None:
    """A zig-zag/contour mix: numbered G1 lines, G2/G3 by IJK and by R, rapids, comments."""
    rng = np.random.default_rng(seed)
    xs = np.round(rng.uniform(-100, 100, n_blocks), 3)
    ys = np.round(rng.uniform(-100, 100, n_blocks), 3)
    with open(path, "w") as fh:
        fh.write(
            "%\nO1234 (BENCH)\nN1 G21 G90 G17 G94 G54\nN2 T1 M6\nN3 S6000 M3 M8\nG0 X0 Y0 Z5\n"
        )
        fh.write("G1 Z-1 F500\n")
        x, y = 0.0, 0.0
        n = 7
        for i in range(n - 1, n_blocks - 2):
            k = i % 10
            if k == 3:  # semicircle by IJK
                fh.write(f"N{i} G2 X{x + 10:.3f} Y{y:.3f} I5. J0.\n")
                x += 10
            elif k == 6:  # quarter by R
                fh.write(f"G3 X{x - 5:.3f} Y{y + 5:.3f} R5. (ARC)\n")
                x, y = x - 5, y + 5
            elif k == 8:
                fh.write("G0 Z2.\n")
            elif k == 9:
                fh.write("G1 Z-1. F300\n")
            else:
                x, y = xs[i], ys[i]
                if k == 0:
                    fh.write(f"N{i} G1 X{x:.3f} Y{y:.3f} F{800 + (i % 7) * 50}\n")
                elif k == 1:
                    fh.write(f"g1x{x:.3f}y{y:.3f}\n")
                elif k in (4, 7):
                    fh.write(f"G1 X{x:.3f} Y{y:.3f}\n")
                else:
                    fh.write(f"X{x:.3f} Y{y:.3f} ; plain\n")
        fh.write("M30\n%\n")


def rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--blocks", type=int, default=1_000_000)
    ap.add_argument("--profile", action="store_true", help="cProfile the run (slower)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.nc"
        t0 = time.perf_counter()
        write_program(path, args.blocks)
        t_gen = time.perf_counter() - t0
        n_lines = sum(1 for _ in open(path))
        size_mb = path.stat().st_size / 1e6
        rss0 = rss_mb()
        t0 = time.perf_counter()
        c0 = time.process_time()
        if args.profile:
            prof = cProfile.Profile()
            motion = prof.runcall(interpret_file, path)
        else:
            motion = interpret_file(path)
        dt = time.perf_counter() - t0
        cpu = time.process_time() - c0
        rss1 = rss_mb()
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    arrays_mb = sum(getattr(motion, f).nbytes for f in motion.__dataclass_fields__) / 1e6
    print(f"program: {n_lines} blocks, {size_mb:.1f} MB (generated in {t_gen:.1f} s)")
    print(f"parse + interpret: {dt:.2f} s, {n_lines / dt:,.0f} blocks/s, {len(motion)} segments")
    print(
        f"CPU time {cpu:.2f} s ({n_lines / cpu:,.0f} blocks/s of CPU; wall > CPU means the "
        f"machine was shared), load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    )
    print(
        f"memory: RSS grew {rss1 - rss0:.0f} MB during interpretation; segment arrays "
        f"{arrays_mb:.0f} MB; peak RSS {peak:.0f} MB"
    )
    # Machining time with acceleration (planning.nc.accel): look-ahead passes over all segments.
    from planning.nc import segment_time_s
    from planning.nc.accel import accel_segment_time_s

    plain = segment_time_s(motion)
    accel_segment_time_s(motion[:10], 2000.0, 0.01, plain[:10])  # numba compile / cache load
    t0 = time.perf_counter()
    t_acc = accel_segment_time_s(motion, 2000.0, 0.01, plain)
    dt = time.perf_counter() - t0
    print(
        f"time with acceleration (2000 mm/s^2, 0.01 mm): {dt:.2f} s, {len(motion) / dt:,.0f} "
        f"segments/s; {t_acc.sum() / 60:.1f} min against {plain.sum() / 60:.1f} min at the feeds"
    )
    if args.profile:
        pstats.Stats(prof).sort_stats("tottime").print_stats(12)


if __name__ == "__main__":
    main()
