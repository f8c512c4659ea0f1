"""The run index: one row per HDF5 run file under the indexed folders, in one SQLite file.

Why SQLite (the stdlib's ``sqlite3``): one file that travels with the archive, updated in place
(an incremental re-index rewrites only the rows of new, changed or deleted files), readable by
many processes while one writes (WAL journal: a query never waits for an indexer and never sees
half an update), and a schema any tool can read. A JSON or Parquet file would be rewritten whole
on every update and has no reader/writer safety of its own.

Incremental: a file whose size and mtime match its row is not opened; a new or changed file is
read (metadata only, ``load_run(samples=False)``: no force data) and hashed (SHA-256); a row
whose file is gone leaves the index. A run still being written (status ``running``: SWMR, its
writer alive) is indexed as ``running`` without a hash and re-read on every update, so it turns
``success`` / ``abort`` / ``fail`` (or ``interrupted`` when its writer died) once it ends. Files
are only read, never repaired.

The status is the run file's own (the campaign runner closes the file with it before it updates
its manifest); the campaign's ``campaign.json`` only supplies the campaign name and a run's group
when the run file does not record them (files of older cutlabs or other writers).
"""

from __future__ import annotations

import contextlib
import datetime as dt
import hashlib
import json
import math
import os
import sqlite3
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, TypedDict, cast

import pandas as pd

from analysis.errors import AnalysisError
from analysis.validation import JsonObject

#: The index file's name inside an indexed folder (``--index`` puts it elsewhere).
INDEX_NAME = ".cutlab-catalog.sqlite"
#: A parameter of an SQL condition on the index (a column's constant)
SqlValue = str | int | float | None
SCHEMA_VERSION = 1
RUN_SUFFIXES = (".h5", ".hdf5")
#: Columns of the ``runs`` table (and of the frame :func:`load_index` returns), with SQL types.
COLUMNS: dict[str, str] = {
    "path": "TEXT PRIMARY KEY",  # relative to the index's folder when inside it
    "campaign": "TEXT", "run": "TEXT", "group": "TEXT", "status": "TEXT", "reason": "TEXT",
    "current": "INTEGER",  # 0: an earlier attempt kept aside (.attempt-K, before-*/)
    "tool": "TEXT", "material": "TEXT", "machine": "TEXT", "spindle_rpm": "REAL",
    "feed_mm_min": "REAL", "fz_mm": "REAL", "depth_mm": "REAL", "width_mm": "REAL",
    "mode": "TEXT", "rig": "TEXT", "calibration_id": "TEXT", "rate_hz": "REAL",
    "samples_stored": "INTEGER", "samples_acquired": "INTEGER", "samples_lost": "INTEGER",
    "duration_s": "REAL", "n_events": "INTEGER", "events": "TEXT", "program": "TEXT",
    "software_version": "TEXT", "size_bytes": "INTEGER", "mtime_ns": "INTEGER",
    "sha256": "TEXT", "indexed_utc": "TEXT", "conditions": "TEXT",
}  # fmt: skip


class RowBase(TypedDict):
    """An index row's columns but the JSON ones (:data:`COLUMNS`; None: not recorded)."""

    path: str
    campaign: str | None
    run: str
    group: str | None
    status: str | None
    reason: str | None
    current: int
    tool: str | None
    material: str | None
    machine: str | None
    spindle_rpm: float | None
    feed_mm_min: float | None
    fz_mm: float | None
    depth_mm: float | None
    width_mm: float | None
    mode: str | None
    rig: str | None
    calibration_id: str | None
    rate_hz: float | None
    samples_stored: int | None
    samples_acquired: int | None
    samples_lost: int | None
    duration_s: float | None
    n_events: int | None
    program: str | None
    software_version: str | None
    size_bytes: int
    mtime_ns: int
    sha256: str | None
    indexed_utc: str


class IndexRow(RowBase):
    """A row as stored: ``events`` (kind -> count) and ``conditions`` as JSON text."""

    events: str | None
    conditions: str | None


