"""Benchmark: the HDF5 logger's throughput without and with the live console open.

Three conditions, run in alternation (``--trials`` rounds, each condition first in turn, the
same pause before every trial), so the machine's slow drifts (other processes on shared cores,
the disk writing back the last trial's file) fall on all of them alike:

- without: blocks go straight into :class:`rig.log.RunWriter`;
- tap: through the console's tee (the writer first, then the shared-memory ring) with the
  live side's status thread running, no server (the cost inside the logger's process);
- console: the tap, plus the console server in its own process and a websocket client (another
  process, standing in for the browser) taking its 25 frames a second (the console open).

Two rates: flat out (``put_block`` as fast as the writer takes them: the headroom) and a
realistic DAQ (``--rate`` samples/s per channel, blocks handed over on the DAQ's clock through
``on_block``, the call a DAQ makes: there the figure is the logger process's CPU time per second
of data, its busy fraction). Prints the median of each condition, the ratios (the issue asks
for at least 0.95 with the console open), the frames a second the client got, the page's load.

Then the page itself in headless Chromium (``/usr/bin/chromium``; skipped without it), fed by the
realistic DAQ for ``--page-s``: its sample-to-screen latency (from a block's arrival in the ring
to the animation frame that shows it, as the page's ``latency`` corner shows it) p50 / p95 (the
issue's target: p95 <= 60 ms), and the logger's CPU per s of data with the page open against
without (the issue asks within 5 %).

    .venv/bin/python bench/bench_console.py [--samples 10000000] [--trials 5] [--rate 100000]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import secrets
import shutil
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
from rig.console.live import LIVE_FILE, LiveCampaign, _Tee, start_server, stop_server
from rig.console.server import STATIC
from rig.daq import DaqInfo
from rig.log import RunWriter

ROOT = Path(__file__).resolve().parent.parent
BLOCK_S = 0.1  # a DAQ block: 0.1 s of samples
SOURCE_BLOCKS = 50  # distinct source blocks, cycled (a DAQ's buffers are reused too)
CONDITIONS = ("without", "tap", "console")
TOKEN = secrets.token_urlsafe(24)  # the console server's session token
SETTLE_S = 2.5  # a pause before every trial (the console's server and client connect in it)
CLIENT = """
import json, signal, sys, time
from websockets.sync.client import connect
n, t_end, t0 = 0, time.monotonic() + float(sys.argv[2]), time.monotonic()
def done(*_):
    print(n / (time.monotonic() - t0), flush=True)
    sys.exit(0)
signal.signal(signal.SIGTERM, done)
# the page's Origin and the session's token (in the URL): the console refuses others (issue 31)
with connect(sys.argv[1], max_size=None, origin="http://" + sys.argv[1].split("/")[2]) as ws:
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


class _Null:
    def on_start(self, info: DaqInfo, t0_s: float) -> None: ...

    def on_block(self, first_sample: int, data: np.ndarray) -> None: ...

    def on_event(self, event: object) -> None: ...


def _trial(
    folder: Path, info: DaqInfo, blocks: list[np.ndarray], n_total: int,
    live: LiveCampaign | None, paced: bool,
) -> tuple[float, float]:  # fmt: skip
    """Flat out: samples/s per channel, by the wall clock and by the process's CPU time (the
    second is blind to other processes taking the cores). Paced: CPU s per s of data."""
    path = folder / f"run-{time.perf_counter_ns()}.h5"
    writer = RunWriter(path, info)
    sink = writer if live is None else _Tee(writer, live)  # the sink a DAQ is given
    ring_only = None if live is None else _Tee(_Null(), live)
    block_n = blocks[0].shape[1]
    period_s = block_n / info.rate_hz
    t0, cpu0 = time.perf_counter(), time.process_time()
    sink.on_start(info, 0.0)
    for j, k in enumerate(range(0, n_total, block_n)):
        block = blocks[j % len(blocks)]
        if paced:
            time.sleep(max(0.0, t0 + (j + 1) * period_s - time.perf_counter()))
            sink.on_block(k, block)  # what a DAQ calls: never waits
        else:
            writer.put_block(k, block)  # as the tee does: the writer first (waiting, not
            if ring_only is not None:  # dropping, so the figure is the writer's pace) ...
                ring_only.on_block(k, block)  # ... then the ring
    writer.close(rf.STATUS_SUCCESS)
    dt, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    path.unlink()
    if paced:
        return cpu / (n_total / info.rate_hz), 0.0
    return n_total / dt, n_total / cpu


