"""Benchmark: the HDF5 logger's throughput without and with the live console open.

"Without": blocks go straight into :class:`rig.log.RunWriter` as fast as it takes them. "With":
the same blocks go through the console's tee (the writer first, then the shared-memory ring)
while the console server runs in its own process and a websocket client (another process,
standing in for the browser) takes its 25 frames a second. Alternating trials; prints the
median samples/s of each, the ratio (the issue asks for at least 0.95), the frames a second the
client got, and the page's load size.

    .venv/bin/python bench/bench_console.py [--samples 2000000] [--trials 3]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from analysis.runs import file as rf
from rig.campaign import load_campaign
from rig.console.live import LIVE_FILE, LiveCampaign, start_server, stop_server
from rig.console.server import STATIC
from rig.daq import DaqInfo
from rig.log import RunWriter

ROOT = Path(__file__).resolve().parent.parent
BLOCK = 2000  # a DAQ block: 0.1 s at 20 kHz
CLIENT = """
import json, signal, sys, time
from websockets.sync.client import connect
n, t_end, t0 = 0, time.monotonic() + float(sys.argv[2]), time.monotonic()
def done(*_):
    print(n / (time.monotonic() - t0), flush=True)
    sys.exit(0)
signal.signal(signal.SIGTERM, done)
with connect(sys.argv[1], max_size=None) as ws:
    ws.send(json.dumps({"type": "hello", "px": 1000, "window_s": 10}))
    t0 = time.monotonic()
    while time.monotonic() < t_end:
        json.loads(ws.recv(timeout=5)); n += 1
done()
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _trial(
    folder: Path, info: DaqInfo, data: np.ndarray, live: LiveCampaign | None, block_n: int
) -> float:
    path = folder / f"run-{time.perf_counter_ns()}.h5"
    writer = RunWriter(path, info)
    n = data.shape[1]
    t0 = time.perf_counter()
    writer.on_start(info, 0.0)
    if live is not None:
        live.on_start(info, 0.0)
    for k in range(0, n, block_n):
        block = data[:, k : k + block_n]
        writer.put_block(k, block)  # as the tee does: the writer first (waiting, not dropping)
        if live is not None:
            live.guard(live.on_block, k, block)  # ... then the ring
    writer.close(rf.STATUS_SUCCESS)
    dt = time.perf_counter() - t0
    path.unlink()
    return n / dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=2_000_000, help="samples per channel")
    ap.add_argument("--trials", type=int, default=3)
    ap.add_argument("--block", type=int, default=BLOCK, help="samples per DAQ block")
    args = ap.parse_args()
    campaign = load_campaign("facemill-ploughing")  # its rig: the dynamometer channels
    c = len(campaign.rig.dynamometer.channels)
    info = DaqInfo("bench", tuple(f"b/ai{i}" for i in range(c)),
                   tuple(ch.name for ch in campaign.rig.dynamometer.channels), 20_000.0,
                   rf.SAMPLE_FORMAT_VOLTS, 10.0, args.block)  # fmt: skip
    rng = np.random.default_rng(0)
    data = rng.normal(0.0, 1.0, (c, args.samples))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        live = LiveCampaign(campaign, folder)
        live._run_k = 0  # a run in progress, as the session factory sets it
        (folder / LIVE_FILE).write_text(json.dumps({"ring": str(live.ring.path),
                                                    "pid": os.getpid()}))  # fmt: skip
        port = _free_port()
        server = start_server(folder, port, "127.0.0.1")
        without, with_console, rates = [], [], []
        try:
            for _ in range(args.trials):
                without.append(_trial(folder, info, data, None, args.block))
                client = subprocess.Popen(
                    [sys.executable, "-c", CLIENT, f"ws://127.0.0.1:{port}/ws", "600"],
                    stdout=subprocess.PIPE, text=True)  # fmt: skip
                time.sleep(1.0)  # connected, frames flowing
                with_console.append(_trial(folder, info, data, live, args.block))
                client.terminate()
                out, _ = client.communicate(timeout=10)
                rates.append(float(out.strip() or "nan"))
        finally:
            live.close()
            stop_server(server, 0.0)
            live.ring.path.unlink(missing_ok=True)
    a, b = statistics.median(without), statistics.median(with_console)
    page = sum((STATIC / f).stat().st_size for f in
               ("index.html", "console.js", "console.css", "uPlot.iife.min.js", "uPlot.min.css"))
    print(f"logger without console: {a:,.0f} samples/s per channel ({c} channels, float64, "
          f"blocks of {args.block})")
    print(f"logger with console:    {b:,.0f} samples/s per channel")
    print(f"ratio: {b / a:.3f} (>= 0.95 asked)")
    print(f"frames received by a client: {statistics.median(rates):.1f} per s")
    print(f"page load: {page / 1024:.1f} KiB (html, js, css, uPlot)")


if __name__ == "__main__":
    main()
