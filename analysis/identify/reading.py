"""Reading runs for the fits: each run file (HDF5 run or DynoWare / CSV export) reduced to its
revolution average with its conditions (the file's own, a conditions table row, a file-name
pattern, the given ones, key by key) and axis mapping; a run that records another tool than the
fit's is refused. Tools come from a user catalogue (``tools_path``) before the shipped
``configs/tools.toml``."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from analysis.config import (
    Dynamometer,
    EndMill,
    FaceMill,
    get_material,
    get_tool,
    load_rig,
    user_catalogs,
)
from analysis.errors import AnalysisError, ConfigError
from analysis.forces.models import (
    ENDMILL,
    model_for,
)
from analysis.identify._common import (
    RunAverage,
    axis_order,
    reduce_run,
    reduce_run_file,
)
from analysis.identify.axes import AxisMap, remap
from analysis.identify.conditions import (
    Conditions,
    normalize,
    resolve_conditions,
)
from analysis.identify.facemill import tool_entry_s
from analysis.identify.importers import Export, load_export
from analysis.identify.options import ImportOptions
from analysis.runs import IDENTIFY_TOLERANCE, NoSteadyCutError, load_run

Progress = Callable[[int, int], None]


def find_tool(name: str, tools_path: str | Path | None = None) -> EndMill | FaceMill:
    """A tool from the user's catalogue ``tools_path`` (if given and it has it), else from the
    shipped ``configs/tools.toml`` (:func:`analysis.config.user_catalogs`)."""
    with user_catalogs(tools=tools_path):
        return get_tool(name)


def tool_teeth(name: str, tools_path: str | Path | None = None) -> int:
    """Flutes of a named end mill, inserts of a face mill; 1 for no name."""
    if not name:
        return 1
    tool = find_tool(name, tools_path)
    return model_for(tool).teeth(tool)


def _check_tool(path: str | Path, recorded: str, expected: str | None, by: str) -> None:
    """Refuse a run cut with another tool than the fit's (a silent switch of model and teeth)."""
    if expected and recorded and recorded != expected:
        hint = "leave out --tool, or" if by == "--tool" else "validate runs of that tool, or"
        raise AnalysisError(
            f"{path}: the run records tool {recorded!r} but {by} is {expected!r}; {hint} "
            "override the run's tool with --conditions tool=NAME"
        )


def _check_material(path: str | Path, name: str, materials_path: str | Path | None) -> None:
    if materials_path is None or not name:
        return
    try:
        get_material(name, materials_path)
    except ConfigError:
        try:
            get_material(name)
        except ConfigError:
            raise ConfigError(
                f"{path}: material {name!r} is neither in {materials_path} nor in the shipped "
                "catalogue"
            ) from None