class IndexUpdate(TypedDict):
    """What :func:`update_index` did (`cutlab catalog index --json`)."""

    index: str
    files: int
    added: int
    updated: int
    removed: int
    unchanged: int
    runs_in_index: int
    statuses: dict[str, int]
    seconds: float
    files_per_s: float


#: Read again on every update: the file may change without its size or mtime telling (a writer
#: that died leaves a ``running`` file that now reads ``interrupted``).
_RECHECK = ("running",)
#: Rows written per transaction: an interrupted first index of a large archive keeps its work.
_BATCH = 500


def index_file(where: str | Path | None) -> Path:
    """The index file of ``where``: an index file, or a folder holding :data:`INDEX_NAME`;
    None: the current folder's or its nearest parent's. Raises when there is none."""
    if where is not None:
        p = Path(where)
        if p.is_dir():
            p = p / INDEX_NAME
        if not p.is_file():
            raise AnalysisError(
                f"{where}: no run catalogue there (expected {INDEX_NAME} or an index file); "
                f"make one with `cutlab catalog index DIR`"
            )
        return p
    cwd = Path.cwd()
    for folder in (cwd, *cwd.parents):
        if (folder / INDEX_NAME).is_file():
            return folder / INDEX_NAME
    raise AnalysisError(
        f"{cwd}: no run catalogue ({INDEX_NAME}) here or in a parent folder; make one with "
        "`cutlab catalog index DIR`, or give --index FILE"
    )


@contextlib.contextmanager
def connect(path: Path, write: bool = False) -> Iterator[sqlite3.Connection]:
    """A connection to the index (created with ``write``), closed afterwards."""
    if not write and not path.is_file():
        raise AnalysisError(f"{path}: run catalogue not found")
    try:
        con = sqlite3.connect(path, timeout=60.0)  # waits for another indexer's transaction
    except sqlite3.Error as exc:
        raise AnalysisError(f"{path}: cannot open the run catalogue: {exc}") from None
    try:
        if write:
            with contextlib.suppress(sqlite3.OperationalError):  # e.g. a network file system
                con.execute("PRAGMA journal_mode=WAL")
            _schema(con, path)
        yield con
    except sqlite3.DatabaseError as exc:
        raise AnalysisError(f"{path}: not a readable run catalogue: {exc}") from None
    finally:
        con.close()


def _schema(con: sqlite3.Connection, path: Path) -> None:
    version = con.execute("PRAGMA user_version").fetchone()[0]
    if version not in (0, SCHEMA_VERSION):  # another cutlab's layout: rebuilt from the files
        con.execute("DROP TABLE IF EXISTS runs")
    cols = ", ".join(f'"{k}" {t}' for k, t in COLUMNS.items())
    con.execute(f"CREATE TABLE IF NOT EXISTS runs ({cols})")
    con.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
    con.commit()