def _rounds(
    folder: Path, campaign: object, info: DaqInfo, blocks: list[np.ndarray], n_total: int,
    trials: int, paced: bool, port: int,
) -> tuple[dict[str, list[tuple[float, float]]], list[float]]:  # fmt: skip
    out: dict[str, list[tuple[float, float]]] = {c: [] for c in CONDITIONS}
    rates: list[float] = []
    for r in range(trials):
        for cond in CONDITIONS[r % 3 :] + CONDITIONS[: r % 3]:  # each first in turn
            ready = time.monotonic() + SETTLE_S  # the last trial's file written back, for all
            if cond == "without":
                time.sleep(max(0.0, ready - time.monotonic()))
                out[cond].append(_trial(folder, info, blocks, n_total, None, paced))
                continue
            live = LiveCampaign(campaign, folder)  # a fresh live side: its thread, its ring
            live._run_k = 0  # a run in progress, as the session factory sets it
            live.on_start(info, 0.0)  # the ring's pages touched, as by a campaign's earlier runs
            cap = live.ring._rows.shape[1]
            for k in range(0, cap, blocks[0].shape[1]):
                live.ring.write(k, blocks[0])
            client = None
            if cond == "console":
                (folder / LIVE_FILE).write_text(json.dumps({"ring": str(live.ring.path),
                                                            "pid": os.getpid()}))  # fmt: skip
                time.sleep(1.2)  # the server attaches (it looks once a second)
                url = f"ws://127.0.0.1:{port}/ws?token={TOKEN}"
                client = subprocess.Popen(
                    [sys.executable, "-c", CLIENT, url, "600"],
                    stdout=subprocess.PIPE, text=True)  # fmt: skip
            time.sleep(max(0.0, ready - time.monotonic()))  # (console: frames flowing)
            try:
                out[cond].append(_trial(folder, info, blocks, n_total, live, paced))
            finally:
                if client is not None:
                    client.terminate()
                    text, _ = client.communicate(timeout=10)
                    rates.append(float(text.strip() or "nan"))
                live.close()
                live.ring.path.unlink(missing_ok=True)
    return out, rates


