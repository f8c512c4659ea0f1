"""The console's web server (Starlette on uvicorn): the page, its websocket, the run browser.

``cutlab console TARGET`` serves a campaign folder (live while its campaign runs: the ring named
in ``<folder>/live.json``; its run files always) or one run file. Endpoints:

- ``/`` the page and ``/static/*`` (uPlot vendored, no CDN: the lab PC may be offline);
- ``/ws``: 25 frames a second of force min/max bins (one bin per pixel of the page's plot), the
  status (machine, stream, progress, events) when it changes, the runs when they change; the
  page's commands (hold, resume, abort) go to the campaign through the ring;
- ``/api/health``, ``/api/runs``, ``/api/run?file=NAME`` (blocks, events, program) and
  ``/api/trace?file=NAME&t0=&t1=&px=`` (min/max bins of a run file's forces, run clock s).

Run files are opened read-only (never repaired from here). A websocket whose Origin is not this
server is refused: a web page elsewhere must not reach the machine's feed hold.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import os
import time
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

import numpy as np
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from analysis.errors import ConfigError
from analysis.runs import file as rf
from rig.console.live import LIVE_FILE, TICK_S
from rig.console.ring import RingError, RingReader

STATIC = Path(__file__).parent / "static"
STALE_S = 3.0  # s without a heartbeat: the campaign process is gone
DEFAULT_PX, DEFAULT_WINDOW_S = 1000, 10.0


def resolve_target(target: str | Path) -> tuple[Path | None, Path | None]:
    """(campaign folder, single run file): what ``cutlab console TARGET`` serves."""
    p = Path(target)
    if p.is_file() and p.suffix == ".h5":
        return None, p
    if p.is_dir() and ((p / "runs").is_dir() or (p / "campaign.json").exists()
                       or (p / LIVE_FILE).exists()):  # fmt: skip
        return p, None
    raise ConfigError(
        f"console: {p}: expected a campaign folder (with runs/ or campaign.json) or a run file "
        "(.h5)"
    )


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return pid > 0


def bins_min_max(
    values: np.ndarray, sample: np.ndarray, per_bin: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Min and max per bin of ``per_bin`` samples (bin = sample // per_bin) of ``values``
    (n, c); returns (bin numbers (k,), min (c, k), max (c, k), position of the last bin's
    first row)."""
    if len(values) == 0:
        c = values.shape[1] if values.ndim == 2 else 0
        return np.zeros(0, np.int64), np.zeros((c, 0)), np.zeros((c, 0)), 0
    b = sample // per_bin
    starts = np.flatnonzero(np.r_[True, b[1:] != b[:-1]])
    lo = np.minimum.reduceat(values, starts, axis=0).T
    hi = np.maximum.reduceat(values, starts, axis=0).T
    return b[starts], lo, hi, int(starts[-1])