def _reduce_file(path: str | Path, given: Mapping[str, object], dynamometer: Dynamometer | None,
                 rate_hz: float | None, expected_tool: str | None, by: str,
                 tolerance: float, opts: ImportOptions) -> tuple[RunAverage, dict[str, str]]:
    """The run's revolution average and its notes (``axes``, ``zero``)."""  # fmt: skip
    def teeth_of(name: str) -> int:
        return tool_teeth(name, opts.tools_path)

    if str(path).lower().endswith((".h5", ".hdf5")):
        layers = [*opts.layers(path), (f"{path} (--conditions)", given)]
        meta = load_run(path, samples=False)
        try:
            recorded = normalize(meta.conditions, f"{path} (conditions)", "skip")
            if "fz_mm" in recorded:  # campaigns record both feeds; fz_mm is the one fitted
                recorded.pop("feed_mm_min", None)
            cond = resolve_conditions([(f"{path} (conditions)", recorded), *layers], teeth_of,
                                      expected_tool)  # fmt: skip
            _check_tool(path, cond.tool, expected_tool, by)
            _check_material(path, cond.material, opts.materials_path)
            name = expected_tool or cond.tool
            avg = reduce_run_file(path, teeth_of(name), cond, tolerance=tolerance,
                                  entry_s=tool_entry_s(name, cond, opts.tools_path))
        except AnalysisError as exc:
            if meta.complete:
                raise
            # a killed attempt (a campaign keeps it as .attempt-K.h5) lacks what it never wrote
            why = str(exc).removeprefix(f"{path} (conditions): ").removeprefix(f"{path}: ")
            raise AnalysisError(
                f"{path}: an interrupted attempt (status {meta.status}: the writer was killed or "
                f"crashed; {meta.samples_stored} samples per channel kept): {why}; leave it out "
                "(a resumed campaign cut the run again)"
            ) from None
        names = [meta.channel_names[i] for i in axis_order(meta.channel_names)]
        # (loaded(): a string mapping other than "auto" is parsed; "auto" reads as None here)
        axes = (opts.axes if isinstance(opts.axes, AxisMap)
                else AxisMap((names[0], names[1], names[2])))  # fmt: skip
        if opts.axes is not None:
            avg = remap(avg, axes.matrix(names, str(path)))
        zero = (meta.rig or {}).get("import", {}).get("zero", "air or the amplifier's zero")
        return avg, {"axes": axes.text, "zero": zero}
    ex = _load_export(path, given, dynamometer, rate_hz, expected_tool, by, opts)
    name = expected_tool or ex.run.conditions.tool  # its entry bound, as a run file's
    avg = reduce_run(ex.run, teeth_of(name), tolerance=tolerance,
                     entry_s=tool_entry_s(name, ex.run.conditions, opts.tools_path))  # fmt: skip
    return avg, {"axes": ex.axes, "zero": ex.zero}


def _load_export(path: str | Path, given: Mapping[str, object], dynamometer: Dynamometer | None,
                 rate_hz: float | None, expected_tool: str | None, by: str,
                 opts: ImportOptions) -> Export:  # fmt: skip
    def teeth_of(name: str) -> int:
        return tool_teeth(name, opts.tools_path)

    layers = [*opts.layers(path), (f"{path} (--conditions)", given)]
    ex = load_export(path, None, dynamometer, rate_hz, axes=opts.axes, layers=layers,
                     zero_file=opts.zero_file, zeroed=opts.zeroed, teeth_of=teeth_of,
                     expected_tool=expected_tool)  # fmt: skip
    _check_tool(path, ex.run.conditions.tool, expected_tool, by)
    _check_material(path, ex.run.conditions.material, opts.materials_path)
    return replace(ex, stated=_catalogued(ex, expected_tool, opts.tools_path))


def _catalogued(
    ex: Export, expected_tool: str | None, tools_path: str | Path | None
) -> Conditions:
    """What an imported run's catalogue row keeps beside the fitted form: the stated feed (or
    the one fz, speed and teeth give), the teeth, and the mode: a cut as wide as the end mill
    is a slot (up and down milling are the same there), not the default "down"."""
    c = ex.run.conditions
    out = dict(ex.stated)
    name = expected_tool or c.tool
    tool = find_tool(name, tools_path) if name else None
    teeth = out.get("teeth", out.get("flutes"))
    if teeth is None and tool is not None:
        teeth = model_for(tool).teeth(tool)
    if teeth is not None:
        out["teeth"] = int(teeth)
        out.setdefault("feed_mm_min", c.fz_mm * abs(c.spindle_rpm) * int(teeth))
    if ("mode" not in out and ENDMILL.describes(tool) and math.isfinite(c.width_mm)
            and c.width_mm >= tool.diameter_mm * (1 - 1e-9)):  # fmt: skip
        out["mode"] = "slot"
    return out


def load_exports(
    paths: Sequence[str | Path],
    overrides: Mapping[str, object] | None = None,
    rig_path: str | Path | None = None,
    rate_hz: float | None = None,
    tool: str | None = None,
    options: ImportOptions | None = None,
) -> Iterator[Export]:
    """Each export as :func:`fit_files` reads it (conditions merged, axes mapped, offset
    decided), one at a time; ``tool`` as ``--tool``. Run files (.h5) are refused."""
    given = normalize(overrides or {}, "--conditions")
    opts = (options or ImportOptions()).loaded()
    dyno = load_rig(rig_path or None).dynamometer
    for p in paths:
        if str(p).lower().endswith((".h5", ".hdf5")):
            raise AnalysisError(f"{p}: already a run file; import reads DynoWare / CSV exports")
        yield _load_export(p, given, dyno, rate_hz, tool, "--tool", opts)


