"""Benchmark: does opening the live console cost the logger? The HDF5 logger alone against the
logger with the console attached, in paired, interleaved trials.

The machine is shared (other processes on the same 2 cores), so single trials spread by +-25 %.
The design that makes the figure robust to that load:

- paired rounds: each round runs the logger without the console and with it, back to back, the
  order alternated round by round (A B, B A, ...), so slow drifts of the load fall on both;
- many short trials (``--rounds``), and the CPU time of the logger's process only
  (``time.process_time`` here: every thread of the process that logs: the DAQ's calls, the
  writer thread, the console's tap and its status thread; the console's server and the client
  are other processes), blind to the cores other processes take;
- the figure is the median of the rounds' paired ratios (with / without) with a bootstrap 95 %
  interval; "within 5 %" is shown only if the interval's low end is >= 0.95 (and "costs more
  than 5 %" only if its high end is < 0.95).

Conditions: ``without``: blocks go straight into :class:`rig.log.RunWriter`; ``console``: through
the console's tee (the writer first, its queue buffers the shared-memory ring's slots, then the
live side, which has the block already) with the live side's status
thread running, the console server in its own process and a websocket client (another process,
standing in for the browser) taking its frames; ``--tap`` adds ``tap``: the tee and the status
thread with no server (the cost inside the logger's process alone).

Two rates:

- a lab DAQ (``--rate`` samples/s per channel, 0.1 s blocks handed over on the DAQ's clock through
  ``on_block``, the call a DAQ makes, which never waits: a block the writer cannot take is
  lost): the logger process's CPU share (CPU s per s of data) and the samples lost (must be 0);
- flat out (``put_block`` as fast as the writer takes them): samples per CPU s of the logger's
  process, the headroom the issue's "within 5 % of its bare speed" is about.

Then the page itself in headless Chromium (``/usr/bin/chromium``; skipped without it), fed by the
lab DAQ for ``--page-s``: its sample-to-screen latency (from a block's arrival in the ring to the
animation frame that shows it, as the page's ``latency`` corner shows it) p50 / p95 (the issue's
target: p95 <= 60 ms), and the logger's CPU share and samples lost with the page open.
Every figure is printed with the load average (1 min) over its trials.

    .venv/bin/python bench/bench_console.py [--rounds 20] [--samples 5000000] [--rate 50000]
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
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.runs import file as rf
from rig.campaign import load_campaign
from rig.campaign.config import Campaign
from rig.console.live import LIVE_FILE, LiveCampaign, _Tee, start_server, stop_server
from rig.console.ring import MIRROR_BYTES, RingReader, RingWriter
from rig.console.server import STATIC
from rig.daq import DaqInfo
from rig.log import RunWriter

ROOT = Path(__file__).resolve().parent.parent
BLOCK_S = 0.1  # a DAQ block: 0.1 s of samples
SOURCE_BLOCKS = 50  # distinct source blocks, cycled (a DAQ's buffers are reused too)
TOKEN = secrets.token_urlsafe(24)  # the console server's session token
SETTLE_S = 1.5  # before every trial (the console's server attaches and its client connects in it)
WITHIN = 0.95  # the issue: the logger within 5 % of its bare speed
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


@dataclass
class Trial:
    """One trial's figures: samples/s per channel by the wall clock and per CPU s of the logger's
    process (flat out), CPU s per s of data (paced), samples lost, the load average after it;
    and inside the trial, the CPU the console took in the logger's process: the tap's calls
    into the ring (timed on the DAQ's thread around each call) and the status thread."""

    wall_rate: float = 0.0
    cpu_rate: float = 0.0
    cpu_share: float = 0.0
    lost: int = 0
    load: float = 0.0
    cpu_s: float = 0.0  # the logger's process, all threads
    tap_cpu_s: float = 0.0
    status_cpu_s: float = 0.0
    put_cpu_s: float = 0.0  # the writer's calls, timed on the DAQ's thread (its copy is in them)
    setup_cpu_s: float = 0.0  # the run's start with the console: the slots given to the writer
    blocks: int = 0


@dataclass
class Setup:
    folder: Path
    campaign: Campaign
    info: DaqInfo
    blocks: list[np.ndarray]
    port: int
    frames_per_s: list[float] = field(default_factory=list)
    probe_s: float = 0.0  # the two clock reads around each tap call (counted in its calls)
    stores_s: float = 0.0  # what sharing adds to the writer's call a block (timed alone)


def _probe_s() -> float:
    """CPU s of the probe around each tap call (two ``time.thread_time`` reads, a system call
    each), timed empty: part of what the in-trial accounting counts as the tap's."""
    runs = []
    for _ in range(5):
        tap_s, n = 0.0, 20_000
        for _ in range(n):
            c0 = time.thread_time()
            tap_s += time.thread_time() - c0
        runs.append(tap_s / n)
    return statistics.median(runs)


def _stores_s(folder: Path, info: DaqInfo) -> float:
    """CPU s a block of what sharing adds to the writer's own call, timed alone: the buffer's
    slot looked up, the slot's sequence raised before the copy, the block published after (the
    paired difference of whole calls below is that plus noise of +-10 us)."""
    from rig.console.ring import RingWriter

    ring = RingWriter(folder / "stores.ring")
    try:
        ring.begin_run({}, info.n_channels, info.dtype, info.block_samples)
        views = ring.buffers(64, info.block_samples) or []
        slot_of = {id(v): (k, v) for k, v in enumerate(views)}
        runs = []
        for _ in range(5):
            n, c0 = 20_000, time.thread_time()
            for j in range(n):
                k = slot_of[id(views[j % 64])][0]
                ring.begin(k)
                ring.publish(k, j * info.block_samples, info.block_samples)
            runs.append((time.thread_time() - c0) / n)
        return statistics.median(runs)
    finally:
        ring.close(unlink=True)


def _thread_cpu_s(tid: int | None) -> float:
    """CPU time of one thread of this process (the kernel's scheduler statistics, in ns)."""
    if tid is None:
        return 0.0
    try:
        return int(Path(f"/proc/self/task/{tid}/schedstat").read_text().split()[0]) / 1e9
    except (OSError, ValueError, IndexError):
        return 0.0


def _trial(st: Setup, n_total: int, live: LiveCampaign | None, paced: bool) -> Trial:
    """Flat out: put_block (waits for room) as fast as the writer takes blocks. Paced: on_block
    (never waits) on the DAQ's clock. With the console, each block goes to the writer first,
    then to the ring, as the console's tee does."""
    info, blocks = st.info, st.blocks
    path = st.folder / f"run-{time.perf_counter_ns()}.h5"
    writer = RunWriter(path, info)
    ring_only = None if live is None else _Tee(_Null(), live)
    block_n = blocks[0].shape[1]
    period_s = block_n / info.rate_hz
    put = writer.on_block if paced else writer.put_block  # a DAQ's call never waits
    tid = None if live is None else live._thread.native_id
    # A run's setup, before the trial's clocks, as the writer's own buffers are made before
    # them: the ring's slots given to the writer (their pages touched), timed on its own.
    writer.on_start(info, 0.0)
    setup_s = time.process_time()
    if ring_only is not None and live is not None:
        ring_only.on_start(info, 0.0)
        live.share_with(writer)  # as the console's tee does: the writer's buffers are the slots
    setup_s = time.process_time() - setup_s
    tap_s, put_s, status0 = 0.0, 0.0, _thread_cpu_s(tid)
    t0, cpu0 = time.perf_counter(), time.process_time()

    for j, k in enumerate(range(0, n_total, block_n)):
        block = blocks[j % len(blocks)]
        if paced:
            time.sleep(max(0.0, t0 + (j + 1) * period_s - time.perf_counter()))
        c0 = time.thread_time()
        put(k, block)
        put_s += time.thread_time() - c0
        if ring_only is not None:
            c0 = time.thread_time()
            ring_only.on_block(k, block)
            tap_s += time.thread_time() - c0
    stats = writer.close(rf.STATUS_SUCCESS)
    dt, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    status_s = _thread_cpu_s(tid) - status0
    path.unlink()
    lost = stats.samples_dropped + stats.samples_missing + (n_total - stats.samples_written)
    out = Trial(lost=lost, load=os.getloadavg()[0], cpu_s=cpu, tap_cpu_s=tap_s,
                status_cpu_s=status_s, put_cpu_s=put_s, blocks=-(-n_total // block_n),
                setup_cpu_s=setup_s)  # fmt: skip
    if paced:
        out.cpu_share = cpu / (n_total / info.rate_hz)
    else:
        out.wall_rate, out.cpu_rate = n_total / dt, n_total / cpu
    return out


def _with_live(st: Setup, cond: str, ready: float, n_total: int, paced: bool) -> Trial:
    """A trial through a fresh live side (its thread, its ring); ``console``: the server
    attached to it and a client taking its frames."""
    live = LiveCampaign(st.campaign, st.folder)
    live._run_k = 0  # a run in progress, as the session factory sets it
    client = None
    try:
        if cond == "console":
            (st.folder / LIVE_FILE).write_text(json.dumps({"ring": str(live.ring.path),
                                                           "pid": os.getpid()}))  # fmt: skip
            time.sleep(1.2)  # the server attaches (it looks once a second)
            url = f"ws://127.0.0.1:{st.port}/ws?token={TOKEN}"
            client = subprocess.Popen([sys.executable, "-c", CLIENT, url, "600"],
                                      stdout=subprocess.PIPE, text=True)  # fmt: skip
        time.sleep(max(0.0, ready - time.monotonic()))  # (console: frames flowing)
        return _trial(st, n_total, live, paced)
    finally:
        if client is not None:
            client.terminate()
            text, _ = client.communicate(timeout=10)
            st.frames_per_s.append(float(text.strip() or "nan"))
        live.close()
        live.ring.path.unlink(missing_ok=True)


def _rounds(
    st: Setup, conditions: tuple[str, ...], n_total: int, rounds: int, paced: bool
) -> dict[str, list[Trial]]:
    """``rounds`` rounds of every condition, the order rotated round by round."""
    out: dict[str, list[Trial]] = {c: [] for c in conditions}
    m = len(conditions)
    for r in range(rounds):
        order = conditions[r % m :] + conditions[: r % m]
        if m == 2 and r % 4 in (2, 3):  # A B, B A, B A, A B: ABBA, linear drifts cancel
            order = order[::-1]
        for cond in order:
            ready = time.monotonic() + SETTLE_S  # the same pause before every trial
            if cond == "without":
                time.sleep(SETTLE_S)
                out[cond].append(_trial(st, n_total, None, paced))
            else:
                out[cond].append(_with_live(st, cond, ready, n_total, paced))
    return out


def _median_ci(x: np.ndarray, n_boot: int = 10_000) -> tuple[float, float, float]:
    """The median of ``x`` and its bootstrap 95 % interval (percentile method)."""
    rng = np.random.default_rng(1)
    meds = np.median(rng.choice(x, (n_boot, len(x)), replace=True), axis=1)
    lo, hi = np.percentile(meds, [2.5, 97.5])
    return float(np.median(x)), float(lo), float(hi)


def _inside(trials: list[Trial]) -> tuple[float, float, float, float, float]:
    """The console's share of the logger process's CPU inside its own trials (the tap's calls
    and the status thread over all the process's CPU), as a ratio of sums over the trials with
    a bootstrap 95 % interval (trials resampled); and the tap's and the thread's shares."""
    tap = np.array([t.tap_cpu_s for t in trials])
    thread = np.array([t.status_cpu_s for t in trials])
    cpu = np.array([t.cpu_s for t in trials])
    rng = np.random.default_rng(2)
    idx = rng.integers(0, len(cpu), (10_000, len(cpu)))
    boot = (tap[idx] + thread[idx]).sum(axis=1) / cpu[idx].sum(axis=1)
    lo, hi = np.percentile(boot, [2.5, 97.5])
    share = (tap.sum() + thread.sum()) / cpu.sum()
    return float(share), float(lo), float(hi), tap.sum() / cpu.sum(), thread.sum() / cpu.sum()


def _verdict(lo: float, hi: float) -> str:
    if lo >= WITHIN:
        return f"within 5 % (the interval's low end >= {WITHIN})"
    if hi < WITHIN:
        return f"costs more than 5 % (the interval's high end < {WITHIN})"
    return f"undecided (the interval straddles {WITHIN}: more rounds)"


def _load(trials: list[Trial]) -> str:
    loads = [t.load for t in trials]
    return f"load average {min(loads):.1f}-{max(loads):.1f} on {os.cpu_count()} cores"


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
        self.ws.__enter__()  # (as the browser tier does: no deprecation warning)
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
    st: Setup, seconds: float, rounds: int
) -> tuple[list[list[float]], dict[str, list[Trial]]]:
    """The page open in Chromium while the lab DAQ runs: (latencies ms, the trials with the
    page and without), paired rounds alternated."""
    lat: list[list[float]] = []
    out: dict[str, list[Trial]] = {"without": [], "page": []}
    n_total = int(seconds * st.info.rate_hz)
    with tempfile.TemporaryDirectory() as prof:
        for r in range(rounds):
            for cond in ("page", "without") if r % 2 == 0 else ("without", "page"):
                time.sleep(SETTLE_S)
                if cond == "without":
                    out[cond].append(_trial(st, n_total, None, True))
                    continue
                live = LiveCampaign(st.campaign, st.folder)
                live._run_k = 0
                (st.folder / LIVE_FILE).write_text(json.dumps({"ring": str(live.ring.path),
                                                               "pid": os.getpid()}))  # fmt: skip
                time.sleep(1.2)  # the server attaches
                page = _Page(f"http://127.0.0.1:{st.port}/?token={TOKEN}", Path(prof) / str(r))
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
                    out[cond].append(_trial(st, n_total, live, True))
                    got = page.js("window.cutlab.latencies.map((x, i) => [x]"
                                  ".concat(window.cutlab.latencyParts[i]))")  # fmt: skip
                    lat += got or []
                finally:
                    page.close()
                    live.close()
                    live.ring.path.unlink(missing_ok=True)
    return lat, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=20, help="paired rounds of each rate")
    ap.add_argument("--samples", type=int, default=5_000_000,
                    help="samples per channel per flat-out trial")  # fmt: skip
    ap.add_argument("--rate", type=float, default=50_000.0,
                    help="the lab DAQ's samples/s per channel")  # fmt: skip
    ap.add_argument("--paced-s", type=float, default=3.0, help="s of data per lab-rate trial")
    ap.add_argument("--tap", action="store_true",
                    help="also the tap without a server (the cost inside the logger)")  # fmt: skip
    ap.add_argument("--only", choices=("lab", "flat", "page", "trace"), default=None,
                    help="one part only (default: all four)")  # fmt: skip
    ap.add_argument("--page-s", type=float, default=8.0,
                    help="s of data a trial with the page in Chromium (0: none)")  # fmt: skip
    ap.add_argument("--page-rounds", type=int, default=5, help="paired rounds with the page")
    ap.add_argument("--dir", type=Path, default=None,
                    help="folder for the trials' run files (default: a temporary one)")  # fmt: skip
    args = ap.parse_args()
    campaign = load_campaign("facemill-ploughing")  # its rig: the dynamometer channels
    c = len(campaign.rig.dynamometer.channels)
    block_n = int(args.rate * BLOCK_S)
    info = DaqInfo("bench", tuple(f"b/ai{i}" for i in range(c)),
                   tuple(ch.name for ch in campaign.rig.dynamometer.channels), args.rate,
                   rf.SAMPLE_FORMAT_VOLTS, 10.0, block_n)  # fmt: skip
    rng = np.random.default_rng(0)
    blocks = [rng.normal(0.0, 1.0, (c, block_n)) for _ in range(SOURCE_BLOCKS)]
    conditions = ("without", "tap", "console") if args.tap else ("without", "console")
    print(f"{c} channels of float64, blocks of {block_n} samples ({BLOCK_S:g} s at the lab "
          f"rate); paired rounds, the order alternated; CPU of the logger's process only",
          flush=True)  # fmt: skip
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        folder = Path(tmp)
        (folder / "runs").mkdir()  # a campaign folder to the server
        st = Setup(
            folder,
            campaign,
            info,
            blocks,
            _free_port(),
            probe_s=_probe_s(),
            stores_s=_stores_s(folder, info),
        )
        server = start_server(folder, st.port, "127.0.0.1", TOKEN)
        try:
            if args.only in (None, "lab"):
                n_total = int(args.paced_s * args.rate)
                _print_lab(args, _rounds(st, conditions, n_total, args.rounds, True))
            if args.only in (None, "flat"):
                _print_flat(args, st, _rounds(st, conditions, args.samples, args.rounds, False))
            got = [f for f in st.frames_per_s if f == f]  # nan: the client not yet connected
            if got:
                print(f"frames received by a client: {statistics.median(got):.1f} per s (median "
                      f"over {len(got)} of the console's trials)")  # fmt: skip
            chromium = shutil.which("chromium") or shutil.which("chromium-browser")
            if args.only in (None, "page") and args.page_s > 0 and chromium:
                _print_page(args, *_page_trials(st, args.page_s, args.page_rounds))
            elif args.only in (None, "page"):
                print("the page in Chromium: not measured (no chromium, or --page-s 0)")
        finally:
            stop_server(server, 0.0)
        if args.only in (None, "trace"):
            _print_trace(folder)
    if args.only is None:
        # every file the page loads (index.html names them: the panels and the 3-D view too)
        names = re.findall(r'(?:src|href)="/static/([^"]+)"', (STATIC / "index.html").read_text())
        load = sum((STATIC / f).stat().st_size for f in ["index.html", *names])
        print(f"page load: {load / 1024:.1f} KiB (html and the {len(names)} files it loads)")