class Hub:
    """What every connection shares: the target, the ring of a live campaign (reattached when
    ``live.json`` changes), the campaign's liveness."""

    def __init__(self, folder: Path | None, run_file: Path | None, linger_s: float | None) -> None:
        self.folder, self.run_file, self.linger_s = folder, run_file, linger_s
        self.ring: RingReader | None = None
        self._pointer: str = ""
        self.pid = 0
        self.gone_since: float | None = None
        self.should_exit = False
        self.refresh()

    def refresh(self) -> None:
        if self.folder is None:
            return
        try:
            text = (self.folder / LIVE_FILE).read_text()
            ptr = json.loads(text)
        except (OSError, ValueError):
            text, ptr = "", None
        if text and text != self._pointer and isinstance(ptr, dict):
            with contextlib.suppress(RingError, KeyError, TypeError, ValueError):
                ring = RingReader(ptr["ring"])
                self.ring, self.pid, self.gone_since = ring, int(ptr.get("pid", 0)), None
        self._pointer = text or self._pointer
        if self.ring is not None and not self.ring.closed and not self.alive():
            self.gone_since = self.gone_since or time.monotonic()
            if self.linger_s is not None and time.monotonic() - self.gone_since > self.linger_s:
                self._clean_up()
                self.should_exit = True
        elif self.ring is not None and self.ring.closed and self.linger_s is not None:
            self.gone_since = self.gone_since or time.monotonic()
            if time.monotonic() - self.gone_since > self.linger_s:
                self.should_exit = True

    def alive(self) -> bool:
        """The campaign process is there and beating."""
        r = self.ring
        if r is None or r.closed:
            return False
        return r.heartbeat_age_s() < STALE_S and _pid_alive(r.writer_pid)

    def _clean_up(self) -> None:
        """The campaign died without closing: its ring and pointer are left to us."""
        if self.ring is not None and not _pid_alive(self.ring.writer_pid):
            with contextlib.suppress(OSError):
                self.ring.path.unlink()
            if self.folder is not None:
                with contextlib.suppress(OSError):
                    (self.folder / LIVE_FILE).unlink()

    def live_state(self) -> dict[str, Any]:
        r = self.ring
        if r is None:
            return {"live": False, "alive": False, "ended": ""}
        ended = ""
        if r.closed:
            ended = "closed"
        elif not self.alive():
            ended = "gone"
        return {"live": True, "alive": self.alive(), "ended": ended}

    # -- the run files ---------------------------------------------------------------------------
    def run_files(self) -> list[Path]:
        if self.run_file is not None:
            return [self.run_file]
        assert self.folder is not None
        return sorted((self.folder / "runs").glob("*.h5"))

    def runs(self) -> list[dict[str, Any]]:
        manifest: dict[str, Any] = {}
        if self.folder is not None:
            with contextlib.suppress(OSError, ValueError):
                manifest = json.loads((self.folder / "campaign.json").read_text()).get("runs", {})
        by_file = {Path(str(e.get("file", ""))).name: e for e in manifest.values()
                   if isinstance(e, dict)}  # fmt: skip
        out = []
        for p in self.run_files():
            e = by_file.get(p.name)
            if e is None:
                try:
                    run = rf.load_run(p, samples=False, repair=False)
                    e = {"status": run.status, "reason": run.reason}
                except (rf.RunFileError, OSError, KeyError, ValueError) as exc:
                    e = {"status": "unreadable", "reason": str(exc)[:200]}
            out.append({"file": p.name, "status": e.get("status", ""),
                        "reason": e.get("reason", "")})  # fmt: skip
        return out

    def runs_signature(self) -> tuple[Any, ...]:
        files = self.run_files()
        m = self.folder / "campaign.json" if self.folder is not None else None
        with contextlib.suppress(OSError):
            return (len(files), m.stat().st_mtime_ns if m is not None else 0)
        return (len(files), 0)

    def run_path(self, name: str) -> Path:
        for p in self.run_files():
            if p.name == name:
                return p
        raise ConfigError(f"console: no run file {name!r} here")


def _run_details(path: Path) -> dict[str, Any]:
    run = rf.load_run(path, samples=False, repair=False)
    b = run.blocks
    start = b["exec_s"].where(np.isfinite(b["exec_s"]), b["send_s"]).to_numpy(float)
    order = np.argsort(start, kind="stable")
    spans = []
    t_end = run.t0_s + run.duration_s if math.isfinite(run.t0_s) else math.nan
    for j, i in enumerate(order):
        t1 = start[order[j + 1]] if j + 1 < len(order) else t_end
        spans.append({"block": int(b["block"].iloc[i]), "line": int(b["line"].iloc[i]),
                      "text": str(b["text"].iloc[i]), "t0": _num(start[i]), "t1": _num(t1)})
    ev = run.events
    events = [{"t_s": _num(t), "kind": str(k), "message": str(m)}
              for t, k, m in zip(ev["time_s"], ev["kind"], ev["message"])
              if not str(m).startswith("executed block")]  # fmt: skip
    return {
        "file": path.name, "status": run.status, "reason": run.reason,
        "channels": list(run.channel_names), "rate_hz": run.rate_hz, "t0_s": _num(run.t0_s),
        "duration_s": run.duration_s, "blocks": spans, "events": events,
        "program": run.program_text.splitlines(), "calibrated": run.calibration is not None,
    }  # fmt: skip


def _num(x: Any) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _trace(path: Path, t0: float | None, t1: float | None, px: int) -> dict[str, Any]:
    meta = rf.load_run(path, samples=False, repair=False)
    base = meta.t0_s if math.isfinite(meta.t0_s) else 0.0
    start = None if t0 is None else max(0.0, t0 - base)
    stop = None if t1 is None else max(0.0, t1 - base)
    run = rf.load_run(path, start, stop, repair=False)
    data = run.force_n if run.force_n is not None else run.volts
    n = len(data)
    per = max(1, math.ceil(n / max(px, 1)))
    b, lo, hi, _ = bins_min_max(data, np.arange(n), per)
    t = run.time_s[b * per] if n else np.zeros(0)
    return {"t": np.round(t, 5).tolist(), "min": np.round(lo, 2).tolist(),
            "max": np.round(hi, 2).tolist(), "unit": "N" if run.force_n is not None else "V",
            "channels": list(run.channel_names)}  # fmt: skip


