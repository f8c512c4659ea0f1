"""The campaign folder's own record: the manifest (``campaign.json``), the lock that stops two
runners writing one campaign, and which run files count as finished (resume)."""

from __future__ import annotations

import contextlib
import datetime as dt
import hashlib
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from analysis import __version__
from analysis.runs import file as rf
from rig.campaign.config import Campaign
from rig.errors import RigError


def utc_now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


class Manifest:
    def __init__(self, folder: Path, campaign: Campaign) -> None:
        self.path = folder / "campaign.json"
        self.data: dict[str, Any] = {}
        if self.path.exists():
            try:
                self.data = json.loads(self.path.read_text())
            except (OSError, json.JSONDecodeError) as exc:
                raise RigError(f"{self.path}: campaign manifest unreadable: {exc}") from None
        self.data.setdefault("campaign", campaign.name)
        self.data.setdefault("created_utc", utc_now())
        self.data["config_sha256"] = hashlib.sha256(campaign.text.encode()).hexdigest()
        self.data["software_version"] = __version__
        self.data.setdefault("runs", {})

    def entry(self, name: str) -> dict[str, Any] | None:
        return self.data["runs"].get(name)

    def set(self, name: str, **kw: Any) -> None:
        self.data["runs"].setdefault(name, {}).update(kw)
        self.save()

    def save(self) -> None:
        tmp = self.path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(self.data, indent=2, default=str))
        os.replace(tmp, self.path)


@contextlib.contextmanager
def campaign_lock(folder: Path) -> Iterator[None]:
    lock = folder / "campaign.lock"
    if lock.exists():
        try:
            pid = int(lock.read_text().strip() or 0)
        except (OSError, ValueError):
            pid = 0
        alive = False
        if pid > 0:
            try:
                os.kill(pid, 0)
                alive = pid != os.getpid()
            except (ProcessLookupError, PermissionError):
                alive = False
        if alive:
            raise RigError(f"{folder}: campaign already running in process {pid} ({lock})")
    lock.write_text(str(os.getpid()))
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            lock.unlink()


def run_status(path: Path) -> tuple[str, str]:
    """(status, reason) stored in a run file; ("missing", ...) or ("unreadable", ...) otherwise."""
    if not path.exists():
        return "missing", "no run file"
    try:
        run = rf.load_run(path, samples=False)
    except Exception as exc:  # noqa: BLE001 - any unreadable file is re-run, and kept
        return "unreadable", str(exc)
    return run.status, run.reason


def finished(folder: Path, entry: dict[str, Any] | None, stem: str) -> bool:
    path = folder / "runs" / f"{stem}.h5"
    if entry is None or entry.get("status") != rf.STATUS_SUCCESS:
        return False
    return run_status(path)[0] == rf.STATUS_SUCCESS


def set_aside(path: Path) -> Path | None:
    """Keep an earlier attempt's file (never delete recorded data)."""
    if not path.exists():
        return None
    k = 1
    while (dest := path.with_name(f"{path.stem}.attempt-{k}.h5")).exists():
        k += 1
    os.replace(path, dest)
    return dest
