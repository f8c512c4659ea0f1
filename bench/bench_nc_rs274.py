"""Benchmark: cutlab's NC commands side by side with LinuxCNC's ``rs274`` (issue 16, item 5).

Generates, in a temporary folder, 1 M random ``G1 X.. Y..`` blocks, 200 k mixed arcs (G2/G3 by
I J and by R between G1 moves) and a 50 MB single-line file, then runs on each ``rs274 -g FILE``
(skipped when /usr/bin/rs274 is absent), ``cutlab nc check FILE --json``, ``cutlab nc motions
FILE --csv -o OUT`` and the streaming API (:func:`planning.nc.run.iter_motion_chunks` with
:class:`planning.nc.stats.StreamStats`, and with :func:`planning.nc.table.write_motion_csv`),
each as its own process; prints wall time, CPU time (user + system: steadier than the wall
time on a shared machine), peak RSS (the child's ``ru_maxrss``) and the ratios to rs274.

    .venv/bin/python bench/bench_nc_rs274.py [--blocks 1000000] [--arcs 200000] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RS274 = shutil.which("rs274") or "/usr/bin/rs274"
CUTLAB = str(ROOT / ".venv" / "bin" / "cutlab")
PY = sys.executable
# The children run with their bytecode cached, as an installed package does: with
# PYTHONDONTWRITEBYTECODE set and no __pycache__, every run would compile its modules again
# (~40 ms). main() points the cache into its temporary folder and warms it.
CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}

STREAM_CHECK = """
import json, sys
from planning.nc.interpreter import Interpreter
from planning.nc.run import iter_motion_chunks
from planning.nc.stats import StreamStats
from planning.nc.errors import NCError
path = sys.argv[1]
it = Interpreter(None, file=path)
acc = StreamStats(None)
try:
    for part in iter_motion_chunks(__import__("pathlib").Path(path), interpreter=it):
        acc.add(part)
except NCError as exc:
    print(exc, file=sys.stderr); sys.exit(2)
st = acc.result()
print(json.dumps({"blocks": it.blocks_seen, "motions": st.segments, "time_s": st.time_s}))
"""
STREAM_CSV = """
import sys
from pathlib import Path
from planning.nc.run import file_mentions_rotary, iter_motion_chunks
from planning.nc.table import write_motion_csv
path = Path(sys.argv[1])
with open(sys.argv[2], "w") as fh:
    write_motion_csv(iter_motion_chunks(path), fh, rotary=file_mentions_rotary(path))