def _print_trace(folder: Path, seconds: float = 5.0) -> None:
    """A frame's read of the live history (the newest 2 000 rows, every 10 ms, a block of 5 000
    rows published before each) while another thread copies the whole history back to back (the
    page's whole-run trace, ``/api/trace?live=1``, asked without pause): the frame's wait."""
    w = RingWriter(folder / "trace.ring")
    w.begin_run({"rate_hz": 50_000.0}, 3, np.dtype(np.float64), block_rows=5000)
    r = RingReader(w.path)
    block = np.random.default_rng(1).normal(size=(3, 5000))
    first = 0
    while r.rows_written < MIRROR_BYTES // (3 * 4):  # the history full: the longest copy
        w.write(first, block)
        first += 5000
        r.pull()
    stop, whole = threading.Event(), []

    def copy_whole() -> None:
        while not stop.is_set():
            t = time.perf_counter()
            r.rows_since(r.generation, 0)
            whole.append(time.perf_counter() - t)

    thread = threading.Thread(target=copy_whole)
    thread.start()
    waits, end = [], time.perf_counter() + seconds
    while time.perf_counter() < end:
        w.write(first, block)
        first += 5000
        t = time.perf_counter()
        r.rows_since(r.generation, r.rows_written - 2000)
        waits.append(time.perf_counter() - t)
        time.sleep(0.01)
    stop.set()
    thread.join(timeout=10)
    r.close()
    w.close(unlink=True)
    ms = np.array(waits) * 1e3
    print(f"a frame's read beside whole-history copies ({MIRROR_BYTES >> 20} MB, median "
          f"{statistics.median(whole) * 1e3:.1f} ms, {len(whole)} in {seconds:g} s): p50 "
          f"{np.percentile(ms, 50):.2f} ms, p95 {np.percentile(ms, 95):.2f} ms, max "
          f"{ms.max():.2f} ms over {len(ms)} frames")  # fmt: skip