class _Page:
    """Headless Chromium on one page, spoken to over the DevTools protocol (as the browser
    tier does: no selenium)."""

    def __init__(self, url: str, profile: Path) -> None:
        import urllib.request

        from websockets.sync.client import connect

        chromium = shutil.which("chromium") or shutil.which("chromium-browser")
        args = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                "--disable-background-networking", f"--user-data-dir={profile}",
                "--remote-debugging-port=0", "about:blank"]  # fmt: skip
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = profile / "DevToolsActivePort"
        t_end = time.monotonic() + 30
        while not (port_file.exists() and port_file.read_text().strip()):
            if time.monotonic() > t_end or self.proc.poll() is not None:
                raise SystemExit("bench: chromium did not start")
            time.sleep(0.05)
        port = port_file.read_text().split()[0]
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
            target = next(t for t in json.load(r) if t["type"] == "page")
        self.ws = connect(target["webSocketDebuggerUrl"], max_size=None, open_timeout=20)
        self.n = 0
        self.call("Page.navigate", url=url)

    def call(self, method: str, **params: object) -> dict:
        self.n += 1
        self.ws.send(json.dumps({"id": self.n, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv(timeout=20))
            if msg.get("id") == self.n:
                return msg.get("result", {})

    def js(self, expr: str) -> object:
        r = self.call("Runtime.evaluate", expression=expr, returnByValue=True)
        return r.get("result", {}).get("value")

    def close(self) -> None:
        self.ws.close()
        self.proc.terminate()
        self.proc.wait(timeout=10)


def _page_trials(
    folder: Path, campaign: object, info: DaqInfo, blocks: list[np.ndarray], seconds: float,
    trials: int, port: int,
) -> tuple[list[float], list[float], list[float]]:  # fmt: skip
    """The page open in Chromium while the paced DAQ runs: (latencies ms, logger CPU per s of
    data with the page, without), trials alternated."""
    lat: list[float] = []
    cpu_page: list[float] = []
    cpu_bare: list[float] = []
    n_total = int(seconds * info.rate_hz)
    with tempfile.TemporaryDirectory() as prof:
        for r in range(trials):
            for cond in ("page", "without") if r % 2 == 0 else ("without", "page"):
                time.sleep(SETTLE_S)
                if cond == "without":
                    cpu_bare.append(_trial(folder, info, blocks, n_total, None, True)[0])
                    continue
                live = LiveCampaign(campaign, folder)
                live._run_k = 0
                (folder / LIVE_FILE).write_text(json.dumps({"ring": str(live.ring.path),
                                                            "pid": os.getpid()}))  # fmt: skip
                time.sleep(1.2)  # the server attaches
                page = _Page(f"http://127.0.0.1:{port}/?token={TOKEN}", Path(prof) / str(r))
                try:
                    t_end = time.monotonic() + 20
                    while not (page.js("window.cutlab && 1") and
                               (page.js("+document.getElementById('frame-count')"
                                        ".textContent") or 0) > 10):  # fmt: skip
                        if time.monotonic() > t_end:
                            raise SystemExit("bench: the page did not connect")
                        time.sleep(0.1)
                    page.js("window.cutlab.latencies.length = 0; "
                            "window.cutlab.latencyParts.length = 0")  # fmt: skip
                    cpu_page.append(_trial(folder, info, blocks, n_total, live, True)[0])
                    got = page.js("window.cutlab.latencies.map((x, i) => [x]"
                                  ".concat(window.cutlab.latencyParts[i]))")  # fmt: skip
                    lat += got or []
                finally:
                    page.close()
                    live.close()
                    live.ring.path.unlink(missing_ok=True)
    return lat, cpu_page, cpu_bare


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=10_000_000,
                    help="samples per channel per flat-out trial")  # fmt: skip
    ap.add_argument("--trials", type=int, default=5, help="trials of each condition and rate")
    ap.add_argument("--rate", type=float, default=100_000.0,
                    help="the realistic DAQ's samples/s per channel")  # fmt: skip
    ap.add_argument("--paced-s", type=float, default=3.0, help="s of data per paced trial")
    ap.add_argument("--page-only", action="store_true",
                    help="only the page in Chromium: its latency, the logger with it")  # fmt: skip
    ap.add_argument("--page-s", type=float, default=8.0,
                    help="s of data a trial with the page in Chromium (0: none)")  # fmt: skip
    args = ap.parse_args()
    campaign = load_campaign("facemill-ploughing")  # its rig: the dynamometer channels
    c = len(campaign.rig.dynamometer.channels)
    block_n = int(args.rate * BLOCK_S)
    info = DaqInfo("bench", tuple(f"b/ai{i}" for i in range(c)),
                   tuple(ch.name for ch in campaign.rig.dynamometer.channels), args.rate,
                   rf.SAMPLE_FORMAT_VOLTS, 10.0, block_n)  # fmt: skip
    rng = np.random.default_rng(0)
    blocks = [rng.normal(0.0, 1.0, (c, block_n)) for _ in range(SOURCE_BLOCKS)]
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "runs").mkdir()  # a campaign folder to the server
        port = _free_port()
        server = start_server(folder, port, "127.0.0.1", TOKEN)
        try:
            for paced in () if args.page_only else (False, True):
                n_total = int(args.paced_s * args.rate) if paced else args.samples
                results[paced] = _rounds(folder, campaign, info, blocks, n_total, args.trials,
                                         paced, port)  # fmt: skip
            page = None
            if args.page_s > 0 and (shutil.which("chromium") or shutil.which("chromium-browser")):
                page = _page_trials(folder, campaign, info, blocks, args.page_s, args.trials,
                                    port)  # fmt: skip
        finally:
            stop_server(server, 0.0)
    print(f"{c} channels of float64, blocks of {block_n} samples, {args.trials} alternated "
          "trials of each condition; medians")  # fmt: skip
    if args.page_only:
        _print_page(args, page)
        return
    flat, rates = results[False]
    print(f"flat out ({args.samples:,} samples per channel a trial), samples/s per channel")
    for j, clock in enumerate(("by the wall clock", "per CPU s of the logger's process")):
        med = {k: statistics.median(x[j] for x in v) for k, v in flat.items()}
        print(f" {clock}:")
        for k in CONDITIONS:
            trials = ", ".join(f"{x[j] / 1e6:.1f}" for x in flat[k])
            print(f"  {k:8s} {med[k]:14,.0f}   ratio {med[k] / med['without']:.3f}   "
                  f"(trials, M/s: {trials})")
    paced, rates2 = results[True]
    print(f"realistic DAQ ({args.rate:,.0f} samples/s per channel, {args.paced_s:g} s a trial), "
          "the logger process's CPU per s of data:")
    for k in CONDITIONS:
        med_k = statistics.median(x[0] for x in paced[k])
        trials = ", ".join(f"{x[0] * 100:.2f}" for x in paced[k])
        print(f"  {k:8s} {med_k * 100:6.2f} %   (trials, %: {trials})")
    print(f"frames received by a client: {statistics.median(rates + rates2):.1f} per s")
    # every file the page loads (index.html names them: the panels and the 3-D view too)
    names = re.findall(r'(?:src|href)="/static/([^"]+)"', (STATIC / "index.html").read_text())
    load = sum((STATIC / f).stat().st_size for f in ["index.html", *names])
    print(f"page load: {load / 1024:.1f} KiB (html and the {len(names)} files it loads)")
    _print_page(args, page)