@dataclass(frozen=True)
class FileReducer:
    """One file's reduction as :func:`fit_files` does it, as a picklable callable that a task
    scheduler (dask) can run anywhere: ``reducer(path)`` -> (revolution average, notes, None),
    or (None, {}, reason) for a run without steady cutting (other bad input raises). Its repr
    holds everything besides the file that decides the result (a cache key's part)."""

    given: Mapping[str, object]
    dynamometer: Dynamometer | None
    rate_hz: float | None
    expected_tool: str | None
    by: str
    tolerance: float
    opts: ImportOptions

    def __call__(self, path: str | Path) -> tuple[RunAverage | None, dict[str, str], str | None]:
        try:
            avg, note = _reduce_file(path, self.given, self.dynamometer, self.rate_hz,
                                     self.expected_tool, self.by, self.tolerance,
                                     self.opts)  # fmt: skip
        except NoSteadyCutError as exc:  # a run to leave out; other bad input stops
            return None, {}, str(exc)
        return avg, note, None


#: Runs a :class:`FileReducer` over paths, results in the paths' order (default: one by one).
Reduced = tuple[RunAverage | None, dict[str, str], str | None]
Mapper = Callable[[FileReducer, Sequence[str | Path]], Iterable[Reduced]]


def _one_by_one(
    reducer: FileReducer, paths: Sequence[str | Path], progress: Progress | None
) -> Iterator[Reduced]:
    for k, p in enumerate(paths):
        yield reducer(p)
        if progress:
            progress(k + 1, len(paths))


def reduce_all(
    paths: Sequence[str | Path], overrides: Mapping[str, object] | None,
    dynamometer: Dynamometer | None, rate_hz: float | None, expected_tool: str | None, by: str,
    tolerance: float, progress: Progress | None, opts: ImportOptions, mapper: Mapper | None = None,
) -> tuple[list[RunAverage], list[tuple[str, str]], set[str], dict[str, dict[str, str]]]:
    given = normalize(overrides or {}, "--conditions")
    opts = opts.loaded()
    if opts.auto:  # read with the files' own (or the rig's) mapping; the fit chooses after
        opts = replace(opts, axes=None)
    reducer = FileReducer(given, dynamometer, rate_hz, expected_tool, by, tolerance, opts)
    results = mapper(reducer, paths) if mapper else _one_by_one(reducer, paths, progress)
    avgs: list[RunAverage] = []
    notes: dict[str, dict[str, str]] = {}
    rejected: list[tuple[str, str]] = []
    tool_names: set[str] = set()
    for p, (avg, note, reason) in zip(paths, results):
        if avg is None:
            rejected.append((Path(p).stem, reason or ""))
            continue
        avgs.append(avg)
        notes[avg.name] = note
        tool_names.add(expected_tool or avg.conditions.tool)
    return avgs, rejected, tool_names, notes


def reduce_files(
    paths: Sequence[str | Path],
    overrides: Mapping[str, object] | None = None,
    dynamometer: Dynamometer | None = None,
    rate_hz: float | None = None,
    expected_tool: str | None = None,
    by: str = "--tool",
    tolerance: float = IDENTIFY_TOLERANCE,
    progress: Progress | None = None,
    options: ImportOptions | None = None,
) -> tuple[list[RunAverage], list[tuple[str, str]], set[str]]:
    """Each run file reduced to its revolution average: (averages, rejected (name, reason),
    tool names). ``overrides`` replace each file's own conditions key by key; ``expected_tool``
    (given by ``by``, for messages) must match the tool a run records; ``rate_hz`` for exports
    without a rate; ``options`` the axes, conditions table... (:class:`ImportOptions`). A run
    without steady cutting is rejected; other bad input raises. ``progress(done, total)`` after
    each file."""
    opts = options or ImportOptions()
    avgs, rejected, tools, _ = reduce_all(
        paths, overrides, dynamometer, rate_hz, expected_tool, by, tolerance, progress, opts
    )
    return avgs, rejected, tools
