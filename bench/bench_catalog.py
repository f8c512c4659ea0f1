"""Benchmark: the run catalogue (index, query) and identification over a query on dask.

Uses bench_identify's run files (--runs of them, 10^7 force samples each: 30 make the 3 x 10^8
the issue asks for; written once into --dir and reused) plus --small tiny run files, then prints:

- index speed: a cold index (every file read and hashed) and a warm one (nothing changed), in
  files/s; the cold one also in MB/s hashed;
- query time on the index, and on a copy grown to --rows rows (an archive's tens of thousands);
- identification throughput in force samples/s over the 10 files: fit_files one file after
  another (``analyze forces`` on the files), dask's synchronous, threaded and process
  schedulers and a LocalCluster of 2 single-thread process workers, each cold (no cache), with
  the peak memory of a worker; then the same query again (its fit stored) and a query over the
  same runs that fits again from the cached reductions (no force data read).

    .venv/bin/python bench/bench_catalog.py [--dir /tmp/cutlab_catalog_bench] [--runs 30]
        [--small 200] [--rows 20000]
"""

from __future__ import annotations

import argparse
import logging
import resource
import shutil
import sqlite3
import sys
import time
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_identify import write_runs  # noqa: E402

from analysis.catalog import INDEX_NAME, fit_catalog, query_runs, update_index  # noqa: E402
from analysis.config import load_rig  # noqa: E402
from analysis.identify import fit_files  # noqa: E402
from analysis.runs import SAMPLE_FORMAT_VOLTS  # noqa: E402
from rig.daq import Calibration, DaqInfo  # noqa: E402
from rig.log import RunWriter  # noqa: E402

WHERE = "tool == 'seed003-facemill' and depth_mm >= 0.5"


def write_small(folder: Path, n: int) -> None:
    """``n`` short run files (0.1 s at 10 kHz), as a campaign's many small runs."""
    folder.mkdir(parents=True, exist_ok=True)
    rig = load_rig()
    cal = Calibration.from_rig(rig)
    info = DaqInfo(device="Bench", physical_channels=("ai0", "ai1", "ai2"),
                   channel_names=tuple(c.name for c in rig.dynamometer.channels),
                   rate_hz=10_000.0, sample_format=SAMPLE_FORMAT_VOLTS, input_range_v=10.0,
                   block_samples=1000)  # fmt: skip
    rng = np.random.default_rng(1)
    for k in range(n):
        p = folder / f"{k:04d}-small.h5"
        if p.exists():
            continue
        w = RunWriter(p, info, cal, clock=lambda: 0.0, overwrite=True)
        w.on_start(info, 0.0)
        w.set_conditions({"campaign": "small", "tool": "phi30-ball", "material": "GM241",
                          "spindle_rpm": 2000.0, "fz_mm": 0.1 + 0.001 * k, "depth_mm": 0.5})
        w.put_block(0, rng.normal(size=(3, 1000)))
        w.close()


