"""Benchmark: reading a big DynoWare export (issue 17): `cutlab data info` (parse only) and
`cutlab data import` (parse, map axes, write a run file) on a ~100 MB tab-separated,
decimal-comma export, each as its own process; prints wall time and MB/s.

    .venv/bin/python bench/bench_import.py [--mb 100] [--keep DIR]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CUTLAB = str(ROOT / ".venv" / "bin" / "cutlab")


def write_export(path: Path, mb: float, rate_hz: float = 10_000.0) -> None:
    """A DynoWare-style export of about ``mb`` MB: a header block, Time Fx Fy Fz, decimal comma."""
    row_bytes = 42  # "0,000100\t-12,345678\t..." with 3 channels
    n = int(mb * 1e6 / row_bytes)
    rng = np.random.default_rng(1)
    t = np.arange(n) / rate_hz
    f = 100 * np.sin(2 * np.pi * 200 * t)[:, None] + rng.normal(0, 2, (n, 3))
    with path.open("w", encoding="utf-8") as fh:
        fh.write(f"DynoWare:\tType 5697A1\nSampling rate:\t{rate_hz:g}\n\n")
        fh.write("Time\tFx\tFy\tFz\ns\tN\tN\tN\n")
        step = 200_000
        for a in range(0, n, step):
            block = np.column_stack([t[a:a + step], f[a:a + step]])
            text = "\n".join("\t".join(f"{v:.6f}" for v in row) for row in block)
            fh.write(text.replace(".", ",") + "\n")


def timed(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mb", type=float, default=100.0)
    ap.add_argument("--keep", default=None)
    args = ap.parse_args()
    d = Path(args.keep or tempfile.mkdtemp(prefix="bench_import_"))
    d.mkdir(parents=True, exist_ok=True)
    src = d / "big.txt"
    write_export(src, args.mb)
    size_mb = src.stat().st_size / 1e6
    print(f"export: {size_mb:.1f} MB, {sum(1 for _ in src.open()) - 5} samples")
    for name, cmd in (
        ("data info", [CUTLAB, "data", "info", str(src), "--json"]),
        ("data import", [CUTLAB, "data", "import", str(src), "-o", str(d / "runs"), "--force",
                         "--conditions", "spindle_rpm=6000", "fz_mm=0.05", "depth_mm=3",
                         "width_mm=25", "tool=phi10-flat", "mode=slot"]),
    ):  # fmt: skip
        s = timed(cmd)
        print(f"{name:12s} {s:6.2f} s  {size_mb / s:6.1f} MB/s")
    if not args.keep:
        shutil.rmtree(d)


if __name__ == "__main__":
    main()
