"""Benchmark: seed 003 identification over 10^8 force samples streamed from HDF5 run files.

Writes (once; reused while they exist) 10 run files of 3.34 M samples x 3 channels each with
``rig.log.writer.RunWriter`` — face milling at depths 0.5..3.0 mm with seed 003's setup, Table 2's
modes, 2 % noise, an offset — then times the identification: each file is streamed in chunks
through ``analysis.runs.file.load_run`` windows (two passes: per-revolution statistics, then the
synchronous average) and the fit runs on the averages. Prints samples, wall time, throughput,
peak traced memory of the identification, the chunk size, and the coefficients' errors.

    .venv/bin/python bench/bench_identify.py [--dir /tmp/cutlab_bench] [--chunk 1048576]
"""

from __future__ import annotations

import argparse
import time
import tracemalloc
from pathlib import Path

import numpy as np

from analysis.config import get_material, get_tool, load_rig
from analysis.forces import FaceMillCut, facemill_forces
from analysis.identify import fit_facemill, reduce_run_file
from analysis.modal import DynamometerFilter
from analysis.runs import SAMPLE_FORMAT_VOLTS, load_run
from rig.daq import Calibration, DaqInfo
from rig.log import RunWriter

RATE_HZ = 50_000.0
RPM = 600.0
SAMPLES = 3_340_000  # per channel and run: 10 runs x 3 channels x 3.34 M = 1.0e8
DEPTHS = np.linspace(0.5, 3.0, 10)
N_BINS = None  # default: 2500 bins of 2 samples each at 5000 samples per revolution


def write_runs(folder: Path, runs: int = len(DEPTHS)) -> list[Path]:
    """``runs`` run files at depths 0.5..3.0 mm in ``folder`` (written once, then reused)."""
    depths = np.linspace(0.5, 3.0, runs)
    rig = load_rig()
    tool = get_tool("seed003-facemill")
    coef = get_material("al6061-t6").facemill
    cal = Calibration.from_rig(rig)
    modes = DynamometerFilter.from_config(rig.dynamometer, RATE_HZ, crosstalk=False)
    spr = int(RATE_HZ * 60 / RPM)
    rng = np.random.default_rng(2026)
    paths = []
    folder.mkdir(parents=True, exist_ok=True)
    for k, d in enumerate(depths):
        p = folder / f"facemill_d{d:.3f}.h5"
        paths.append(p)
        if p.exists() and load_run(p, samples=False).samples_stored == SAMPLES:
            continue
        # One steady revolution through the modes, tiled; air before and after.
        theta = 2 * np.pi * np.arange(spr) / spr
        wave = facemill_forces(theta, tool, coef, FaceMillCut(0.236, float(d), 100.0))
        wave = modes.periodic_response(wave, 60 / RPM)
        peak = float(np.linalg.norm(wave, axis=1).max())
        offset = rng.normal(0, 5, 3)
        info = DaqInfo(
            device="Bench", physical_channels=("ai0", "ai1", "ai2"),
            channel_names=tuple(c.name for c in rig.dynamometer.channels), rate_hz=RATE_HZ,
            sample_format=SAMPLE_FORMAT_VOLTS, input_range_v=10.0, block_samples=1 << 16,
        )  # fmt: skip
        w = RunWriter(p, info, cal, clock=lambda: 0.0, overwrite=True)
        w.on_start(info, 0.0)
        w.set_conditions({"tool": "seed003-facemill", "spindle_rpm": RPM, "fz_mm": 0.236,
                          "depth_mm": float(d), "width_mm": 100.0})  # fmt: skip
        air = int(0.5 * RATE_HZ)
        shift = int(rng.integers(spr))
        for a in range(0, SAMPLES, 1 << 16):
            b = min(a + (1 << 16), SAMPLES)
            idx = np.arange(a, b)
            f = wave[(idx + shift) % spr]
            f[(idx < air) | (idx >= SAMPLES - air)] = 0.0
            f = f + offset + rng.normal(0, 0.02 * peak, f.shape)
            w.put_block(a, cal.volts_from_force(f).T.copy())
        w.close()
        print(f"wrote {p} ({k + 1}/{len(depths)})", flush=True)
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default="/tmp/cutlab_bench", help="folder for the run files")
    ap.add_argument("--chunk", type=int, default=1 << 19, help="samples per chunk")
    args = ap.parse_args()
    paths = write_runs(Path(args.dir))
    tool = get_tool("seed003-facemill")
    true = get_material("al6061-t6").facemill
    dyno = load_rig().dynamometer
    total = sum(load_run(p, samples=False).samples_stored for p in paths) * 3
    # Timing without tracemalloc (it slows every numpy allocation), then memory with it.
    c0, t0 = time.process_time(), time.perf_counter()
    avgs = [reduce_run_file(p, 1, n_bins=N_BINS, chunk_samples=args.chunk) for p in paths]
    t1 = time.perf_counter()
    fit = fit_facemill(avgs, tool, dyno)
    t2, c2 = time.perf_counter(), time.process_time()
    tracemalloc.start()
    reduce_run_file(paths[0], 1, n_bins=N_BINS, chunk_samples=args.chunk)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"force samples streamed      : {total:.3e} (x2 passes)")
    print(f"chunk                       : {args.chunk} samples x 3 channels "
          f"({args.chunk * 3 * 8 / 1e6:.1f} MB as float64)")  # fmt: skip
    print(f"reduce (stream + average)   : {t1 - t0:.2f} s")
    print(f"fit (phase search + LSQ)    : {t2 - t1:.2f} s")
    print(f"identification total        : {t2 - t0:.2f} s  ({total / (t2 - t0) / 1e6:.1f} M "
          "samples/s)")  # fmt: skip
    print(f"CPU time of this process    : {c2 - c0:.2f} s (the machine is shared: wall >= CPU)")
    print(f"peak traced memory, 1 run   : {peak / 1e6:.1f} MB (the chunk and the loader's copies)")
    print(f"fit                         : {fit.success} {fit.message}")
    if fit.success:
        for name in ("K_T_n_mm2", "K_R", "P_T_n_mm", "P_R_n_mm", "K_A", "P_A_n_mm"):
            got, want = getattr(fit.coefficients, name), getattr(true, name)
            err = 100 * (got / want - 1)
            print(f"  {name:10s} {got:9.4f}  true {want:9.4f}  error {err:+.2f} %")


if __name__ == "__main__":
    main()
