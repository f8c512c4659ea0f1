"""Force identification over a catalogue query, with the per-run reductions as dask tasks.

The heavy part of ``analyze forces`` is reducing each run file to its revolution average (the
steady window, the synchronous average, the per-revolution means: every sample is read). Here
each file's reduction is one dask task that opens the file read-only with h5py in the worker
and streams it in chunks (:func:`analysis.identify.reduce_run_file`: memory is the chunk, not
the run); only the small average travels back. The fit then runs on the averages exactly as
:func:`analysis.identify.fit_files` does, so the coefficients are those of ``analyze forces`` on
the same files.

Where the tasks run: ``scheduler`` None uses a ``scheduler-address`` from the dask config if
there is one, else the dask config's ``scheduler``, by default dask's threaded scheduler on this
machine (h5py reads one at a time, the numpy reduction in parallel); ``"threads"``, ``"processes"``,
``"sync"`` name a local one; ``tcp://HOST:PORT`` a dask.distributed scheduler, whose workers
must see the run files under the same paths (a shared file system). A scheduler is reached
before anything else, a cached fit too (a wrong address is an error, not ignored), within
:data:`CONNECT_TIMEOUT_S`. A worker that dies is
replaced and its tasks rerun by the scheduler; a reduction has no side effect, so a rerun gives
the same result.

The cache: each reduction is kept in ``<index>.cache/`` (beside the index file) as a pickle,
keyed by the file's SHA-256 (from the index) and name, cutlab's version, the source of the
reduction's modules and the reduction's parameters; a later query over the same runs reads no
force data. The fit's result is kept there too, keyed by everything it depends on: the selected
files' hashes in order, the options, the content of the files they name and of the config files
read by default, and the source of the ``analysis`` package; the same query over unchanged
files then returns it without fitting again (a query over other runs, or one that writes
plots or validates, fits). Delete the folder to drop it. It holds pickles: share it only as you
share the archive.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import re
import socket
import sys
import threading
import time
from collections.abc import Sequence
from importlib.util import find_spec
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

from analysis import __version__
from analysis.catalog.index import index_file
from analysis.catalog.query import query_runs
from analysis.errors import AnalysisError
from analysis.identify import ForcesResult, fit_files

if TYPE_CHECKING:
    from collections.abc import Mapping

    from distributed import Client
    from typing_extensions import Unpack

    from analysis.identify.options import ImportOptions


class FitOptions(TypedDict, total=False):
    """What :func:`fit_catalog` hands to :func:`analysis.identify.fit_files`."""

    model: str | None
    tool: str | None
    overrides: Mapping[str, object] | None
    rig_path: str | Path | None
    rate_hz: float | None
    tolerance: float
    validate: Sequence[str | Path] | None
    plot_dir: str | Path | None
    options: ImportOptions | None
    keep: bool

LOCAL_SCHEDULERS = ("threads", "processes", "sync", "synchronous", "single-threaded")
#: Modules whose code decides a file's reduction: an edit to them invalidates the cache.
_REDUCTION_CODE = (
    "analysis.identify._common",
    "analysis.identify.reading",
    "analysis.identify.options",
    "analysis.identify.facemill",
    "analysis.identify.conditions",
    "analysis.identify.axes",
    "analysis.runs.steady",
    "analysis.runs.sync",
    "analysis.forces.models",
    "analysis.runs.file",
)


def cache_dir(index: Path) -> Path:
    return index.with_suffix(".cache")


def reduction_key(reducer: object) -> str:
    """What besides the file decides a reduction: version, the code and the parameters."""
    code = [Path(find_spec(m).origin).read_text() for m in _REDUCTION_CODE]  # type: ignore
    return _digest(__version__, repr(reducer), *code)


def _digest(*parts: str) -> str:
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:24]


def _fit_key(rows: Any, fit_kw: FitOptions) -> str | None:
    """The key of a fit's result (module docstring), None when the fit has side effects."""
    if fit_kw.get("plot_dir") or fit_kw.get("validate"):
        return None
    from analysis.config import config_dir

    def content(v: Any) -> str:
        if isinstance(v, str | Path) and Path(v).is_file():
            return f"{v}:{hashlib.sha256(Path(v).read_bytes()).hexdigest()}"
        if hasattr(v, "__dataclass_fields__"):
            return repr(v) + "".join(content(getattr(v, f)) for f in v.__dataclass_fields__)
        return repr(v)

    spec = find_spec("analysis")
    assert spec is not None and spec.origin is not None  # this very module is in it
    package = Path(spec.origin).parent
    code = [p.read_text() for p in sorted(package.rglob("*.py"))]
    configs = [content(p) for p in sorted(config_dir().glob("*.toml"))]
    runs = [f"{r.file}:{r.sha256}" for r in rows.itertuples()]
    options = [f"{k}={content(v)}" for k, v in sorted(fit_kw.items())]
    return "fit-" + _digest(__version__, *runs, *options, *configs, *code)


