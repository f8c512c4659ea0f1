"""The console's web server (Starlette on uvicorn): the page, its websocket, the run browser.

``cutlab console TARGET`` serves a campaign folder (live while its campaign runs: the ring named
in ``<folder>/live.json``; its run files always) or one run file. Endpoints:

- ``/`` the page and ``/static/*`` (uPlot vendored, no CDN: the lab PC may be offline);
- ``/ws``: 25 frames a second of force min/max bins (one bin per pixel of the page's plot), the
  status (machine, stream, progress, events) when it changes, the runs when they change; the
  page's commands (hold, resume, abort) go to the campaign through the ring;
- ``/api/history``: run history across campaigns (the run catalogue, else the campaign folders
  beside this one);
- ``/api/health``, ``/api/runs``, ``/api/run?file=NAME`` (blocks, events, program, the
  toolpath: :mod:`rig.console.run_path`) and
  ``/api/trace?file=NAME&t0=&t1=&px=`` (min/max bins of a run file's forces, run clock s).

Run files are opened read-only (never repaired from here). Access (:class:`Guard`, issue 31): a
web page elsewhere must not reach the machine's feed hold nor read the runs, also through a DNS
name rebound to this computer, so

- the Host header must name this computer: ``localhost``, ``127.0.0.1``, ``[::1]`` or the bound
  address (bound to all addresses: also the computer's own names and any IP address; a rebinding
  page's Host is a DNS name): others get 403 (a websocket is refused);
- a websocket must carry an Origin whose host is allowed and equals the Host header;
- everything but ``/static/*`` needs the session's token (:func:`secrets.token_urlsafe`, made
  per server and printed with the address as ``http://127.0.0.1:PORT/?token=...``): in the query,
  as ``Authorization: Bearer TOKEN``, or in the cookie the server sets when the token comes in the
  query; else 401 (a websocket is refused). There is no mode without it.

A bad websocket message (not JSON, not an object, NaN or infinity, an unknown type or command, a
wrong type) is dropped with one logged line and an ``error`` reply; no traceback reaches stderr.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import secrets
import socket
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from analysis.errors import AnalysisError, ConfigError
from analysis.runs import file as rf
from rig.console.common import TICK_S, TOKEN_ENV, url_of
from rig.console.frames import DEFAULT_PX, DEFAULT_WINDOW_S, _Client, _live_trace, _trace
from rig.console.guard import LOG_BUDGET, Guard, _peer, parse_message, say
from rig.console.hub import Hub, _history, _run_details, resolve_target
from rig.console.run_path import run_toolpath
from rig.console.trail import SAMPLE_S as TRAIL_SAMPLE_S

STATIC = Path(__file__).parent / "static"
WS_MAX_BYTES = 64 * 1024  # a page's messages are < 100 bytes; larger ones are closed (1009)
POLL_S = 0.005  # how often a connection looks for new samples between frames
MIN_FRAME_S = 0.025  # frames of new samples at most this often (the page redraws on each)
PULL_S = 0.1  # the ring into the server's history this often (a slot lives seconds)

__all__ = ["make_app", "resolve_target", "serve"]


def make_app(
    target: str | Path,
    linger_s: float | None = None,
    *,
    token: str | None = None,
    bind: str = "127.0.0.1",
) -> Any:
    """The console app for a campaign folder or a run file (see the module docstring), behind
    its :class:`Guard`; ``token`` (default: a new one; always ``app.state.token``) is the
    session's, ``bind`` the address served (for the Host allowlist)."""
    folder, run_file = resolve_target(target)
    hub = Hub(folder, run_file, linger_s)
    token = token or secrets.token_urlsafe(24)

    async def index(request: Request) -> FileResponse:
        return FileResponse(STATIC / "index.html")

    async def health(request: Request) -> JSONResponse:
        return JSONResponse({"ok": True, "target": str(folder or run_file)} | hub.live_state())

    async def runs(request: Request) -> JSONResponse:
        return JSONResponse({"runs": await asyncio.to_thread(hub.runs)})

    async def history(request: Request) -> JSONResponse:
        try:
            return JSONResponse(await asyncio.to_thread(_history, folder))
        except (ConfigError, AnalysisError, OSError, ValueError) as exc:
            return JSONResponse({"source": f"not shown: {str(exc).splitlines()[0][:200]}",
                                 "campaigns": []})  # fmt: skip

    def run_info(q: Any) -> dict[str, Any]:
        path = hub.run_path(q["file"])
        return _run_details(path) | {"path": run_toolpath(path)}  # the toolpath views'

    def trace(q: Any) -> dict[str, Any]:
        t0 = float(q["t0"]) if q.get("t0") else None
        t1 = float(q["t1"]) if q.get("t1") else None
        px = min(max(int(q.get("px", 1500)), 10), 5000)
        if q.get("live"):
            if hub.ring is None:
                raise ValueError("no live campaign here")
            return _live_trace(hub.ring, t0, t1, px)
        return _trace(hub.run_path(q["file"]), t0, t1, px)

    async def ws_endpoint(ws: WebSocket) -> None:
        await _ws_session(ws, hub)

    async def watch() -> None:
        while True:
            await asyncio.sleep(1.0)
            hub.refresh()

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette):  # noqa: ANN202 - an async context
        tasks = [asyncio.create_task(watch()), asyncio.create_task(_follow_trail(hub)),
                 asyncio.create_task(_follow_ring(hub))]  # fmt: skip
        yield
        for task in tasks:
            task.cancel()

    routes = [
        Route("/", index),
        Route("/api/health", health),
        Route("/api/runs", runs),
        Route("/api/history", history),
        Route("/api/run", _guarded(run_info)),
        Route("/api/trace", _guarded(trace)),
        WebSocketRoute("/ws", ws_endpoint),
        Mount("/static", app=StaticFiles(directory=STATIC), name="static"),
    ]
    inner = Starlette(routes=routes, lifespan=lifespan)
    inner.state.hub = hub
    app = Guard(inner, token, bind)
    app.state = inner.state
    app.state.token = token
    return app


