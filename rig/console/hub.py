"""What every connection of a console server shares (:class:`Hub`): the target, the ring of a live
campaign (reattached when ``live.json`` changes), the campaign's liveness, the run files; and
what the browse mode reads: a run's blocks and events, the history across campaigns."""

from __future__ import annotations

import contextlib
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from analysis.errors import ConfigError
from analysis.runs import file as rf
from rig.console.chatter import StabilityAt
from rig.console.common import LIVE_FILE, pid_alive
from rig.console.results import LiveState
from rig.console.ring import RingError, RingReader
from rig.console.trail import Trail

STALE_S = 3.0  # s without a heartbeat: the campaign process is gone


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
        self.trail = Trail()  # the executed path (the 3-D view), sampled by the server
        self.stability = StabilityAt()  # the lobes at the current speed
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
            gone_since = self._mark_gone()
            # A killed campaign's ring and live.json are removed now (issue 31); the mapping
            # keeps its last state for the page.
            self._clean_up()
            if self.linger_s is not None and time.monotonic() - gone_since > self.linger_s:
                self.should_exit = True
        elif self.ring is not None and self.ring.closed and self.linger_s is not None:
            gone_since = self._mark_gone()
            if time.monotonic() - gone_since > self.linger_s:
                self.should_exit = True

    def _mark_gone(self) -> float:
        """When the campaign was first seen gone (now, if it just went), monotonic s."""
        if self.gone_since is None:
            self.gone_since = time.monotonic()
            if self.linger_s is not None:
                self.until_wall = round(time.time() + self.linger_s, 1)
        return self.gone_since

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

    def live_state(self) -> LiveState:
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

    def runs_signature(self) -> tuple[int, int]:
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
                by_status = g["status"].value_counts().to_dict()
                out.append({"campaign": str(name), "runs": len(g), "statuses": {
                    str(k): int(v) for k, v in by_status.items()},
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
