"""Benchmark of the HDF5 run logger (issue 3): sustained zero-loss rate and overhead.

Prints two figures:

1. Overhead: the same float64 blocks written (a) by a bare h5py append loop (resize + write per
   block, same chunk shape, same file format) and (b) through ``RunWriter`` (copy into its pool,
   writer thread, chunk accumulator, SWMR flushes), interleaved in one process; the ratio (b)/(a)
   per repetition and its median. Target: <= 1.25.
2. Sustained rate: the simulated DAQ, paced by a SimClock running faster than real time, feeds a
   RunWriter exactly as in a recording (non-blocking ``on_block``; a full queue drops and records
   the block). Speeds are tried upwards for ``--probe-seconds`` each; the highest with zero loss is
   then held for ``--seconds`` (>= 60) of wall time, stepping down a speed if that longer run loses
   samples. Prints channels x samples/s (float64) per wall
   second and the samples lost. Target: >= 10 MS/s with zero loss.

Usage: .venv/bin/python bench/bench_logger.py [--seconds 60] [--dir /tmp] [--json]
       .venv/bin/python bench/bench_logger.py --only-overhead --dir /dev/shm   # CPU cost only
Needs about rate x 8 bytes x seconds of free disk (10 MS/s for 60 s: 4.8 GB); files are deleted.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

from analysis.runs import file as rf
from rig.daq import DaqInfo
from rig.log import RunWriter
from rig.sim import SimClock, SimDaq


def _info(c: int, rate_hz: float, block: int) -> DaqInfo:
    names = tuple(f"sim/ai{i}" for i in range(c))
    return DaqInfo("bench", names, names, rate_hz, "volts_float64", 10.0, block)


def bare_loop(path: Path, blocks: np.ndarray, n_blocks: int, chunk_rows: int) -> float:
    """Seconds for the plain h5py append loop of ``n_blocks`` copies of ``blocks`` (c, n)."""
    c, n = blocks.shape
    t = time.perf_counter()
    with h5py.File(path, "w", libver="latest") as f:
        ds = f.create_dataset(
            "x", shape=(0, c), maxshape=(None, c), chunks=(chunk_rows, c), dtype="f8"
        )
        for k in range(n_blocks):
            ds.resize(((k + 1) * n, c))
            ds[k * n : (k + 1) * n] = blocks.T
    dt = time.perf_counter() - t
    path.unlink()
    return dt


def logger_loop(path: Path, blocks: np.ndarray, n_blocks: int) -> tuple[float, int]:
    """Seconds for the same blocks through RunWriter (waiting for room, never dropping)."""
    c, n = blocks.shape
    info = _info(c, 1e6, n)
    t = time.perf_counter()
    # A short queue: with put_block nothing is dropped, and a deep pool would only add the
    # one-off cost of allocating it to the timing.
    w = RunWriter(path, info, queue_blocks=4, overwrite=True)
    w.on_start(info, 0.0)
    for k in range(n_blocks):
        w.put_block(k * n, blocks)
    stats = w.close()
    dt = time.perf_counter() - t
    path.unlink()
    return dt, stats.samples_written


def overhead(folder: Path, channels: int, reps: int, total_mb: float) -> dict:
    n = 100_000
    blocks = np.random.default_rng(0).normal(size=(channels, n))
    n_blocks = max(1, int(total_mb * 1e6 / blocks.nbytes))
    probe = RunWriter(folder / "probe.h5", _info(channels, 1e6, n), overwrite=True)
    chunk_rows = probe.chunk_rows  # the same chunk shape as the logger's
    probe.close()
    (folder / "probe.h5").unlink()
    bare_loop(folder / "warm.h5", blocks, 2, chunk_rows)  # warm-up, untimed
    logger_loop(folder / "warm.h5", blocks, 2)
    ratios, bare_s, log_s = [], [], []
    for r in range(reps):
        b = bare_loop(folder / "bare.h5", blocks, n_blocks, chunk_rows)
        lg, written = logger_loop(folder / "log.h5", blocks, n_blocks)
        assert written == n_blocks * n
        bare_s.append(b)
        log_s.append(lg)
        ratios.append(lg / b)
        mb = blocks.nbytes * n_blocks / 1e6
        print(
            f"  overhead rep {r + 1}: {mb:.0f} MB, bare h5py {b:.2f} s ({mb / b:.0f} MB/s), "
            f"RunWriter {lg:.2f} s ({mb / lg:.0f} MB/s), ratio {lg / b:.2f}",
            file=sys.stderr,
            flush=True,
        )
    return {
        "megabytes_per_rep": blocks.nbytes * n_blocks / 1e6,
        "bare_s": bare_s,
        "logger_s": log_s,
        "ratios": ratios,
        "median_ratio": statistics.median(ratios),
        "ratio_of_totals": sum(log_s) / sum(bare_s),
        "ratio_of_best": min(log_s) / min(bare_s),
    }


def sustained(
    folder: Path, channels: int, rate_hz: float, speed: float, wall_s: float, queue_blocks: int
) -> dict:
    """One paced recording: the sim DAQ at ``speed`` x real time for ``wall_s`` wall seconds."""
    block = int(rate_hz * 0.1)
    pattern = np.random.default_rng(1).normal(0, 1.0, (channels, block))

    def source(t0_s: float, n: int, r: float) -> np.ndarray:
        return pattern[:, :n]

    clock = SimClock(speed)
    daq = SimDaq(
        source,
        rate_hz=rate_hz,
        channels=tuple(f"sim/ai{i}" for i in range(channels)),
        clock=clock,
        read_interval_s=0.1,
        seconds=wall_s * speed,
        sim_saturate=False,
    )
    path = folder / "sustained.h5"
    w = RunWriter(path, daq.info, clock=clock.now, queue_blocks=queue_blocks, overwrite=True)
    t = time.perf_counter()
    daq.run(w)
    stats = w.close()
    wall = time.perf_counter() - t
    run = rf.load_run(path, samples=False)
    path.unlink()
    acquired = daq.samples_acquired
    lost = stats.samples_dropped + stats.samples_missing
    assert run.samples_stored == stats.samples_written
    return {
        "channels": channels,
        "rate_hz": rate_hz,
        "speed": speed,
        "wall_s": wall,
        "samples_per_channel": acquired,
        "aggregate_ms_per_s": channels * acquired / wall / 1e6,
        "faster_than_real_time": acquired / rate_hz / wall,
        "samples_lost": lost,
        "queue_full_events": int((run.events["kind"] == "queue_full").sum()),
        "max_queue_depth": stats.max_queue_depth,
        "queue_blocks": queue_blocks,
        "max_write_s": stats.max_write_s,
        "max_flush_s": stats.max_flush_s,
        "gigabytes": channels * acquired * 8 / 1e9,
    }


def describe(r: dict) -> str:
    """One line per paced run."""
    return (
        f"{r['aggregate_ms_per_s']:.1f} MS/s for {r['wall_s']:.1f} s, lost {r['samples_lost']}, "
        f"max queue {r['max_queue_depth']}/{r['queue_blocks']} blocks, longest write "
        f"{r['max_write_s']:.2f} s, longest flush {r['max_flush_s']:.2f} s"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="wall s of the sustained run")
    ap.add_argument("--probe-seconds", type=float, default=15.0, help="wall s per probe")
    ap.add_argument("--channels", type=int, default=8)
    ap.add_argument("--rate-hz", type=float, default=250_000.0, help="per channel, Hz")
    ap.add_argument("--speeds", default="6,8,10,12.5", help="x real time, tried upwards")
    ap.add_argument("--queue-blocks", type=int, default=256, help="RunWriter queue, blocks")
    ap.add_argument("--reps", type=int, default=5, help="overhead repetitions")
    ap.add_argument("--overhead-mb", type=float, default=640.0)
    ap.add_argument("--dir", default=None, help="folder for the files (default: a temp dir)")
    ap.add_argument(
        "--only-overhead", action="store_true", help="skip the sustained run (e.g. --dir /dev/shm)"
    )
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    base = Path(args.dir) if args.dir else None
    with tempfile.TemporaryDirectory(dir=base, prefix="cutlab-bench-") as tmp:
        folder = Path(tmp)
        print("overhead: bare h5py append loop vs RunWriter, same blocks", file=sys.stderr)
        ov = overhead(folder, args.channels, args.reps, args.overhead_mb)
        probes = []
        passed: list[float] = []
        speeds = [] if args.only_overhead else [float(s) for s in args.speeds.split(",")]
        for speed in speeds:
            r = sustained(
                folder, args.channels, args.rate_hz, speed, args.probe_seconds, args.queue_blocks
            )
            probes.append(r)
            print(
                f"  probe x{speed:g}: {describe(r)}",
                file=sys.stderr,
                flush=True,
            )
            if r["samples_lost"]:
                break
            passed.append(speed)
        # Hold the fastest probed speed for the full time; if it loses samples over the longer
        # run (disk write-back throttling shows up late), step down.
        final, attempts = None, []
        for speed in reversed(passed):
            print(f"sustained: x{speed:g} for {args.seconds:g} s", file=sys.stderr, flush=True)
            r = sustained(
                folder, args.channels, args.rate_hz, speed, args.seconds, args.queue_blocks
            )
            attempts.append(r)
            print(
                f"  x{speed:g}: {describe(r)}",
                file=sys.stderr,
                flush=True,
            )
            if r["samples_lost"] == 0:
                final = r
                break
    out = {
        "overhead": ov,
        "probes": probes,
        "attempts": attempts,
        "sustained": final,
        "cpus": os.cpu_count(),
    }
    if args.json:
        json.dump(out, sys.stdout, indent=2)
        print()
        return 0
    print(f"logger overhead vs bare h5py loop: median ratio {ov['median_ratio']:.2f}x "
          f"(per rep {', '.join(f'{x:.2f}' for x in ov['ratios'])}; ratio of totals "
          f"{ov['ratio_of_totals']:.2f}x; best-of-{len(ov['ratios'])} ratio "
          f"{ov['ratio_of_best']:.2f}x; target <= 1.25x)")  # fmt: skip
    if final is None:
        print("sustained: no speed ran without loss for the full time")
    else:
        print(f"sustained zero-loss logging: {final['aggregate_ms_per_s']:.1f} MS/s float64 "
              f"({final['channels']} channels x {final['rate_hz']:.0f} Hz x "
              f"{final['faster_than_real_time']:.2f} real time) for {final['wall_s']:.1f} s, "
              f"{final['gigabytes']:.1f} GB, samples lost {final['samples_lost']} "
              f"(target >= 10 MS/s, 0 lost)")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