class _Client:
    """One page's view of the ring: its cursor and bin width."""

    def __init__(self, px: int, window_s: float) -> None:
        self.px, self.window_s = px, window_s
        self.gen, self.cursor, self.meta_seq, self.status_seq = -1, 0, -1, -1
        self.meta: dict[str, Any] | None = None
        self.catch_up = True
        self.frames = 0
        self.runs_sig: tuple[Any, ...] | None = None
        self.live_state: dict[str, Any] | None = None

    def frame(self, hub: Hub) -> dict[str, Any]:
        self.frames += 1
        msg: dict[str, Any] = {"type": "frame", "n": self.frames}
        state = hub.live_state()
        if state != self.live_state:
            self.live_state = msg["live"] = state
        ring = hub.ring
        if ring is None:
            return msg
        seq = ring.seq("meta")
        if ring.generation != self.gen or seq != self.meta_seq:
            self.meta_seq, self.meta = ring.get_json("meta")
            self.gen = ring.generation
            rate = float((self.meta or {}).get("rate_hz", 0) or 0)
            self.cursor = max(0, ring.rows_written - int(self.window_s * rate))
            msg["meta"], msg["reset"] = self.meta, True
            self.catch_up = True
        st_seq = ring.seq("status")
        if st_seq != self.status_seq:
            self.status_seq, msg["status"] = ring.get_json("status")
        if self.meta:
            bins = self._bins(ring)
            if bins is not None:
                msg["bins"] = bins
        return msg

    def _bins(self, ring: RingReader) -> dict[str, Any] | None:
        meta = self.meta or {}
        rate = float(meta["rate_hz"])
        # A window on a (re)start, else at most half a second a frame: a view that fell behind
        # (or a DAQ faster than its rate, as in bench/bench_console.py) skips ahead.
        most = int(rate * (self.window_s if self.catch_up else 0.5)) + 1
        self.catch_up = False
        g, start, offset, rows = ring.rows_since(self.gen, self.cursor, most)
        if g != self.gen or len(rows) == 0 or rows.ndim != 2:
            return None
        volts = rows.astype(np.float64)
        if meta.get("sample_format") == rf.SAMPLE_FORMAT_RAW and meta.get("scaling_coeff"):
            volts = rf.raw_to_volts(rows, np.asarray(meta["scaling_coeff"], float))
        zero = np.asarray(meta.get("zero_v") or np.zeros(volts.shape[1]), float)
        force = np.einsum("nj,ij->ni", volts - zero, np.asarray(meta["volts_to_n"], float))
        per = max(1, round(rate * self.window_s / self.px))
        sample = np.arange(start, start + len(rows)) + offset
        b, lo, hi, last = bins_min_max(force, sample, per)
        self.cursor = start + last  # the last bin may still grow: sent again next frame
        t0 = float(meta.get("t0_s", 0.0))
        return {"t": np.round(t0 + b * per / rate, 5).tolist(),
                "min": np.round(lo, 1).tolist(), "max": np.round(hi, 1).tolist()}  # fmt: skip


def _same_origin(ws: WebSocket) -> bool:
    origin = ws.headers.get("origin")
    if origin is None:
        return True  # not a browser (scripts, tests)
    return urlparse(origin).netloc == ws.headers.get("host", "")