def timed(fn, *a, **k):
    t0 = time.perf_counter()
    out = fn(*a, **k)
    return out, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default="/tmp/cutlab_catalog_bench", help="folder for the run files")
    ap.add_argument("--runs", type=int, default=30, help="large run files (10^7 samples each)")
    ap.add_argument("--small", type=int, default=10_000, help="tiny run files to index as well")
    ap.add_argument("--rows", type=int, default=20_000, help="rows of the grown index")
    args = ap.parse_args()
    root = Path(args.dir)
    write_runs(root, args.runs)
    write_small(root / "small", args.small)
    index = root / INDEX_NAME
    index.unlink(missing_ok=True)
    shutil.rmtree(root / ".cutlab-catalog.cache", ignore_errors=True)
    mb = sum(p.stat().st_size for p in root.rglob("*.h5")) / 1e6

    cold, t_cold = timed(update_index, [root])
    warm, t_warm = timed(update_index, [root])
    n = cold["files"]
    print(f"index, cold                 : {n} files ({mb:.0f} MB) in {t_cold:.2f} s = "
          f"{n / t_cold:.0f} files/s, {mb / t_cold:.0f} MB/s read and hashed")
    print(f"index, warm (no change)     : {n} files in {t_warm:.3f} s = {n / t_warm:.0f} files/s")
    small = sorted((root / "small").glob("*.h5"))
    for p in small[:100]:
        with h5py.File(p, "r+") as f:  # changed: its content (so its hash), size or mtime
            f.attrs["bench_touch"] = time.time_ns()
    _, t_100 = timed(update_index, [root])
    print(f"index, 100 small files changed: {t_100:.3f} s")

    df, t_q = timed(query_runs, WHERE, index)
    print(f"query ({n} rows)            : {t_q * 1e3:.1f} ms -> {len(df)} runs")
    grown = root / "grown.sqlite"
    grown.unlink(missing_ok=True)
    with sqlite3.connect(index) as src, sqlite3.connect(grown) as dst:
        src.backup(dst)  # the index is in WAL mode: a file copy can miss its last pages
    with sqlite3.connect(grown) as con:
        cols = [r[1] for r in con.execute("PRAGMA table_info(runs)")]
        rows = con.execute("SELECT * FROM runs").fetchall()
        k = cols.index("path")
        extra = [tuple(f"copy{i}/{v}" if j == k else v for j, v in enumerate(rows[i % len(rows)]))
                 for i in range(args.rows - len(rows))]  # fmt: skip
        con.executemany(f"INSERT INTO runs VALUES ({', '.join('?' * len(cols))})", extra)
    dfg, t_g = timed(query_runs, WHERE, grown)
    print(f"query ({args.rows} rows)      : {t_g * 1e3:.1f} ms -> {len(dfg)} runs")
    grown.unlink()

    paths = list(df["file"])
    total = int(df["samples_stored"].sum()) * 3
    print(f"identification over         : {len(paths)} runs, {total:.3e} force samples")

    cache = root / ".cutlab-catalog.cache"

    def ident(label: str, scheduler: str | None, clear: str = "all") -> float:
        """Time one query; ``clear``: 'all' the cache, 'fit' the stored fits, '' nothing."""
        for entry in cache.glob("*.pkl" if clear == "all" else "fit-*.pkl" if clear else "-"):
            entry.unlink()
        cpu = time.process_time()
        out, t = timed(fit_catalog, root, WHERE, scheduler=scheduler)
        cpu = time.process_time() - cpu
        c = out["catalog"]
        print(f"  {label:30s}: {t:6.2f} s  {total / t / 1e6:6.1f} M samples/s  CPU here "
              f"{cpu:5.1f} s  (reduced {c['reduced']}, cached {c['cached']}, fit cached "
              f"{c['fit_cached']}; K_T {out['coefficients']['K_T_n_mm2']:.2f})")
        return t

    _, t = timed(fit_files, paths)
    print(f"  {'fit_files, one by one':26s}: {t:6.2f} s  {total / t / 1e6:5.1f} M samples/s  "
          "(analyze forces on the files)")
    ident("sync, cold", "sync")
    cold = ident("threads (the default), cold", None)
    ident("processes, cold", "processes")
    logging.getLogger("distributed").setLevel(logging.CRITICAL)  # workers left as it closes
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:  # fmt: skip
        ident("LocalCluster 2x1, cold", cluster.scheduler_address)
        with Client(cluster) as client:
            rss = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
        mb = ", ".join(f"{v / 1024:.0f}" for v in rss.values())  # ru_maxrss is in KiB
        print(f"  peak memory per worker        : {mb} MB")
    refit = ident("reductions cached, fit again", None, clear="fit")
    again = ident("the same query again", None, clear="")
    print(f"cached speed-up (default scheduler): the same query {cold / again:.0f}x, "
          f"reductions cached {cold / refit:.1f}x")


if __name__ == "__main__":
    main()
