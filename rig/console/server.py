"""The console's web server (Starlette on uvicorn): the page, its websocket, the run browser.

``cutlab console TARGET`` serves a campaign folder (live while its campaign runs: the ring named
in ``<folder>/live.json``; its run files always) or one run file. Endpoints:

- ``/`` the page and ``/static/*`` (uPlot vendored, no CDN: the lab PC may be offline);
- ``/ws``: 25 frames a second of force min/max bins (one bin per pixel of the page's plot), the
  status (machine, stream, progress, events) when it changes, the runs when they change; the
  page's commands (hold, resume, abort) go to the campaign through the ring;
- ``/api/history``: run history across campaigns (the run catalogue, else the campaign folders
  beside this one);
- ``/api/health``, ``/api/runs``, ``/api/run?file=NAME`` (blocks, events, program) and
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
import ipaddress
import json
import math
import os
import secrets
import socket
import sys
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import numpy as np
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from analysis.errors import AnalysisError, ConfigError
from analysis.runs import file as rf
from rig.console.common import (
    LIVE_FILE,
    TICK_S,
    TOKEN_ENV,
    WILDCARD_BINDS,
    pid_alive,
    url_of,
)
from rig.console.ring import RingError, RingReader

STATIC = Path(__file__).parent / "static"
STALE_S = 3.0  # s without a heartbeat: the campaign process is gone
DEFAULT_PX, DEFAULT_WINDOW_S = 1000, 10.0
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
COMMANDS = ("hold", "resume", "abort")
WS_MAX_BYTES = 64 * 1024  # a page's messages are < 100 bytes; larger ones are closed (1009)
POLL_S = 0.005  # how often a connection looks for new samples between frames
MIN_FRAME_S = 0.025  # frames of new samples at most this often (the page redraws on each)
SPECTRUM_N = 4096  # samples per spectrum (0.5 s at 8 kHz: 2 Hz bins)
SPECTRUM_PX = 400
LOG_BUDGET = 20  # logged lines of refusals / bad messages per connection (then one more saying so)


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
        self.until_wall: float | None = None  # when a lingering server exits (time.time())
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
            self._mark_gone()
            # A killed campaign's ring and live.json are removed now (issue 31); the mapping
            # keeps its last state for the page.
            self._clean_up()
            if self.linger_s is not None and time.monotonic() - self.gone_since > self.linger_s:
                self.should_exit = True
        elif self.ring is not None and self.ring.closed and self.linger_s is not None:
            self._mark_gone()
            if time.monotonic() - self.gone_since > self.linger_s:
                self.should_exit = True

    def _mark_gone(self) -> None:
        if self.gone_since is None:
            self.gone_since = time.monotonic()
            if self.linger_s is not None:
                self.until_wall = round(time.time() + self.linger_s, 1)

    def alive(self) -> bool:
        """The campaign process is there and beating."""
        r = self.ring
        if r is None or r.closed:
            return False
        return r.heartbeat_age_s() < STALE_S and pid_alive(r.writer_pid)

    def _clean_up(self) -> None:
        """The campaign died without closing: its ring and pointer are left to us."""
        r = self.ring
        if r is None or pid_alive(r.writer_pid) or not r.path.exists():
            return
        with contextlib.suppress(OSError):
            r.path.unlink()
        if self.folder is not None:
            pointer = self.folder / LIVE_FILE
            with contextlib.suppress(OSError, ValueError, AttributeError):
                if json.loads(pointer.read_text()).get("ring") == str(r.path):  # not a new one's
                    pointer.unlink()

    def live_state(self) -> dict[str, Any]:
        r = self.ring
        if r is None:
            return {"live": False, "alive": False, "ended": ""}
        ended = ""
        if r.closed:
            ended = "closed"
        elif not self.alive():
            ended = "gone"
        return {"live": True, "alive": self.alive(), "ended": ended, "until": self.until_wall}

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


MAX_HISTORY = 50  # campaigns listed in the history


def _history(folder: Path | None) -> dict[str, Any]:
    """Run history across campaigns: from the run catalogue (``cutlab catalog index``) of this
    folder or a parent, else from the campaign folders beside this one (their manifests)."""
    if folder is None:
        return {"source": "", "campaigns": []}
    from analysis.catalog.index import INDEX_NAME, load_index

    here = folder.resolve()
    for d in (here, *list(here.parents)[:3]):
        index = d / INDEX_NAME
        if index.is_file():
            df = load_index(index)
            out = []
            for name, g in df.groupby("campaign", sort=True):
                counts = g["status"].value_counts().to_dict()
                out.append({"campaign": str(name), "runs": len(g), "statuses": {
                    str(k): int(v) for k, v in counts.items()},
                    "latest_utc": str(g["indexed_utc"].max())})  # fmt: skip
            return {"source": f"the run catalogue {index}", "campaigns": out[:MAX_HISTORY]}
    out = []
    for d in sorted(here.parent.iterdir())[: 10 * MAX_HISTORY]:
        m = d / "campaign.json"
        if not m.is_file():
            continue
        with contextlib.suppress(OSError, ValueError, AttributeError):
            runs = json.loads(m.read_text()).get("runs", {})
            counts: dict[str, int] = {}
            for e in runs.values():
                st = str(e.get("status", "")) if isinstance(e, dict) else ""
                counts[st] = counts.get(st, 0) + 1
            out.append({"campaign": d.name, "runs": len(runs), "statuses": counts,
                        "this": d == here})  # fmt: skip
    return {"source": f"the campaign folders in {here.parent} (no run catalogue: cutlab "
            "catalog index)", "campaigns": out[:MAX_HISTORY]}  # fmt: skip


def _run_details(path: Path) -> dict[str, Any]:
    run = rf.load_run(path, samples=False, repair=False)
    b = run.blocks
    start = b["exec_s"].where(np.isfinite(b["exec_s"]), b["send_s"]).to_numpy(float)
    order = np.argsort(start, kind="stable")
    spans = []
    t_end = run.t0_s + run.duration_s if math.isfinite(run.t0_s) else math.nan
    for j, i in enumerate(order):
        t1 = start[order[j + 1]] if j + 1 < len(order) else t_end
        row = {"block": int(b["block"].iloc[i]), "line": int(b["line"].iloc[i]),
               "text": str(b["text"].iloc[i]), "t0": _num(start[i]), "t1": _num(t1)}  # fmt: skip
        spans.append(row)
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


def _binned(t: np.ndarray, data: np.ndarray, px: int) -> dict[str, Any]:
    """Min and max per pixel of ``data`` (n, c) at times ``t``; when there are no more samples
    than two a pixel, the samples themselves (``raw``: a zoom shows what was recorded)."""
    n = len(data)
    if n <= 2 * max(px, 1):
        vals = np.round(data.T, 3).tolist() if n else [[] for _ in range(data.shape[1])]
        return {"t": np.round(t, 6).tolist(), "min": vals, "max": vals, "raw": True, "n": n}
    per = max(1, math.ceil(n / max(px, 1)))
    b, lo, hi, _ = bins_min_max(data, np.arange(n), per)
    return {"t": np.round(t[b * per], 5).tolist(), "min": np.round(lo, 2).tolist(),
            "max": np.round(hi, 2).tolist(), "raw": False, "n": n}  # fmt: skip


def _trace(path: Path, t0: float | None, t1: float | None, px: int) -> dict[str, Any]:
    meta = rf.load_run(path, samples=False, repair=False)
    base = meta.t0_s if math.isfinite(meta.t0_s) else 0.0
    start = None if t0 is None else max(0.0, t0 - base)
    stop = None if t1 is None else max(0.0, t1 - base)
    run = rf.load_run(path, start, stop, repair=False)
    data = run.force_n if run.force_n is not None else run.volts
    unit = "N" if run.force_n is not None else "V"
    out = _binned(np.asarray(run.time_s, float), np.asarray(data, float), px)
    return out | {"unit": unit, "channels": list(run.channel_names)}


def _live_trace(ring: RingReader, t0: float | None, t1: float | None, px: int) -> dict[str, Any]:
    """The live run's forces between ``t0`` and ``t1`` (run clock s; None: its start / now) as
    the ring still holds them (the whole run unless it outgrew the ring), binned as
    :func:`_binned`."""
    c = _Client(px, DEFAULT_WINDOW_S)
    _, c.meta = ring.get_json("meta")
    meta = c.meta or {}
    if not meta.get("rate_hz"):
        raise ValueError("no live run yet")
    rate, base = float(meta["rate_hz"]), float(meta.get("t0_s", 0.0))
    gen = ring.generation
    first = 0 if t0 is None else max(0, int((t0 - base) * rate))
    g, start, offset, rows = ring.rows_since(gen, max(0, first - ring.row_to_sample))
    if g != gen:
        raise ValueError("a new run began: ask again")
    t = base + (np.arange(start, start + len(rows)) + offset) / rate
    keep = np.ones(len(rows), bool) if t1 is None else t <= t1
    if t0 is not None:
        keep &= t >= t0
    data = c._force(rows[keep]) if keep.any() else np.zeros((0, rows.shape[1] if rows.ndim == 2
                                                                 else 0))  # fmt: skip
    return _binned(t[keep], data, px) | {"unit": "N", "channels": meta.get("channels", []),
                                         "run": meta.get("run"), "first_t": _num(t[0]) if len(t)
                                         else None}  # fmt: skip


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
        self.last_rev = -1
        self.seen: tuple[int, int] = (-1, -1)
        self.written_ns = 0  # the ring's last block already timed on the page

    def news(self, hub: Hub) -> bool:
        """New samples (or a new run) in the ring since the last frame."""
        r = hub.ring
        return r is not None and (r.rows_written, r.generation) != self.seen

    def frame(self, hub: Hub) -> dict[str, Any]:
        self.frames += 1
        if hub.ring is not None:
            self.seen = (hub.ring.rows_written, hub.ring.generation)
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
            self.last_rev = -1
        st_seq = ring.seq("status")
        if st_seq != self.status_seq:
            self.status_seq, msg["status"] = ring.get_json("status")
        if self.meta:
            # read before the rows: the newest block in this frame came no earlier (the latency
            # the page shows errs long, never short)
            written_ns = ring.written_ns
            bins = self._bins(ring)
            if bins is not None:
                if written_ns != self.written_ns:  # new samples in this frame: their latency
                    bins["written_ms"] = written_ns / 1e6
                    self.written_ns = written_ns
                msg["bins"] = bins
            if self.frames % 5 == 0:  # 5 times a second: a revolution at 300 rpm and up
                readouts = self._readouts(ring)
                if readouts is not None:
                    msg["readouts"] = readouts
                spectrum = self._spectrum(ring)
                if spectrum is not None:
                    msg["spectrum"] = spectrum
        return msg

    def _force(self, rows: np.ndarray) -> np.ndarray:
        """(n, c) N of the ring's rows (volts or codes): the run's zero and calibration."""
        meta = self.meta or {}
        volts = rows.astype(np.float64)
        if meta.get("sample_format") == rf.SAMPLE_FORMAT_RAW and meta.get("scaling_coeff"):
            volts = rf.raw_to_volts(rows, np.asarray(meta["scaling_coeff"], float))
        zero = np.asarray(meta.get("zero_v") or np.zeros(volts.shape[1]), float)
        return np.einsum("nj,ij->ni", volts - zero, np.asarray(meta["volts_to_n"], float))

    def _spectrum(self, ring: RingReader) -> dict[str, Any] | None:
        """Amplitude spectrum (N, Hann window) per channel of the newest SPECTRUM_N samples, up
        to the larger of 10 tooth-passing harmonics and 1 kHz, at most SPECTRUM_PX points (the
        largest in each); the tooth-passing frequency and the chatter frequency if known."""
        meta = self.meta or {}
        rate = float(meta.get("rate_hz") or 0.0)
        if rate <= 0 or meta.get("zero_v") is None:
            return None
        n = SPECTRUM_N
        g, _, _, rows = ring.rows_since(self.gen, max(0, ring.rows_written - n))
        if g != self.gen or len(rows) < n:
            return None
        f = self._force(rows)
        win = np.hanning(n)
        amp = np.abs(np.fft.rfft((f - f.mean(axis=0)) * win[:, None], axis=0)) * 2 / win.sum()
        freq = np.fft.rfftfreq(n, 1 / rate)
        rpm = abs(float(meta.get("spindle_rpm") or 0.0))
        teeth = meta.get("teeth") or 0
        tooth_hz = rpm / 60 * teeth if rpm and teeth else None
        top = min(rate / 2, max(1000.0, 10.5 * tooth_hz if tooth_hz else 0.0))
        k = int(np.searchsorted(freq, top))
        per = max(1, -(-k // SPECTRUM_PX))
        m = (k // per) * per
        peak = amp[:m].reshape(-1, per, amp.shape[1]).max(axis=1)
        return {"f_hz": np.round(freq[:m:per], 2).tolist(), "amp": np.round(peak.T, 3).tolist(),
                "df_hz": round(rate / n, 4), "tooth_hz": tooth_hz,
                "chatter_hz": meta.get("chatter_hz"), "channels": meta.get("channels", []),
                "unit": "N"}  # fmt: skip

    def _readouts(self, ring: RingReader) -> dict[str, Any] | None:
        """Mean, peak and RMS of the last whole revolution per channel, N, as
        :func:`analysis.runs.per_revolution` cuts a run: revolution k is device samples
        round(k * spr) .. round((k + 1) * spr) - 1, spr = rate * 60 / rpm (the run's programmed
        speed). None until a new revolution is complete, or without a speed."""
        meta = self.meta or {}
        rpm = abs(float(meta.get("spindle_rpm") or 0.0))
        rate = float(meta.get("rate_hz") or 0.0)
        if rpm <= 0 or rate <= 0 or meta.get("zero_v") is None:
            return None  # before the zero: no forces to speak of
        spr = rate * 60.0 / rpm
        if spr < 8:
            return None
        w = ring.rows_written
        g, start, offset, rows = ring.rows_since(self.gen, max(0, w - int(2 * spr) - 2))
        if g != self.gen or len(rows) == 0:
            return None
        n_dev = start + offset + len(rows)  # device samples up to the newest
        k = int(n_dev // spr)
        while k >= 0 and round((k + 1) * spr) > n_dev:
            k -= 1
        if k <= self.last_rev or k < 0:
            return None
        a, b = round(k * spr) - offset - start, round((k + 1) * spr) - offset - start
        if a < 0:
            return None  # overwritten or a hole: the next one
        f = self._force(rows[a:b])
        self.last_rev = k
        t0 = float(meta.get("t0_s", 0.0))
        return {"run": meta.get("run"), "rev": k, "rpm": rpm,
                "t_s": round(t0 + round(k * spr) / rate, 5),
                "channels": meta.get("channels", []), "unit": "N",
                "mean": np.round(f.mean(axis=0), 2).tolist(),
                "peak": np.round(f.max(axis=0), 2).tolist(),
                "rms": np.round(np.sqrt((f * f).mean(axis=0)), 2).tolist()}  # fmt: skip

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
        force = self._force(rows)
        per = max(1, round(rate * self.window_s / self.px))
        sample = np.arange(start, start + len(rows)) + offset
        b, lo, hi, last = bins_min_max(force, sample, per)
        self.cursor = start + last  # the last bin may still grow: sent again next frame
        t0 = float(meta.get("t0_s", 0.0))
        return {"t": np.round(t0 + b * per / rate, 5).tolist(),
                "min": np.round(lo, 1).tolist(), "max": np.round(hi, 1).tolist()}  # fmt: skip


def say(message: str) -> None:
    """One line on stderr (the console's log: refusals, dropped messages, errors)."""
    line = " ".join(str(message).split())[:400]
    with contextlib.suppress(OSError, ValueError):
        print(f"cutlab: console: {line}", file=sys.stderr, flush=True)


def host_allowlist(bind: str) -> frozenset[str]:
    """The host names (lower case, IPv6 without brackets) a request's Host may name: this
    computer's loopback names and the bound address; bound to all addresses, also the computer's
    own names and addresses (:func:`host_allowed` then takes any IP address too)."""
    names = set(LOOPBACK_NAMES)
    b = bind.strip().strip("[]").lower()
    if b in WILDCARD_BINDS:
        with contextlib.suppress(OSError):
            me = socket.gethostname()
            names |= {me.lower(), socket.getfqdn().lower()}
            names |= {str(i[4][0]).lower() for i in socket.getaddrinfo(me, None)}
    else:
        names.add(b)
    return frozenset(names)


def _hostname(netloc: str) -> str | None:
    """The host of ``host[:port]`` (lower case, IPv6 without brackets); None if malformed."""
    if not netloc or "@" in netloc or any(c.isspace() or c in "/?#\\" for c in netloc):
        return None
    try:
        parts = urlsplit("//" + netloc)
        _ = parts.port  # a non-numeric port raises
    except ValueError:
        return None
    return parts.hostname or None


def host_allowed(host: str | None, allow: frozenset[str], any_ip: bool) -> bool:
    if host is None:
        return False
    if host in allow:
        return True
    if any_ip:  # bound to all addresses: an IP address is no DNS name, so cannot be rebound
        with contextlib.suppress(ValueError):
            ipaddress.ip_address(host.split("%")[0])
            return True
    return False


def _peer(scope: dict[str, Any]) -> str:
    c = scope.get("client")
    if not c:
        return "an unknown client"
    host, port = c[0], c[1]
    return f"[{host}]:{port}" if ":" in str(host) else f"{host}:{port}"


def cookie_name(port: int) -> str:
    """Cookies are shared by every port of a host: one name per console port."""
    return f"cutlab_console_token_{port}"


Send = Callable[[dict[str, Any]], Awaitable[None]]


class Guard:
    """ASGI middleware in front of the console app: the Host allowlist, the websocket's Origin,
    the token (see the module docstring); and a last net under the app: an exception is one
    logged line and a 500 (or a closed websocket), never an ASGI traceback."""

    def __init__(self, app: Any, token: str, bind: str = "127.0.0.1") -> None:
        if not token:
            raise ValueError("the console needs a token")
        self.app, self.token = app, token.encode()
        self.allow = host_allowlist(bind)
        self.any_ip = bind.strip().strip("[]") in WILDCARD_BINDS
        self._logged = 0

    def _say(self, message: str) -> None:
        # A page or script knocking in a loop must not fill the campaign's terminal.
        self._logged += 1
        if self._logged <= 10 * LOG_BUDGET:
            say(message)
        elif self._logged == 10 * LOG_BUDGET + 1:
            say("more refusals: not logged")

    def _token_ok(self, given: str | None) -> bool:
        return bool(given) and secrets.compare_digest(str(given).encode(), self.token)

    def check(self, scope: dict[str, Any]) -> tuple[int, str, bool]:
        """(0 or the HTTP status refusing the request, why, the token came in the query)."""
        headers = {k.decode("latin-1").lower(): v.decode("latin-1")
                   for k, v in scope.get("headers", [])}  # fmt: skip
        host_header = headers.get("host", "")
        if not host_allowed(_hostname(host_header), self.allow, self.any_ip):
            return 403, f"Host {host_header[:80]!r} is not this computer", False
        if scope["type"] == "websocket":
            origin = headers.get("origin")
            if origin is None:
                return 403, "no Origin (a websocket must come from the console's page)", False
            try:
                o = urlsplit(origin)
                ok = o.scheme in ("http", "https") and o.netloc.lower() == host_header.lower()
            except ValueError:
                ok = False
            if not ok or not host_allowed(_hostname(o.netloc), self.allow, self.any_ip):
                return 403, f"Origin {origin[:80]!r} is not this console's page", False
        if scope["path"].startswith("/static/"):
            return 0, "", False  # the page's scripts and styles: no data
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        in_query = (query.get("token") or [None])[-1]
        if in_query is not None:
            if self._token_ok(in_query):
                return 0, "", True
            return 401, "wrong token", False
        auth = headers.get("authorization", "")
        scheme, _, value = auth.partition(" ")
        if scheme.lower() in ("bearer", "token") and self._token_ok(value.strip()):
            return 0, "", False
        port = (scope.get("server") or ("", 0))[1]
        for part in headers.get("cookie", "").split(";"):
            name, _, value = part.strip().partition("=")
            if name == cookie_name(port) and self._token_ok(value):
                return 0, "", False
        return 401, "no token or a wrong one (open the address printed with its ?token=)", False

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        what = "websocket" if scope["type"] == "websocket" else scope.get("method", "GET")
        where = f"{what} {scope.get('path', '')} from {_peer(scope)}"
        code, why, token_in_query = self.check(scope)
        if code:
            self._say(f"refused {where}: {why}")
            await _refuse(scope, send, code, why)
            return
        started = False

        async def send_on(message: dict[str, Any]) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
                if token_in_query:  # later requests of the page carry it by themselves
                    port = (scope.get("server") or ("", 0))[1]
                    cookie = (f"{cookie_name(port)}={self.token.decode()}; Path=/; HttpOnly; "
                              "SameSite=Strict")  # fmt: skip
                    headers = [*message.get("headers", []), (b"set-cookie", cookie.encode())]
                    message = {**message, "headers": headers}
            elif message["type"] in ("websocket.accept", "websocket.close"):
                started = True
            await send(message)

        try:
            await self.app(scope, receive, send_on)
        except Exception as exc:  # noqa: BLE001 - one line, never a traceback in the campaign's log
            self._say(f"error in {where}: {type(exc).__name__}: {exc}")
            if not started:
                with contextlib.suppress(Exception):
                    await _refuse(scope, send, 500, "internal error (logged by the console)")


async def _refuse(scope: dict[str, Any], send: Send, code: int, why: str) -> None:
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 1008 if code != 500 else 1011})
        return
    body = json.dumps({"error": why}).encode()
    await send({"type": "http.response.start", "status": code,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode())]})  # fmt: skip
    await send({"type": "http.response.body", "body": body})