def _print_page(args: argparse.Namespace, page: tuple | None) -> None:
    if page is None:
        print("the page in Chromium: not measured (no chromium, or --page-s 0)")
        return
    lat, cpu_page, cpu_bare = page
    if not lat:
        print("the page in Chromium: no latencies recorded")
        return
    a = np.asarray(lat, float)
    q = np.percentile(a[:, 0], [50, 95])
    qs, qp = np.percentile(a[:, 1], [50, 95]), np.percentile(a[:, 2], [50, 95])
    print(f"the page in Chromium ({args.page_s:g} s a trial, {len(a)} frames): sample to "
          f"screen p50 {q[0]:.0f} ms, p95 {q[1]:.0f} ms, max {a[:, 0].max():.0f} ms (target "
          f"p95 <= 60 ms); of which ring to websocket p50 {qs[0]:.0f} / p95 {qs[1]:.0f} ms, "
          f"websocket to screen p50 {qp[0]:.0f} / p95 {qp[1]:.0f} ms; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")  # fmt: skip
    med_p, med_b = statistics.median(cpu_page), statistics.median(cpu_bare)
    # At a DAQ's pace the logger is not slower with the page: it takes more CPU (the ring's
    # copies, the status thread); its speed, flat out, is the ratio printed above.
    print(f"  the logger process's CPU per s of data: {med_b * 100:.2f} % without, "
          f"{med_p * 100:.2f} % with the page open (+{(med_p - med_b) * 100:.2f} % of a "
          "core)")  # fmt: skip


if __name__ == "__main__":
    main()