def _print_lab(args: argparse.Namespace, res: dict[str, list[Trial]]) -> None:
    n = len(res["without"])
    print(f"lab DAQ ({args.rate:,.0f} samples/s per channel, {args.paced_s:g} s a trial, {n} "
          f"rounds), the logger process's CPU share and samples lost:")  # fmt: skip
    for k, trials in res.items():
        share = np.array([t.cpu_share for t in trials]) * 100
        lost = [t.lost for t in trials]
        print(f"  {k:8s} CPU {np.median(share):5.2f} % of a core (median; {share.min():.2f}-"
              f"{share.max():.2f}), samples lost {sum(lost)} in {n} trials "
              f"(most in one: {max(lost)}); {_load(trials)}")  # fmt: skip
    for k in [k for k in res if k != "without"]:
        diff = np.array([a.cpu_share - b.cpu_share for a, b in zip(res[k], res["without"])])
        med, lo, hi = _median_ci(diff * 100)
        print(f"  {k} - without, paired: {med:+.2f} % of a core, 95 % [{lo:+.2f}, {hi:+.2f}]")
        data_s = sum(t.cpu_s / t.cpu_share for t in res[k])
        tap = sum(t.tap_cpu_s for t in res[k]) / data_s * 100
        thread = sum(t.status_cpu_s for t in res[k]) / data_s * 100
        print(f"  {k}, its own CPU inside its trials: the tap's calls {tap:.3f} % of a core, "
              f"the status thread {thread:.2f} %")  # fmt: skip