def _finite(text: str) -> float:
    x = float(text)
    if not math.isfinite(x):
        raise ValueError(f"{text[:20]} is out of range")
    return x


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number")


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def parse_message(text: str | None) -> tuple[dict[str, Any] | None, str]:
    """A page's websocket message: (the message, "") or (None, why it is dropped)."""
    if text is None:
        return None, "a binary message (expected JSON text)"
    try:
        msg = json.loads(text, parse_float=_finite, parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        return None, f"not JSON ({str(exc)[:80]})"
    if not isinstance(msg, dict):
        return None, f"a JSON {type(msg).__name__} (expected an object with a type)"
    kind = msg.get("type")
    if kind == "hello":
        for key in ("px", "window_s"):
            if key in msg and not _is_number(msg[key]):
                return None, f"hello: {key} = {str(msg[key])[:40]!r}: expected a number"
        return msg, ""
    if kind == "cmd":
        cmd = msg.get("cmd")
        if not isinstance(cmd, str) or cmd not in COMMANDS:
            return None, (f"cmd: {str(cmd)[:40]!r}: unknown command (expected hold, resume or "
                          "abort)")  # fmt: skip
        return msg, ""
    return None, f"type {str(kind)[:40]!r}: unknown (expected hello or cmd)"


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
        if q.get("live"):
            if hub.ring is None:
                raise ValueError("no live campaign here")
            return _live_trace(hub.ring, t0, t1, px)
        return _trace(hub.run_path(q["file"]), t0, t1, px)

    async def ws_endpoint(ws: WebSocket) -> None:
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
