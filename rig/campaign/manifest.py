"""The campaign folder's own record: the manifest (``campaign.json``), the lock that stops two
runners writing one campaign, and which run files count as finished (resume).

The manifest keeps the SHA-256 of every input the runs depend on (the campaign file, the tool, the
material, the machine, the rig config; and each run's program): resuming after any of them changed
would mix cuts of two experiments in one report, so :meth:`Manifest.check_inputs` refuses it,
naming what changed, unless the operator forces it (the change is then recorded) or starts fresh
(:func:`start_fresh` moves the earlier runs aside, nothing is deleted).
"""

from __future__ import annotations

import contextlib
import datetime as dt
import hashlib
import json
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Unpack

from analysis import __version__
from analysis.config import config_dir
from analysis.runs import file as rf
from analysis.validation import JsonValue
from rig.campaign.config import Campaign
from rig.campaign.results import InputRecord, ManifestEntry
from rig.errors import RigError


def utc_now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


def _sha256(obj: Any) -> str:
    text = obj if isinstance(obj, str) else json.dumps(obj, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


#: Campaign fields that do not change what is cut and recorded: how runs are watched and paced,
#: injected faults, the report, notes. Editing them does not stop a resume.
_NOT_THE_EXPERIMENT = {
    "campaign": ("description", "operator", "output_dir"),
    "sim": ("speed", "link_timeout_s", "sim_"),
    "suspenders": ("",),
    "chatter": ("",),
    "analysis": ("",),
}


def experiment_fields(campaign: Campaign) -> dict[str, JsonValue]:
    """The campaign file's fields that decide the runs, flattened (``matrix[0].depth_mm``)."""
    out: dict[str, JsonValue] = {}

    def walk(prefix: str, v: Any) -> None:
        if isinstance(v, dict):
            for k, x in v.items():
                walk(f"{prefix}.{k}" if prefix else k, x)
        elif isinstance(v, list | tuple) and v and isinstance(v[0], dict):
            for i, x in enumerate(v):
                walk(f"{prefix}[{i}]", x)
        else:
            out[prefix] = list(v) if isinstance(v, tuple) else v

    for table, value in campaign.spec.model_dump().items():
        skip = _NOT_THE_EXPERIMENT.get(table, ())
        if isinstance(value, dict):
            value = {k: x for k, x in value.items() if not any(k.startswith(p) for p in skip)}
        walk(table, value)
    return out


def campaign_inputs(campaign: Campaign) -> dict[str, InputRecord]:
    """Every input the campaign's runs depend on: {input: {sha256, source}} (the config's also
    with its ``fields``, to name the ones that changed)."""
    c = campaign.spec.campaign
    cfg = config_dir()
    fields = experiment_fields(campaign)
    here = Path(campaign.path).parent

    def catalogue(kind: str, user: str | None, name: str) -> str:
        # the campaign's own catalogue is searched first (its names shadow the shipped ones)
        shipped = cfg / f"{kind}.toml"
        where = f"{here / user}, then {shipped}" if user else str(shipped)
        where = campaign.source(kind) or where  # the file it was read from (--tools too)
        return f"{where} [{kind}.{name}]"

    return {
        "config": {"sha256": _sha256(fields), "source": str(campaign.path), "fields": fields},
        "tool": {"sha256": _sha256(campaign.tool.model_dump()),
                 "source": catalogue("tools", c.tools_file, c.tool)},
        "material": {"sha256": _sha256(campaign.material.model_dump()),
                     "source": catalogue("materials", c.materials_file, c.material)},
        "machine": {"sha256": _sha256(campaign.machine.model_dump()),
                    "source": f"machine '{c.machine}' ({cfg / 'machines'})"},
        "rig": {"sha256": _sha256(campaign.rig.model_dump()),
                "source": str(c.rig_config or cfg / "rig.toml")},
    }  # fmt: skip


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
        self.data.setdefault("runs", {})
        self.inputs = campaign_inputs(campaign)
        self._text = campaign.text

    def changed_inputs(self, programs: dict[str, str]) -> list[str]:
        """One line per input that differs from what the recorded runs used (``programs``: run
        name -> its program's SHA-256 now). A manifest of an older cutlab has only the config's."""
        old = dict(self.data.get("inputs", {}))
        lines = []
        for name, now in self.inputs.items():
            was = old.get(name, {}).get("sha256")
            if was is not None and was != now["sha256"]:
                what = _field_changes(old[name].get("fields"), now.get("fields"))
                lines.append(f"{name} changed: {now['source']}: sha256 {was[:12]} -> "
                             f"{now['sha256'][:12]}{what}")  # fmt: skip
        for run, entry in self.data["runs"].items():
            was, now_sha = entry.get("program_sha256"), programs.get(run)
            if was and now_sha and was != now_sha:
                lines.append(f"program of run {entry.get('index', '?')} ({run}) changed: "
                             f"{entry.get('file', '')}: sha256 {was[:12]} -> {now_sha[:12]}")
            elif was and now_sha is None:
                lines.append(f"run {run} ({entry.get('file', '')}) is no longer in the campaign")
        return lines

    def accept_inputs(self, forced_changes: Sequence[str] = ()) -> None:
        """Store the current inputs; ``forced_changes`` (a forced resume) are recorded."""
        if forced_changes:
            self.data.setdefault("forced_resumes", []).append(
                {"utc": utc_now(), "changes": list(forced_changes)}
            )
        self.data["inputs"] = self.inputs
        self.data["config_sha256"] = hashlib.sha256(self._text.encode()).hexdigest()
        self.data["software_version"] = __version__
        self.save()

    def entry(self, name: str) -> ManifestEntry | None:
        entry: ManifestEntry | None = self.data["runs"].get(name)
        return entry

    def set(self, name: str, **kw: Unpack[ManifestEntry]) -> None:
        self.data["runs"].setdefault(name, {}).update(kw)
        self.save()

    def save(self) -> None:
        """Write the manifest atomically (a temporary file, fsync, rename): a failed write (a
        full disk) leaves the previous manifest as it was, removes the temporary file and raises
        a one-line RigError."""
        save_json_atomic(self.path, self.data, "campaign manifest")


def save_json_atomic(path: Path, data: object, what: str) -> None:
    """``data`` as JSON at ``path``, all or nothing (see :meth:`Manifest.save`)."""
    text = json.dumps(data, indent=2, default=str).encode()
    tmp = path.with_name(f"{path.name}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            view = memoryview(text)
            while view:
                view = view[os.write(fd, view) :]
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        from rig.log import disk_full_reason

        why = disk_full_reason(exc.errno, path.parent) or exc.strerror or str(exc)
        kept = "the previous one is kept" if path.exists() else "none was written"
        raise RigError(f"{path}: cannot save the {what}: {why}; {kept}") from None
    with contextlib.suppress(OSError):  # the rename itself survives a power cut
        dfd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


@contextlib.contextmanager
def campaign_lock(folder: Path) -> Iterator[None]:
    lock = folder / "campaign.lock"
    pid = lock_holder(folder)
    if pid is not None and pid != os.getpid():
        raise RigError(f"{folder}: campaign already running in process {pid} ({lock})")
    lock.write_text(str(os.getpid()))
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            lock.unlink()


def _field_changes(old: dict[str, Any] | None, new: dict[str, Any] | None) -> str:
    """`` (field old -> new, ...)`` for the fields that differ (empty without both)."""
    if not old or not new:
        return ""
    diff = [f"{k} {old.get(k, '(none)')!r} -> {new.get(k, '(none)')!r}"
            for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)]  # fmt: skip
    return f" ({'; '.join(diff[:6])}{'; ...' if len(diff) > 6 else ''})" if diff else ""


def start_fresh(folder: Path) -> Path | None:
    """Move an earlier campaign's runs, programs and manifest into ``folder/before-<utc>/`` (kept,
    never deleted); the folder to hold them, or None if there was nothing."""
    names = [n for n in ("runs", "programs", "tap", "report", "campaign.json", "campaign.toml")
             if (folder / n).exists()]  # fmt: skip
    if not names:
        return None
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    dest = folder / f"before-{stamp}"
    k = 1
    while dest.exists():
        dest, k = folder / f"before-{stamp}-{k}", k + 1
    dest.mkdir()
    for n in names:
        os.replace(folder / n, dest / n)
    return dest


def lock_holder(folder: Path) -> int | None:
    """The pid of a live runner holding the campaign's lock, else None."""
    try:
        pid = int((folder / "campaign.lock").read_text().strip() or 0)
    except (OSError, ValueError):
        return None
    if pid <= 0:
        return None
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except PermissionError:
        return pid
    return pid


def run_status(path: Path) -> tuple[str, str]:
    """(status, reason) stored in a run file; ("missing", ...) or ("unreadable", ...) otherwise."""
    if not path.exists():
        return "missing", "no run file"
    try:
        run = rf.load_run(path, samples=False)
    except Exception as exc:  # noqa: BLE001 - any unreadable file is re-run, and kept
        return "unreadable", str(exc)
    return run.status, run.reason


def finished(folder: Path, entry: ManifestEntry | None, stem: str, sha256: str = "") -> bool:
    """Whether a test's run is done: its file closed with ``success`` and the manifest says so,
    or the manifest still says ``running`` (the runner was stopped after the file was closed)
    and the file recorded this very program (``sha256``): a finished cut is not cut again."""
    path = folder / "runs" / f"{stem}.h5"
    status = None if entry is None else entry.get("status")
    if status == rf.STATUS_SUCCESS:
        return run_status(path)[0] == rf.STATUS_SUCCESS
    if (entry is None or status != rf.STATUS_RUNNING or not sha256
            or entry.get("program_sha256") != sha256):  # fmt: skip
        return False
    try:
        run = rf.load_run(path, samples=False)
    except Exception:  # noqa: BLE001 - unreadable: run again (and kept)
        return False
    return (run.status == rf.STATUS_SUCCESS and run.complete
            and run.conditions.get("program_sha256") == sha256)  # fmt: skip


def set_aside(path: Path) -> Path | None:
    """Keep an earlier attempt's file (never delete recorded data)."""
    if not path.exists():
        return None
    k = 1
    while (dest := path.with_name(f"{path.stem}.attempt-{k}.h5")).exists():
        k += 1
    os.replace(path, dest)
    return dest