def make_app(target: str | Path, linger_s: float | None = None) -> Starlette:
    """The console app for a campaign folder or a run file (see the module docstring)."""
    folder, run_file = resolve_target(target)
    hub = Hub(folder, run_file, linger_s)

    async def index(request: Request) -> FileResponse:
        return FileResponse(STATIC / "index.html")

    async def health(request: Request) -> JSONResponse:
        return JSONResponse({"ok": True, "target": str(folder or run_file)} | hub.live_state())

    async def runs(request: Request) -> JSONResponse:
        return JSONResponse({"runs": await asyncio.to_thread(hub.runs)})

    def _guarded(fn: Any) -> Any:
        async def endpoint(request: Request) -> JSONResponse:
            try:
                return JSONResponse(await asyncio.to_thread(fn, request.query_params))
            except (ConfigError, rf.RunFileError, OSError, KeyError, ValueError) as exc:
                return JSONResponse({"error": str(exc).splitlines()[0][:300]}, status_code=404)

        return endpoint

    def run_info(q: Any) -> dict[str, Any]:
        return _run_details(hub.run_path(q["file"]))

    def trace(q: Any) -> dict[str, Any]:
        t0 = float(q["t0"]) if q.get("t0") else None
        t1 = float(q["t1"]) if q.get("t1") else None
        px = min(max(int(q.get("px", 1500)), 10), 5000)
        return _trace(hub.run_path(q["file"]), t0, t1, px)

    async def ws_endpoint(ws: WebSocket) -> None:
        if not _same_origin(ws):
            await ws.close(code=1008)
            return
        await ws.accept()
        client = _Client(DEFAULT_PX, DEFAULT_WINDOW_S)
        inbox: asyncio.Queue[dict[str, Any]] = asyncio.Queue()

        async def receive() -> None:
            with contextlib.suppress(WebSocketDisconnect, RuntimeError):
                while True:
                    await inbox.put(await ws.receive_json())

        reader = asyncio.create_task(receive())
        loop = asyncio.get_running_loop()
        due = loop.time()
        try:
            while not reader.done():
                while not inbox.empty():
                    await _handle(ws, hub, client, inbox.get_nowait())
                msg = client.frame(hub)
                sig = hub.runs_signature() if client.frames % 25 == 1 else client.runs_sig
                if sig != client.runs_sig:
                    client.runs_sig = sig
                    msg["runs"] = await asyncio.to_thread(hub.runs)
                await ws.send_text(json.dumps(msg, separators=(",", ":"), allow_nan=False))
                due = max(due + TICK_S, loop.time())  # a fixed rate; late frames do not pile up
                await asyncio.sleep(due - loop.time())
        except (WebSocketDisconnect, RuntimeError, ConnectionError):
            pass
        finally:
            reader.cancel()

    async def watch() -> None:
        while True:
            await asyncio.sleep(1.0)
            hub.refresh()

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette):  # noqa: ANN202 - an async context
        task = asyncio.create_task(watch())
        yield
        task.cancel()

    routes = [
        Route("/", index),
        Route("/api/health", health),
        Route("/api/runs", runs),
        Route("/api/run", _guarded(run_info)),
        Route("/api/trace", _guarded(trace)),
        WebSocketRoute("/ws", ws_endpoint),
        Mount("/static", app=StaticFiles(directory=STATIC), name="static"),
    ]
    app = Starlette(routes=routes, lifespan=lifespan)
    app.state.hub = hub
    return app


async def _handle(ws: WebSocket, hub: Hub, client: _Client, msg: dict[str, Any]) -> None:
    kind = msg.get("type")
    if kind == "hello":
        client.px = min(max(int(msg.get("px", DEFAULT_PX)), 50), 4000)
        client.window_s = min(max(float(msg.get("window_s", DEFAULT_WINDOW_S)), 1.0), 60.0)
        client.gen = -1  # resend the window at the new resolution
    elif kind == "cmd":
        cmd = str(msg.get("cmd", ""))
        if cmd not in ("hold", "resume", "abort"):
            reply = {"type": "cmd", "cmd": cmd, "ok": False, "message": "unknown command"}
        elif hub.ring is None or not hub.alive():
            reply = {"type": "cmd", "cmd": cmd, "ok": False, "message": "no campaign running"}
        else:
            seq = hub.ring.send_command({"cmd": cmd, "at": time.time()})
            reply = {"type": "cmd", "cmd": cmd, "ok": True, "seq": seq, "message": "sent"}
        await ws.send_text(json.dumps(reply))


def serve(
    target: str | Path, port: int = 8765, bind: str = "127.0.0.1", linger_s: float | None = None
) -> None:
    """Serve the console until interrupted (or, with ``linger_s``, until that long after the
    campaign process is gone)."""
    import uvicorn

    app = make_app(target, linger_s)
    config = uvicorn.Config(app, host=bind, port=port, log_level="warning", ws="websockets-sansio",
                            lifespan="on", timeout_graceful_shutdown=1)  # fmt: skip
    server = uvicorn.Server(config)

    async def main() -> None:
        task = asyncio.create_task(server.serve())
        while not task.done():
            await asyncio.sleep(0.5)
            if app.state.hub.should_exit:
                server.should_exit = True
        await task

    asyncio.run(main())


def main(argv: list[str] | None = None) -> None:
    """``python -m rig.console.server TARGET --port P --bind B [--linger-s S]``: the server a
    live campaign starts (it needs none of the CLI; ``cutlab console`` is the user's door)."""
    import argparse

    p = argparse.ArgumentParser(prog="python -m rig.console.server")
    p.add_argument("target")
    p.add_argument("--port", type=int, default=8765)
    p.add_argument("--bind", default="127.0.0.1")
    p.add_argument("--linger-s", type=float, default=None)
    a = p.parse_args(argv)
    serve(a.target, a.port, a.bind, a.linger_s)


if __name__ == "__main__":
    main()