"""


def write_lines(path: Path, n: int, seed: int = 1) -> None:
    rng = np.random.default_rng(seed)
    xy = np.round(rng.uniform(-100, 100, (n, 2)), 4)
    with open(path, "w") as fh:
        fh.write("G21 G90 G17 G94\nG1 F500\n")
        for k in range(0, n, 100_000):
            fh.write("".join(f"G1 X{x:.4f} Y{y:.4f}\n" for x, y in xy[k : k + 100_000].tolist()))
        fh.write("M2\n")


def arc_lines(n: int) -> list[str]:
    """Semicircles by I J, quarter arcs by R and lines, in a zig-zag that stays near the origin
    (also the program tests/test_nc_arcfast.py checks the arc fast path on)."""
    rows, x, y = ["G21 G90 G17 G94\n", "G0 X0 Y0 Z1\n", "G1 Z-1 F400\n"], 0.0, 0.0
    for i in range(n):
        k = i % 4
        if k == 0:
            d = 10.0 if (i // 4) % 2 == 0 else -10.0
            rows.append(f"G2 X{x + d:.3f} Y{y:.3f} I{d / 2:.3f} J0\n")
            x += d
        elif k == 1:
            rows.append(f"G3 X{x - 5:.3f} Y{y + 5:.3f} R5\n")
            x, y = x - 5, y + 5
        elif k == 2:
            rows.append(f"G1 X{x:.3f} Y{y - 5:.3f}\n")
            y -= 5
        else:
            rows.append(f"G1 X{x + 5:.3f} Y{y:.3f} F600\n")
            x += 5
    return rows + ["M2\n"]


def write_arcs(path: Path, n: int) -> None:
    path.write_text("".join(arc_lines(n)))


def write_one_line(path: Path, n_bytes: int) -> None:
    with open(path, "wb") as fh:
        chunk = b"G1X1Y2" * (1 << 16)
        for _ in range(n_bytes // len(chunk)):
            fh.write(chunk)


def run(cmd: list[str], timeout: float = 600) -> tuple[float, float, float, int]:
    """Wall time (s), CPU time (s, user + system), peak RSS (MB) and exit code of one child
    process. The peak comes from ``/usr/bin/time`` when there is one (a child forked from this
    process inherits its peak RSS in ``ru_maxrss``), else from ``os.wait4``."""
    timer = shutil.which("time") or "/usr/bin/time"
    use_time = os.access(timer, os.X_OK)
    with tempfile.NamedTemporaryFile("r", suffix=".rss") as rss:
        full = [timer, "-f", "%M", "-o", rss.name, *cmd] if use_time else cmd
        t = time.perf_counter()
        p = subprocess.Popen(full, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT,
                             env=CHILD_ENV)  # fmt: skip
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t
        cpu_s = usage.ru_utime + usage.ru_stime  # /usr/bin/time's own share is negligible
        peak_mb = usage.ru_maxrss / 1024.0
        if use_time:
            text = rss.read().split()
            peak_mb = int(text[-1]) / 1024.0 if text and text[-1].isdigit() else float("nan")
    err = p.stderr.read().decode(errors="replace").strip() if p.stderr else ""
    p.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code:
        last = [x for x in err.splitlines() if not x.startswith("Command exited")]
        print(f"    ({Path(cmd[0]).name} exit {code}: {last[-1] if last else ''})")
    return wall, cpu_s, peak_mb, code


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=1_000_000)
    ap.add_argument("--arcs", type=int, default=200_000)
    ap.add_argument("--line-mb", type=int, default=50)
    ap.add_argument("--keep", type=Path, help="write the programs here and keep them")
    args = ap.parse_args(argv)
    tmp = args.keep or Path(tempfile.mkdtemp(prefix="bench_nc_rs274_"))
    tmp.mkdir(parents=True, exist_ok=True)
    progs = {"lines": tmp / "lines.ngc", "arcs": tmp / "arcs.ngc", "one-line": tmp / "one.ngc"}
    write_lines(progs["lines"], args.blocks)
    write_arcs(progs["arcs"], args.arcs)
    write_one_line(progs["one-line"], args.line_mb << 20)
    have_rs274 = os.access(RS274, os.X_OK)
    CHILD_ENV["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
    warm = tmp / "warm.ngc"
    warm.write_text("G1 X1 F100\nM2\n")
    for cmd in ([CUTLAB, "nc", "check", str(warm)], [PY, "-c", STREAM_CHECK, str(warm)],
                [CUTLAB, "nc", "motions", str(warm), "--csv"], [PY, "-c", STREAM_CSV, str(warm),
                str(tmp / "warm.csv")]):  # fmt: skip
        subprocess.run(cmd, cwd=ROOT, env=CHILD_ENV, capture_output=True, check=False)
    out = tmp / "out.csv"
    print(
        f"{'program':9} {'command':18} {'rs274 s':>8} {'cutlab s':>9} {'ratio':>6} "
        f"{'cpu s':>6} {'cpu ratio':>9} {'peak MB':>8}"
    )
    try:
        for name, path in progs.items():
            ref = run([RS274, "-g", str(path)]) if have_rs274 and name != "one-line" else None
            if ref:
                print(f"{name:9} {'rs274 -g':18} {ref[0]:8.2f} {'':>9} {'':>6} {ref[1]:6.2f} "
                      f"{'':>9} {ref[2]:8.0f}")  # fmt: skip
            cmds = {
                "nc check --json": [CUTLAB, "nc", "check", str(path), "--json"],
                "stream check": [PY, "-c", STREAM_CHECK, str(path)],
            }
            if name != "one-line":
                cmds["nc motions --csv"] = [CUTLAB, "nc", "motions", str(path), "--csv", "-o",
                                            str(out)]  # fmt: skip
                cmds["stream csv"] = [PY, "-c", STREAM_CSV, str(path), str(out)]
            for label, cmd in cmds.items():
                wall, cpu_s, mb, code = run(cmd)
                ratio = f"{wall / ref[0]:6.2f}" if ref else f"{'':>6}"
                cpu_ratio = f"{cpu_s / ref[1]:9.2f}" if ref else f"{'':>9}"
                rs = f"{ref[0]:8.2f}" if ref else f"{'-':>8}"
                print(f"{name:9} {label:18} {rs} {wall:9.2f} {ratio} {cpu_s:6.2f} {cpu_ratio} "
                      f"{mb:8.0f}" + (f"  exit {code}" if code else ""))  # fmt: skip
    finally:
        if args.keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