async def _follow_ring(hub: Hub) -> None:
    """The ring's new blocks into the server's own history, with or without a page: before the
    run writer reuses their slots (its 64 buffers: seconds of blocks)."""
    while True:
        await asyncio.sleep(PULL_S)
        if hub.ring is not None:
            hub.ring.pull()


async def _follow_trail(hub: Hub) -> None:
    """The executed path sampled from the ring (:mod:`rig.console.trail`); an error is logged
    once and the path stops growing (the page keeps the rest)."""
    while True:
        await asyncio.sleep(TRAIL_SAMPLE_S)
        try:
            hub.trail.sample(hub.ring)
        except Exception as exc:  # noqa: BLE001 - the rest of the console goes on
            say(f"the executed path stops: {type(exc).__name__}: {exc}")
            return


def _guarded(fn: Any) -> Any:
    """An endpoint answering ``fn(query)`` in a thread; bad input, a missing run: 404, one line."""

    async def endpoint(request: Request) -> JSONResponse:
        try:
            return JSONResponse(await asyncio.to_thread(fn, request.query_params))
        except (ConfigError, rf.RunFileError, OSError, KeyError, ValueError) as exc:
            return JSONResponse({"error": str(exc).splitlines()[0][:300]}, status_code=404)

    return endpoint


async def _ws_session(ws: WebSocket, hub: Hub) -> None:
    """One page's websocket: frames at TICK_S (sooner for new samples), its messages handled."""
    await ws.accept()  # the Guard has checked Host, Origin and token
    peer = _peer(ws.scope)
    client = _Client(DEFAULT_PX, DEFAULT_WINDOW_S)
    # Bounded: a client sending faster than 25 frames a second are read waits (TCP holds it).
    inbox: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=256)
    bad = 0

    async def receive() -> None:
        nonlocal bad
        while True:
            m = await ws.receive()
            if m["type"] != "websocket.receive":
                return  # websocket.disconnect
            msg, why = parse_message(m.get("text"))
            if msg is None:
                bad += 1
                if bad <= LOG_BUDGET:
                    say(f"dropped a websocket message from {peer}: {why}")
                elif bad == LOG_BUDGET + 1:
                    say(f"more bad websocket messages from {peer}: dropped, not logged")
                msg = {"type": "_error", "message": why}
            await inbox.put(msg)

    reader = asyncio.create_task(receive())
    loop = asyncio.get_running_loop()
    last_news, due = 0.0, loop.time()
    try:
        while not reader.done():
            if hub.should_exit:  # the page says so rather than "connection lost"
                bye = {"type": "bye", "message": "the console server has stopped"}
                await ws.send_text(json.dumps(bye))
                await ws.close(1001)
                break
            while not inbox.empty():
                await _handle(ws, hub, client, inbox.get_nowait(), peer)
            msg = client.frame(hub)
            sig = hub.runs_signature() if client.frames % 25 == 1 else client.runs_sig
            if sig != client.runs_sig:
                client.runs_sig = sig
                msg["runs"] = await asyncio.to_thread(hub.runs)
            if "bins" in msg:  # the server's part of the latency ends here
                msg["bins"]["sent_ms"] = time.time() * 1e3
            await ws.send_text(json.dumps(msg, separators=(",", ":"), allow_nan=False))
            # The next frame: at TICK_S, or sooner when new samples come (not before
            # MIN_FRAME_S): a block waits for no beat (the sample-to-screen latency).
            if "written_ms" in msg.get("bins", {}):
                last_news = loop.time()  # frames of new samples: at most every MIN_FRAME_S
            if loop.time() >= due:  # the beat's frame: the next beat (late: no pile-up)
                due = max(due + TICK_S, loop.time())
            while (now := loop.time()) < due and inbox.empty() and not hub.should_exit:
                if now - last_news >= MIN_FRAME_S and client.news(hub):
                    break
                await asyncio.sleep(min(POLL_S, max(0.0, due - now)))
    except (WebSocketDisconnect, RuntimeError, ConnectionError):
        pass
    finally:
        reader.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await reader  # its exception (a connection gone mid-read) is retrieved here
        if reader.done() and not reader.cancelled() and reader.exception() is not None:
            exc = reader.exception()
            if not isinstance(exc, WebSocketDisconnect | RuntimeError | ConnectionError):
                say(f"websocket from {peer} ended: {type(exc).__name__}: {exc}")


