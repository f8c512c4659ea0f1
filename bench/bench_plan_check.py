"""`plan check`'s predicted per-block force against the simulated rig's (issue 22). Prints
figures; asserts nothing (tests/test_plan_limits_vs_rig.py does).

    .venv/bin/python bench/bench_plan_check.py

The demo part's T1 blocks (data/programs/demo-part.nc, phi10-flat, al6061-t6, stock 80 x 60 x 20)
cut on the twin at 20 kHz; per block: the check's time-mean and peak resultant force against the
twin's force before the dynamometer, reduced per executing block, and the wall times.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main() -> None:
    import pandas as pd

    from tests.test_plan_limits_vs_rig import compare_demo, cutting_blocks

    t0 = time.perf_counter()
    table = compare_demo()
    wall_s = time.perf_counter() - t0
    with pd.option_context("display.width", 200, "display.float_format", "{:.1f}".format):
        print(table.to_string())
    cut = cutting_blocks(table)
    print(
        f"\nblocks that cut on the twin ({len(cut)} of {len(table)}; the plunge reads 0 N): "
        f"mean error {cut['mean_err_pct'].min():.1f} .. {cut['mean_err_pct'].max():.1f} %, "
        f"peak error {cut['peak_err_pct'].min():.1f} .. {cut['peak_err_pct'].max():.1f} %"
    )
    print(f"wall time (check + twin at 20 kHz, {len(table)} blocks): {wall_s:.1f} s")


if __name__ == "__main__":
    main()