def sha256_file(path: Path) -> str:
    with path.open("rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def _number(c: dict[str, Any], *keys: str) -> float:
    for k in keys:
        try:
            return float(c[k])
        except (KeyError, TypeError, ValueError):
            continue
    return math.nan


def _manifest(folder: Path, cache: dict[Path, JsonObject]) -> JsonObject:
    """The campaign manifest (``campaign.json``) of a campaign folder, {} without one."""
    if folder not in cache:
        try:
            doc = json.loads((folder / "campaign.json").read_text())
        except (OSError, ValueError):
            doc = None
        cache[folder] = doc if isinstance(doc, dict) else {}
    return cache[folder]


def _is_current(path: Path, root: Path) -> bool:
    parts = path.relative_to(root).parts
    return ".attempt-" not in path.name and not any(p.startswith("before-") for p in parts)


def read_row(path: Path, root: Path, manifests: dict[Path, JsonObject]) -> IndexRow:
    """The index row of a run file (metadata only; no force data is read)."""
    from analysis.runs import load_run

    st = path.stat()
    row: dict[str, Any] = {k: None for k in COLUMNS}
    row.update(run=path.stem, size_bytes=st.st_size, mtime_ns=st.st_mtime_ns,
               current=int(_is_current(path, root)), indexed_utc=_utc_now())  # fmt: skip
    try:
        run = load_run(path, samples=False, repair=False)
    except AnalysisError as exc:  # indexed as such, so that a query finds what cannot be read
        row.update(status="unreadable", reason=str(exc)[:400], sha256=sha256_file(path))
        return cast(IndexRow, row)  # built column by column from COLUMNS
    c = run.conditions
    folder = path.parent.parent if path.parent.name == "runs" else path.parent
    man = _manifest(folder, manifests)
    runs = man.get("runs")
    listed = runs.values() if isinstance(runs, dict) else ()
    entry = next((e for e in listed if isinstance(e, dict)
                  and Path(str(e.get("file", ""))).stem == path.stem), {})  # fmt: skip
    feed = _number(c, "feed_mm_min")
    fz = _number(c, "fz_mm")
    teeth, rpm = _number(c, "teeth"), _number(c, "spindle_rpm")
    if math.isnan(fz) and teeth > 0 and rpm > 0:  # one of the two feeds recorded
        fz = feed / (rpm * teeth)
    elif math.isnan(feed):
        feed = fz * rpm * teeth
    counts = run.events["kind"].value_counts().to_dict()
    row.update(
        campaign=str(c.get("campaign") or man.get("campaign") or ""),
        group=str(c.get("group") or entry.get("group") or ""),
        status=run.status, reason=run.reason, tool=str(c.get("tool", "")),
        material=str(c.get("material", "")), machine=str(c.get("machine", "")),
        spindle_rpm=rpm, feed_mm_min=feed, fz_mm=fz,
        depth_mm=_number(c, "depth_mm", "ap_mm"), width_mm=_number(c, "width_mm", "ae_mm"),
        mode=str(c.get("mode", "")), rig=str(run.rig.get("rig", "")),
        calibration_id=(run.calibration.attrs.get("calibration_id") if run.calibration
                        else None),
        rate_hz=run.rate_hz, samples_stored=run.samples_stored,
        samples_acquired=run.samples_acquired, samples_lost=run.samples_lost,
        duration_s=run.duration_s, n_events=len(run.events),
        events=json.dumps({str(k): int(v) for k, v in sorted(counts.items())}),
        program=str(run.program_info.get("name", "")), software_version=run.software_version,
        conditions=json.dumps(c, sort_keys=True, default=str),
        # A file still written changes under the hash: it gets one when it is closed.
        sha256=None if run.status in _RECHECK else sha256_file(path),
    )  # fmt: skip
    return cast(IndexRow, row)  # built column by column from COLUMNS


def _utc_now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


def _stored(path: Path, base: Path) -> str:
    """How a file is named in the index: relative to the index's folder when inside it (the
    archive can move), else absolute."""
    return str(path.relative_to(base)) if path.is_relative_to(base) else str(path)


def resolve(stored: str, base: str) -> str:
    """The file a row names (see :func:`_stored`); ``base`` the index's folder, resolved."""
    return os.path.join(base, stored)  # an absolute ``stored`` stays as it is


def _run_files(root: Path) -> Iterator[Path]:
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))  # the cache, hidden tools
        for name in sorted(files):
            if name.lower().endswith(RUN_SUFFIXES) and not name.startswith("."):
                yield Path(folder) / name