def _load(path: Path) -> Any:
    try:
        with path.open("rb") as fh:
            return pickle.load(fh)
    except FileNotFoundError:
        return None
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError):
        return None  # a damaged or foreign entry: reduce again (and overwrite it)


def _store(path: Path, value: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with tmp.open("wb") as fh:
        pickle.dump(value, fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)  # readers see the whole entry or none


#: How long to try to reach a dask scheduler (distributed's default is 30 s; a scheduler on
#: the lab's network answers in milliseconds)
CONNECT_TIMEOUT_S = 4.0


def distributed_address(scheduler: str | None) -> str | None:
    """The dask.distributed scheduler ``scheduler`` (or the dask config's
    ``scheduler-address``) names, None for a local one; a malformed one is one line."""
    import dask

    address = scheduler or dask.config.get("scheduler-address", None)
    if scheduler in LOCAL_SCHEDULERS or not address:
        return None
    if not re.fullmatch(r"[a-z]+://\S+", str(address)):  # tcp://, tls://, inproc://
        raise AnalysisError(f"--scheduler {address}: expected {', '.join(LOCAL_SCHEDULERS[:3])} "
                            "or a dask scheduler's address, tcp://HOST:PORT")  # fmt: skip
    return str(address)


def connect(address: str) -> Client:
    """A ``distributed.Client`` of the scheduler at ``address`` (not made the default client),
    or one line within :data:`CONNECT_TIMEOUT_S` saying it cannot be reached."""
    from distributed import Client

    tcp = re.fullmatch(r"tcp://\[?([^\]/]+?)\]?:(\d+)/?", address)
    made: list[Any] = []
    given_up = threading.Event()
    deadline = time.monotonic() + CONNECT_TIMEOUT_S

    def make() -> None:
        try:
            client = Client(address, set_as_default=False, timeout=CONNECT_TIMEOUT_S)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            made.append(exc)
            return
        made.append(client)
        if given_up.is_set():  # answered after the deadline: nobody will use it
            client.close()

    try:
        if tcp:  # a closed port says so at once (distributed retries it until its timeout)
            socket.create_connection((tcp[1], int(tcp[2])), timeout=CONNECT_TIMEOUT_S).close()
        # distributed's timeout covers the connection, not the scheduler's answer: a port that
        # accepts and stays silent (not a dask scheduler) would hang the Client for ever
        maker = threading.Thread(target=make, name="dask-connect", daemon=True)
        maker.start()
        maker.join(max(0.0, deadline - time.monotonic()))
        if not made:
            given_up.set()
            if made and not isinstance(made[0], BaseException):  # (in between)
                made[0].close()
            raise TimeoutError(f"no dask scheduler answered in {CONNECT_TIMEOUT_S:g} s")
        if isinstance(made[0], BaseException):
            raise made[0]
        return made[0]
    except (OSError, TimeoutError, ValueError) as exc:
        why = " ".join(f"{type(exc).__name__}: {exc}".split())
        raise AnalysisError(f"--scheduler {address}: cannot reach the dask scheduler within "
                            f"{CONNECT_TIMEOUT_S:g} s ({why})") from None  # fmt: skip


def compute(tasks: Sequence[object], scheduler: str | None = None, progress: bool = False,
            client: Client | None = None) -> list[object]:  # fmt: skip
    """Compute dask ``tasks`` on ``scheduler`` (see the module docstring), or on ``client`` (a
    ``distributed.Client`` already connected), with dask's progress bar on stderr when
    ``progress``."""
    import dask

    if not tasks:
        return []
    address = None if client is not None else distributed_address(scheduler)
    if client is None and address is None:
        from dask.diagnostics import ProgressBar

        bar = ProgressBar(out=sys.stderr) if progress else contextlib.nullcontext()
        with bar:
            # None: the dask config's ``scheduler`` (or a default Client), else threads
            return list(dask.compute(*tasks, scheduler=scheduler))
    from distributed import progress as show_progress

    own = client is None
    if client is None:
        assert address is not None  # (no client and no address returned above)
        client = connect(address)
    try:
        futures = client.compute(list(tasks))
        if progress:
            # distributed's bar prints to stdout, and finds its scheduler through the default
            # client unless told (this one is not the default: "No clients found")
            with contextlib.redirect_stdout(sys.stderr):
                show_progress(futures, scheduler=client.scheduler.address)
        return list(client.gather(futures))
    finally:
        if own:
            client.close()


class CachedMapper:
    """A :data:`analysis.identify.reading.Mapper` that answers from the cache where it can and runs
    the other reductions as dask tasks; counts ``cached`` and ``reduced`` files."""

    def __init__(self, cache: Path, hashes: dict[str, str | None], scheduler: str | None = None,
                 progress: bool = False, client: Client | None = None) -> None:  # fmt: skip
        self.cache, self.hashes = cache, hashes
        self.scheduler, self.progress, self.client = scheduler, progress, client
        self.cached = self.reduced = 0

    def __call__(self, reducer: Any, paths: Sequence[Any]) -> list[Any]:
        import dask

        key = reduction_key(reducer)
        # The name too: a run's name, its conditions table row and file-name pattern go by it.
        entries = [self.cache / f"{h}-{_digest(Path(p).name, key)}.pkl"
                   if (h := self.hashes.get(str(p))) else None for p in paths]  # fmt: skip
        results = [_load(e) if e else None for e in entries]
        todo = [i for i, r in enumerate(results) if r is None]
        task = dask.delayed(reducer, pure=False)  # one node: the reducer goes to a worker once
        done = compute([task(str(paths[i])) for i in todo], self.scheduler, self.progress,
                       self.client)  # fmt: skip
        for i, r in zip(todo, done):
            results[i] = r
            if e := entries[i]:
                _store(e, r)
        self.cached += len(paths) - len(todo)
        self.reduced += len(todo)
        return results


def _check_current(rows: Any) -> dict[str, str | None]:
    """The rows' files as indexed (else one line saying to re-index): {file: sha256}."""
    for r in rows.itertuples():
        if r.status == "running":
            raise AnalysisError(f"{r.file}: run {r.campaign}/{r.run} is still being written "
                                "(status running); wait for it, or add status == 'success' "
                                "to --where")  # fmt: skip
        try:
            st = os.stat(r.file)
        except OSError:
            raise AnalysisError(f"{r.file}: run file gone since it was indexed; run "
                                "`cutlab catalog index` again") from None  # fmt: skip
        if (st.st_size, st.st_mtime_ns) != (r.size_bytes, r.mtime_ns):
            raise AnalysisError(f"{r.file}: changed since it was indexed (size or mtime); run "
                                "`cutlab catalog index` again")  # fmt: skip
    return {r.file: r.sha256 for r in rows.itertuples()}


def fit_catalog(
    index: str | Path | None,
    where: str | None = None,
    scheduler: str | None = None,
    progress: bool = False,
    **fit_kw: Unpack[FitOptions],
) -> ForcesResult:
    """:func:`analysis.identify.fit_files` over the runs of the catalogue ``index`` (its file or
    folder) that match ``where`` (all without), the reductions on dask (``scheduler``) and
    cached, the result cached too (module docstring); ``fit_kw`` as fit_files takes them. The
    result is fit_files' plus ``catalog``: index, where, runs, cached and reduced counts,
    fit_cached, scheduler."""
    ipath = index_file(index)
    rows = query_runs(where, ipath)
    if rows.empty:
        raise AnalysisError(f"{ipath}: no run in the catalogue matches {where!r}")
    hashes = _check_current(rows)
    # The scheduler asked for is reached first, cached fit or not: a wrong one is an error.
    address = distributed_address(scheduler)
    client = connect(address) if address else None
    with client if client is not None else contextlib.nullcontext():
        mapper = CachedMapper(cache_dir(ipath), hashes, scheduler, progress, client)
        key = _fit_key(rows, fit_kw)
        entry = cache_dir(ipath) / f"{key}.pkl" if key else None
        out = _load(entry) if entry else None
        fit_cached = out is not None
        if out is None:
            out = fit_files(list(rows["file"]), mapper=mapper, **fit_kw)
            if entry:
                _store(entry, out)
    out["catalog"] = {"index": str(ipath), "where": where, "runs": len(rows),
                      "cached": len(rows) if fit_cached else mapper.cached,
                      "reduced": mapper.reduced, "fit_cached": fit_cached,
                      "scheduler": scheduler or "default"}  # fmt: skip
    return out