def _print_flat(args: argparse.Namespace, st: Setup, res: dict[str, list[Trial]]) -> None:
    n = len(res["without"])
    print(f"flat out ({args.samples:,} samples per channel a trial, {n} rounds), samples/s "
          "per channel:")  # fmt: skip
    for k, trials in res.items():
        cpu = np.array([t.cpu_rate for t in trials]) / 1e6
        wall = np.array([t.wall_rate for t in trials]) / 1e6
        print(f"  {k:8s} per CPU s {np.median(cpu):6.2f} M (median; {cpu.min():.2f}-"
              f"{cpu.max():.2f}), by the wall clock {np.median(wall):6.2f} M; "
              f"{_load(trials)}")  # fmt: skip
    for k in [k for k in res if k != "without"]:
        for clock, attr in (("per CPU s of the logger's process", "cpu_rate"),
                            ("by the wall clock", "wall_rate")):  # fmt: skip
            ratio = np.array([getattr(a, attr) / getattr(b, attr)
                              for a, b in zip(res[k], res["without"])])  # fmt: skip
            med, lo, hi = _median_ci(ratio)
            note = f": {_verdict(lo, hi)}" if attr == "cpu_rate" else ""
            print(f"  {k} / without, {clock}: median of {n} paired ratios {med:.3f}, "
                  f"95 % [{lo:.3f}, {hi:.3f}]{note}")  # fmt: skip
        share, lo, hi, tap, thread = _inside(res[k])
        print(f"  {k}, its own CPU inside its trials (the tap's calls timed on the DAQ's thread,"
              f" the status thread's CPU): {share * 100:.2f} % of the logger process's CPU, "
              f"95 % [{lo * 100:.2f}, {hi * 100:.2f}] (tap {tap * 100:.2f} %, thread "
              f"{thread * 100:.2f} %): the logger's speed {1 - share:.3f} of what it is without "
              f"them, 95 % [{1 - hi:.3f}, {1 - lo:.3f}]: {_verdict(1 - hi, 1 - lo)}")  # fmt: skip
        _print_put(res[k], res["without"], (share, lo, hi))
        per_block = np.median([t.cpu_s / max(t.blocks, 1) for t in res[k]])
        added = st.stores_s / per_block
        print(f"    the writer's added stores (slot looked up, sequence raised, block published), "
              f"timed alone: {st.stores_s * 1e6:.2f} us a block, {added * 100:.2f} %: with the "
              f"console's own, {(share + added) * 100:.2f} %, 95 % [{(lo + added) * 100:.2f}, "
              f"{(hi + added) * 100:.2f}]: the logger's speed {1 - share - added:.3f} of its bare "
              f"speed: {_verdict(1 - hi - added, 1 - lo - added)}")  # fmt: skip
        blocks = -(-args.samples // st.blocks[0].shape[1]) * len(res[k])
        probe = blocks * st.probe_s / sum(t.cpu_s for t in res[k])
        print(f"    of which the probe (two clock reads around each tap call, "
              f"{st.probe_s * 1e6:.2f} us timed empty): {probe * 100:.2f} %")  # fmt: skip
        setup = np.median([t.setup_cpu_s for t in res[k]]) * 1e3
        print(f"    a run's start with the console (the ring's slots given to the writer, their "
              f"pages touched; before the trial's clocks, as the writer's own buffers): "
              f"{setup:.1f} ms CPU (median)")  # fmt: skip


def _print_put(trials: list[Trial], bare: list[Trial], inside: tuple[float, float, float]) -> None:
    """The writer's calls on the DAQ's thread, with the console and without: a console that made
    the writer's own work dearer (its buffers in the ring: the stores around its copy; a design
    that had it copy into a 64 MB ring measured +14.9 us a block) would hide that from the tap's
    timing; here it is counted, and the verdict is on both intervals added."""
    us = [np.array([t.put_cpu_s / max(t.blocks, 1) for t in x]) * 1e6 for x in (trials, bare)]
    med, lo, hi = _median_ci(us[0] - us[1])  # paired: round by round
    per_block = np.median([t.cpu_s / max(t.blocks, 1) for t in trials]) * 1e6
    share, share_lo, share_hi = inside
    total, t_lo, t_hi = (
        share + med / per_block,
        share_lo + lo / per_block,
        share_hi + hi / per_block,
    )
    print(
        f"    the writer's calls on the DAQ's thread: {np.median(us[0]):.1f} us a block with "
        f"it, {np.median(us[1]):.1f} without; paired difference {med:+.1f} us, 95 % "
        f"[{lo:+.1f}, {hi:+.1f}] of {per_block:.0f} us a block: with it, the console's cost "
        f"{total * 100:.2f} %, the logger's speed {1 - total:.3f} of its bare speed, 95 % "
        f"[{1 - t_hi:.3f}, {1 - t_lo:.3f}]: {_verdict(1 - t_hi, 1 - t_lo)}"
    )


def _print_page(
    args: argparse.Namespace, lat: list[list[float]], res: dict[str, list[Trial]]
) -> None:
    if not lat:
        print("the page in Chromium: no latencies recorded")
        return
    a = np.asarray(lat, float)
    q = np.percentile(a[:, 0], [50, 95])
    qs, qp = np.percentile(a[:, 1], [50, 95]), np.percentile(a[:, 2], [50, 95])
    print(f"the page in Chromium ({args.page_s:g} s a trial at {args.rate:,.0f} samples/s per "
          f"channel, {len(a)} frames): sample to screen p50 {q[0]:.0f} ms, p95 {q[1]:.0f} ms, "
          f"max {a[:, 0].max():.0f} ms (target p95 <= 60 ms); of which ring to websocket p50 "
          f"{qs[0]:.0f} / p95 {qs[1]:.0f} ms, websocket to screen p50 {qp[0]:.0f} / p95 "
          f"{qp[1]:.0f} ms; {_load(res['page'])}")  # fmt: skip
    page, bare = res["page"], res["without"]
    diff = np.array([a.cpu_share - b.cpu_share for a, b in zip(page, bare)]) * 100
    print(f"  the logger process's CPU share: {np.median([t.cpu_share for t in bare]) * 100:.2f}"
          f" % without, {np.median([t.cpu_share for t in page]) * 100:.2f} % with the page open"
          f" (paired difference median {np.median(diff):+.2f} % of a core); samples lost "
          f"{sum(t.lost for t in bare)} without, {sum(t.lost for t in page)} with the page, in "
          f"{len(page)} trials each")  # fmt: skip


if __name__ == "__main__":
    main()