def update_index(
    dirs: Sequence[str | Path],
    index: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> IndexUpdate:
    """Index the run files under ``dirs`` into ``index`` (default ``dirs[0]/`` :data:`INDEX_NAME`):
    new and changed files are read, unchanged ones skipped, rows of files gone from ``dirs``
    removed. Returns the counts (files, added, updated, removed, unchanged, unreadable, running),
    the index path and the seconds taken. ``progress(done, total)`` after each file."""
    t0 = time.perf_counter()
    roots = []
    for d in dirs:
        p = Path(d)
        if not p.is_dir():
            raise AnalysisError(f"{d}: not a folder; expected a folder of run files (.h5)")
        roots.append(p.resolve())
    if not roots:
        raise AnalysisError("catalog index: give at least one folder of run files")
    ipath = Path(index) if index is not None else roots[0] / INDEX_NAME
    if ipath.is_dir():
        ipath = ipath / INDEX_NAME
    base = ipath.parent.resolve()
    files = sorted({f: r for r in reversed(roots) for f in _run_files(r)}.items())
    counts = dict.fromkeys(("added", "updated", "removed", "unchanged"), 0)
    manifests: dict[Path, JsonObject] = {}
    with connect(ipath, write=True) as con:
        known = {r[0]: r[1:] for r in con.execute(
            "SELECT path, size_bytes, mtime_ns, status FROM runs")}  # fmt: skip
        seen: set[str] = set()
        pending: list[dict[str, Any]] = []
        for k, (f, root) in enumerate(files):
            key = _stored(f, base)
            seen.add(key)
            try:
                st = f.stat()
            except OSError:  # deleted while we walked
                continue
            old = known.get(key)
            if old and old[:2] == (st.st_size, st.st_mtime_ns) and old[2] not in _RECHECK:
                counts["unchanged"] += 1
            else:
                counts["updated" if old else "added"] += 1
                pending.append({**read_row(f, root, manifests), "path": key})
                if len(pending) >= _BATCH:
                    _write(con, pending)
            if progress:
                progress(k + 1, len(files))
        _write(con, pending)
        gone = [p for p in known if p not in seen
                and any(Path(resolve(p, str(base))).is_relative_to(r) for r in roots)]  # fmt: skip
        with con:
            con.executemany("DELETE FROM runs WHERE path = ?", [(p,) for p in gone])
        counts["removed"] = len(gone)
        states = dict(con.execute("SELECT status, COUNT(*) FROM runs GROUP BY status").fetchall())
        total = con.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
    seconds = time.perf_counter() - t0
    return {"index": str(ipath), "files": len(files), "added": counts["added"],
            "updated": counts["updated"], "removed": counts["removed"],
            "unchanged": counts["unchanged"], "runs_in_index": total, "statuses": states,
            "seconds": seconds,
            "files_per_s": len(files) / seconds if seconds > 0 else math.inf}  # fmt: skip


def _write(con: sqlite3.Connection, rows: list[dict[str, Any]]) -> None:
    if not rows:
        return
    names = ", ".join(f'"{k}"' for k in COLUMNS)
    marks = ", ".join("?" for _ in COLUMNS)
    with con:  # one transaction: readers see all of it or none
        con.executemany(f"INSERT OR REPLACE INTO runs ({names}) VALUES ({marks})",
                        [tuple(r[k] for k in COLUMNS) for r in rows])  # fmt: skip
    rows.clear()


def load_index(
    index: str | Path | None = None, where_sql: str = "", params: Sequence[SqlValue] = ()
) -> pd.DataFrame:
    """The index as a frame, one row per run file, columns :data:`COLUMNS` plus ``file`` (the
    absolute path), sorted by campaign, run and path; ``where_sql`` (with ``params``) an SQL
    condition the rows must meet."""
    ipath = index_file(index)
    sql = "SELECT * FROM runs" + (f" WHERE {where_sql}" if where_sql else "")
    with connect(ipath) as con:
        try:
            df = pd.read_sql_query(sql, con, params=tuple(params))
        except (sqlite3.DatabaseError, pd.errors.DatabaseError) as exc:
            if where_sql:  # an index from before a column existed: read it all
                return load_index(ipath)
            raise AnalysisError(f"{ipath}: not a readable run catalogue: {exc}") from None
    base = str(ipath.parent.resolve())
    df["file"] = [resolve(p, base) for p in df["path"]]
    for col, kind in COLUMNS.items():
        if kind == "REAL":
            df[col] = df[col].astype(float)
    return df.sort_values(["campaign", "run", "path"], kind="stable").reset_index(drop=True)