async def _handle(
    ws: WebSocket, hub: Hub, client: _Client, msg: dict[str, Any], peer: str = ""
) -> None:
    """A message checked by :func:`parse_message` (or its ``_error``: the reply says why)."""
    kind = msg.get("type")
    if kind == "_error":
        await ws.send_text(json.dumps({"type": "error", "message": msg["message"]}))
    elif kind == "hello":
        client.px = int(min(max(msg.get("px", DEFAULT_PX), 50), 4000))
        client.window_s = float(min(max(msg.get("window_s", DEFAULT_WINDOW_S), 1.0), 60.0))
        client.gen = -1  # resend the window at the new resolution
    elif kind == "cmd":
        cmd = msg["cmd"]
        if hub.ring is None or not hub.alive():
            reply = {"type": "cmd", "cmd": cmd, "ok": False, "message": "no campaign running"}
        else:
            # who asked goes with it: the run's reason names the console and this client
            seq = hub.ring.send_command({"cmd": cmd, "at": time.time(), "from": peer})
            reply = {"type": "cmd", "cmd": cmd, "ok": True, "seq": seq, "message": "sent"}
        await ws.send_text(json.dumps(reply))


def serve(
    target: str | Path,
    port: int = 8765,
    bind: str = "127.0.0.1",
    linger_s: float | None = None,
    *,
    token: str | None = None,
    on_listening: Callable[[str], None] | None = None,
) -> None:
    """Serve the console until interrupted (or, with ``linger_s``, until that long after the
    campaign process is gone). ``token``: the session's (default: a new one); ``port`` 0: a free
    one; ``on_listening(url)`` is called once it listens, with the address and token."""
    import uvicorn

    token = token or secrets.token_urlsafe(24)
    app = make_app(target, linger_s, token=token, bind=bind)
    config = uvicorn.Config(app, host=bind, port=port, log_level="warning", ws="websockets-sansio",
                            lifespan="on", timeout_graceful_shutdown=1,
                            ws_max_size=WS_MAX_BYTES)  # fmt: skip
    server = uvicorn.Server(config)
    sockets = None
    if port == 0:  # bound here, so the address printed is the one listened on
        fam = socket.AF_INET6 if ":" in bind else socket.AF_INET
        sock = socket.socket(fam, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((bind.strip("[]"), 0))
        sockets, port = [sock], sock.getsockname()[1]

    async def main() -> None:
        task = asyncio.create_task(server.serve(sockets))
        told = False
        while not task.done():
            await asyncio.sleep(0.05 if not told else 0.5)
            if not told and server.started:
                told = True
                if on_listening is not None:
                    on_listening(url_of(bind, port, token))
            if app.state.hub.should_exit:
                server.should_exit = True
        await task

    asyncio.run(main())


def main(argv: list[str] | None = None) -> None:
    """``python -m rig.console.server TARGET --port P --bind B [--linger-s S]``: the server a
    live campaign starts (it needs none of the CLI; ``cutlab console`` is the user's door). The
    token comes in the environment (``CUTLAB_CONSOLE_TOKEN``: not on the command line, which
    other users can read); without it the server makes one and prints the address with it."""
    import argparse

    p = argparse.ArgumentParser(prog="python -m rig.console.server")
    p.add_argument("target")
    p.add_argument("--port", type=int, default=8765)
    p.add_argument("--bind", default="127.0.0.1")
    p.add_argument("--linger-s", type=float, default=None)
    a = p.parse_args(argv)
    token = os.environ.pop(TOKEN_ENV, "") or None

    def tell(url: str) -> None:
        say(f"listening at {url}")

    try:
        serve(a.target, a.port, a.bind, a.linger_s, token=token,
              on_listening=tell if token is None else None)  # fmt: skip
    except KeyboardInterrupt:  # Ctrl-C (uvicorn re-raises it after its clean shutdown)
        sys.exit(130)


if __name__ == "__main__":
    main()
