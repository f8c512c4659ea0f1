"""Force coefficients from files, as `cutlab analyze forces` computes them: reduce each run file
(HDF5 run or DynoWare / CSV export) to its revolution average, choose the tool and the model,
fit, and optionally predict other runs and plot.

Each run's conditions are its own (the run file's conditions or the export's header), then its
row of a conditions table, a file-name pattern, then the given ones, key by key; a run that
records another tool than the fit's is refused. ``axes`` maps columns (exports) or channels (run
files) to cutlab's x, y, z; the end-mill fit is checked against the other plausible mappings
(:func:`analysis.identify.axes.check_axes`). Tools come from a user catalogue (``tools_path``)
before the shipped ``configs/tools.toml``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

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
    FACEMILL,
    ForceModel,
    ModelTool,
    model_for,
    model_named,
)
from analysis.identify._common import (
    CI_NOTE,
    RunAverage,
    axis_order,
    reduce_run,
    reduce_run_file,
)
from analysis.identify._types import StatsRow
from analysis.identify.axes import AxisMap, check_axes, choose_axes, parse_axes, remap
from analysis.identify.conditions import (
    Conditions,
    ConditionsTable,
    load_conditions_table,
    normalize,
    pattern_conditions,
    resolve_conditions,
)
from analysis.identify.endmill import EndMillFit, fit_endmill
from analysis.identify.facemill import FaceMillFit, fit_facemill, tool_entry_s
from analysis.identify.importers import NO_AIR_ZEROED, Export, load_export
from analysis.identify.results import (
    EDGE_REASON,
    SHORT_NAMES,
    ForcesResult,
    add_trust,
    add_validation,
)
from analysis.identify.trust import (
    by_direction,
    outside_limits,
    per_run_residuals,
)
from analysis.runs import IDENTIFY_TOLERANCE, NoSteadyCutError, load_run

__all__ = ["FileReducer", "ImportOptions", "Mapper", "find_tool", "fit_files", "load_exports",
           "reduce_files", "tool_teeth"]  # fmt: skip

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


@dataclass(frozen=True)
class ImportOptions:
    """How to read each file: ``axes`` (``x=-Fy,y=Fx,z=-Fz`` or None for the rig config's /
    the files' own), a conditions ``table`` (path or loaded), a file-name ``pattern``, a
    ``zero_file`` or ``zeroed`` (exports), the user's ``tools_path`` and ``materials_path``."""

    axes: AxisMap | str | None = None
    table: ConditionsTable | str | Path | None = None
    pattern: str | None = None
    zero_file: str | Path | None = None
    zeroed: bool = False
    tools_path: str | Path | None = None
    materials_path: str | Path | None = None

    @property
    def auto(self) -> bool:
        """``--axes auto``: the mapping is chosen from the fit (:func:`choose_axes`)."""
        return isinstance(self.axes, str) and self.axes.strip().lower() == "auto"

    def loaded(self) -> ImportOptions:
        """Parsed once: the mapping and the table (``auto`` stays ``"auto"``)."""
        axes = self.axes
        if isinstance(axes, str) and not self.auto:
            axes = parse_axes(axes)
        table = self.table
        if table is not None and not isinstance(table, ConditionsTable):
            table = load_conditions_table(table)
        return ImportOptions(axes, table, self.pattern, self.zero_file, self.zeroed,
                             self.tools_path, self.materials_path)  # fmt: skip

    def layers(self, path: str | Path) -> list[tuple[str, Mapping[str, object]]]:
        """The conditions from the table row and the file-name pattern of ``path``."""
        out: list[tuple[str, Mapping[str, object]]] = []
        if isinstance(self.table, ConditionsTable):
            out.append(self.table.row(path))
        if self.pattern:
            out.append((f"{Path(str(path)).name} (--conditions-pattern)",
                        pattern_conditions(self.pattern, path)))  # fmt: skip
        return out


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


def _reduce_all(
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
    avgs, rejected, tools, _ = _reduce_all(
        paths, overrides, dynamometer, rate_hz, expected_tool, by, tolerance, progress, opts
    )
    return avgs, rejected, tools


def _fit(
    avgs: list[RunAverage], tool_name: str, model: str | None, dynamometer: Dynamometer,
    tools_path: str | Path | None = None,
) -> tuple[str, ModelTool, FaceMillFit | EndMillFit, dict[str, StatsRow]]:  # fmt: skip
    """(model, tool, fit, statistics) with the model from the tool's kind unless given."""
    tool = find_tool(tool_name, tools_path)
    force_model = model_named(model) if model else model_for(tool)
    if force_model is FACEMILL:
        fit = fit_facemill(avgs, tool, dynamometer)
        return force_model.name, tool, fit, _identified(fit, fit.summary or {}, force_model)
    if not force_model.describes(tool):
        raise AnalysisError(
            f"--model endmill with tool {tool_name!r} of kind {tool.kind!r}: the end-mill "
            "model describes flat, ball and bull end mills"
        )
    em_fit = fit_endmill(avgs, tool)
    stats = em_fit.fit.as_dict() if em_fit.fit else {}
    return force_model.name, tool, em_fit, _identified(em_fit, stats, force_model)


def _identified(
    fit: FaceMillFit | EndMillFit, stats: Mapping[str, Mapping[str, float | bool | str]],
    model: ForceModel,
) -> dict[str, StatsRow]:  # fmt: skip
    """Statistics rows marked ``identified`` with a ``status`` ('identified' or 'not identified:
    reason'): the edge rows only when the data support the linear edge-force model (adequacy);
    rows that carry their own (the face mill's, from the design's split) keep it."""
    edge_ok = fit.adequacy is None or fit.adequacy.edge_identified
    out: dict[str, StatsRow] = {}
    for k, v in stats.items():
        ok = edge_ok or k not in model.edge_keys
        why = "identified" if ok else f"not identified: {EDGE_REASON}"
        out[k] = {**v, "identified": v.get("identified", ok), "status": v.get("status", why)}
    return out


def _per_run(a: RunAverage) -> dict[str, object]:
    return {
        "run": a.name,
        "fz_mm": a.conditions.fz_mm,
        "depth_mm": a.conditions.depth_mm,
        "revolutions": a.revolutions,
        "steady": a.steady,
        "mean_force_n": a.mean_n,
        "tooth_peak_n": a.tooth_peak_n,
        "runout_ratio": a.runout_ratio,
    }


def fit_files(
    paths: Sequence[str | Path],
    model: str | None = None,
    tool: str | None = None,
    overrides: Mapping[str, object] | None = None,
    rig_path: str | Path | None = None,
    rate_hz: float | None = None,
    tolerance: float = IDENTIFY_TOLERANCE,
    validate: Sequence[str | Path] | None = None,
    plot_dir: str | Path | None = None,
    progress: Progress | None = None,
    options: ImportOptions | None = None,
    mapper: Mapper | None = None,
    keep: bool = False,
) -> ForcesResult:
    """Fit the force model (``model`` 'facemill' / 'endmill', default from the tool's kind) to
    run files; the tool is ``tool`` or the one the runs record. With a successful fit,
    ``validate`` runs (or the fitted ones when only ``plot_dir`` is given) are predicted and
    ``plot_dir`` gets the PNGs. ``options``: axes, conditions table, zero, user catalogues
    (:class:`ImportOptions`); ``mapper`` runs the per-file reductions (e.g. as dask tasks; default
    one by one, calling ``progress``). Returns the JSON-able result: model, tool, success, message,
    coefficients (end mill: also ``Ktc`` ... ``Kae``, units in ``coefficient_units``), statistics
    (+ note), r_squared, residual_rms_n, dof, runs, rejected, per_run (with each run's ``axes``
    and ``zero``), axes, axes_check (end mill), split (face mill), warnings, and validation
    (max_error_pct, rows) / plots when made. End mill: runs whose conditions exceed the tool's
    limits (``max_chip_mm``) are named in ``outside_limits`` and left out of the fit unless
    ``keep``; the result adds ``by_direction`` (R^2 and RMS per direction), ``run_residuals`` (per
    run and direction, N and %), ``influence`` (leave-one-out) and each statistics row's
    ``status``. The mapping is checked against the 47 other signed permutations and refused
    (AnalysisError) when it gives a negative cutting coefficient or fits clearly worse; ``--axes
    auto`` (``options.axes = "auto"``) chooses it (``axes_choice``)."""
    if not 0.0 < tolerance < 1.0:
        raise ConfigError(
            f"--steady-tolerance {tolerance}: expected a fraction of the steady "
            "force level, 0 < value < 1 (e.g. 0.02)"
        )
    opts = (options or ImportOptions()).loaded()
    rig = load_rig(rig_path or None)
    dyno = rig.dynamometer
    avgs, rejected, tool_names, notes = _reduce_all(
        paths, overrides, dyno, rate_hz, tool, "--tool", tolerance, progress, opts, mapper
    )
    names = {t for t in tool_names if t}
    if not tool and len(names) != 1:
        raise AnalysisError(
            f"runs name tools {sorted(names) or 'none'}: give --tool NAME (one tool per fit)"
        )
    tool_name = tool or names.pop()
    tool_obj = find_tool(tool_name, opts.tools_path)
    force_model = model_named(model) if model else model_for(tool_obj)
    em_tool = tool_obj if force_model is ENDMILL and ENDMILL.describes(tool_obj) else None
    limits = outside_limits(avgs, em_tool) if em_tool is not None else []
    if limits and not keep:
        out_names = {n for n, _ in limits}
        avgs = [a for a in avgs if a.name not in out_names]
    choice = None
    if em_tool is not None and opts.auto:
        base = sorted({n["axes"] for n in notes.values()})
        if len(base) != 1:
            raise AnalysisError(f"--axes auto: the runs are read with different mappings "
                                f"({'; '.join(base)}): give --axes")  # fmt: skip
        read = parse_axes(base[0])
        chosen, choice = choose_axes(avgs, em_tool, read)
        # chosen = M_c @ columns, read = M_r @ columns (M_r diagonal +-1): chosen = M_c M_r^T read
        cols = list(read.sources)
        m = chosen.matrix(cols, "--axes auto") @ read.matrix(cols, "--axes auto").T
        avgs = [remap(a, m) for a in avgs]
        notes = {k: {**n, "axes": chosen.text} for k, n in notes.items()}
    elif opts.auto:
        raise AnalysisError("--axes auto chooses the mapping from the end-mill fit; for "
                            f"{model or tool_obj.kind} runs give --axes")  # fmt: skip
    model, tool_cfg, fit, stats = _fit(avgs, tool_name, model, dyno, opts.tools_path)
    message = fit.message
    if rejected:
        message += " (rejected: " + "; ".join(f"{n}: {m}" for n, m in rejected) + ")"
    lin = fit.fit
    coefficients = fit.coefficients.model_dump() if fit.coefficients else None
    mappings = sorted({n["axes"] for n in notes.values()})
    out: ForcesResult = {
        "model": model,
        "tool": tool_name,
        "success": fit.success,
        "message": message,
        "coefficients": coefficients,
        "statistics": stats,
        "statistics_note": CI_NOTE,
        "r_squared": lin.r_squared if lin else None,
        "residual_rms_n": lin.residual_rms if lin else None,
        "dof": lin.dof if lin else None,
        "runs": [a.name for a in avgs],
        "rejected": [{"run": n, "reason": m} for n, m in rejected],
        "per_run": [{**_per_run(a), **notes[a.name]} for a in avgs],
        "axes": mappings[0] if len(mappings) == 1 else mappings,
        "warnings": [f"{n}: {note['zero']}" for n, note in notes.items()
                     if note["zero"] == NO_AIR_ZEROED],  # fmt: skip
        "adequacy": (
            {**fit.adequacy.as_dict(), "summary": fit.adequacy.line()}
            if fit.adequacy is not None else None
        ),
    }
    if model == "endmill" and coefficients:
        coefficients.update({k: coefficients[v] for k, (v, _) in SHORT_NAMES.items()})
        out["coefficient_units"] = {k: u for k, (_, u) in SHORT_NAMES.items()}
    if choice is not None:
        out["axes_choice"] = {"axes": choice["axes"], "line": choice["line"],
                              "runner_up": choice["runner_up"]}  # fmt: skip
        out["axes_check"] = choice["candidates"]
    elif model == "endmill" and len(mappings) == 1 and ENDMILL.describes(tool_cfg):
        check = check_axes(avgs, tool_cfg, parse_axes(mappings[0]))
        if check["refusal"]:
            raise AnalysisError(check["refusal"])
        if not check["checked"]:
            out["warnings"].append(f"axes {mappings[0]} unchecked: the runs cannot be fitted "
                                   "under any mapping (too few runs or feeds)")  # fmt: skip
        out["axes_check"] = check["candidates"]
        out["warnings"] += check["warnings"]
    if em_tool is not None:
        out["outside_limits"] = [{"run": n, "reason": r, "kept": keep} for n, r in limits]
        out["speed_limits"] = "unchecked: the tool catalogue gives no speed range"
        mc = em_tool.max_chip_mm
        out["chip_limit"] = (f"checked against max_chip_mm {mc:g} mm" if mc is not None else
                             "unchecked: the tool gives no max_chip_mm")  # fmt: skip
        if limits and not keep:
            out["message"] += (f" (left out {len(limits)} run(s) beyond the tool's limits: "
                               + "; ".join(f"{n}: {r}" for n, r in limits)
                               + "; --keep fits them)")  # fmt: skip
        if isinstance(fit, EndMillFit) and fit.fit is not None:
            add_trust(out, avgs, em_tool, fit.fit, fit.adequacy)
    elif (model == "facemill" and isinstance(fit, FaceMillFit) and fit.success  # (with a split)
          and fit.split is not None and len(fit.residuals_n) == len(avgs)):  # fmt: skip
        # the face-mill fit is to the revolution-averaged waveforms: per direction over their bins
        out["by_direction"] = by_direction(np.concatenate([a.waveform_n for a in avgs]),
                                           np.concatenate(fit.residuals_n))  # fmt: skip
        out["by_direction_over"] = "the runs' revolution-averaged waveforms (all bins)"
        out["split"] = fit.split.as_dict()  # which coefficients the design splits, and why
        out["run_residuals"] = per_run_residuals(
            [a.name for a in avgs], np.stack([a.mean_n for a in avgs]),
            np.stack([r.mean(axis=0) for r in fit.residuals_n]),
        )  # fmt: skip
        out["influence"] = {"checked": False, "runs": [], "depends": {},
                            "reason": "leave-one-out is not run for the face-mill fit"}  # fmt: skip
    if fit.success and fit.coefficients is not None and (validate or plot_dir):
        targets = avgs
        if validate:
            by = "the fitted runs' tool"
            targets, rej2, _, _ = _reduce_all(validate, overrides, dyno, rate_hz, tool_name, by,
                                              tolerance, progress, opts, mapper)  # fmt: skip
            out["rejected"] += [{"run": n, "reason": m} for n, m in rej2]
        add_validation(out, targets, tool_cfg, fit.coefficients, dyno, plot_dir)
    return out


def auto_axes(
    paths: Sequence[str | Path],
    overrides: Mapping[str, object] | None = None,
    rig_path: str | Path | None = None,
    rate_hz: float | None = None,
    tool: str | None = None,
    options: ImportOptions | None = None,
    tolerance: float = IDENTIFY_TOLERANCE,
) -> tuple[str, str]:
    """``--axes auto`` for `cutlab data import`: the exports reduced under their own mapping
    (column names, the rig config) and the end-mill fit's choice among the 48 signed
    permutations (:func:`analysis.identify.axes.choose_axes`). Returns (mapping, the line that
    says it with the runner-up); AnalysisError when the runs cannot tell."""
    opts = replace((options or ImportOptions()).loaded(), axes=None)
    dyno = load_rig(rig_path or None).dynamometer
    avgs, rejected, tool_names, notes = _reduce_all(
        paths, overrides, dyno, rate_hz, tool, "--tool", tolerance, None, opts
    )
    names = {t for t in tool_names if t}
    if not tool and len(names) != 1:
        raise AnalysisError(f"--axes auto fits the end-mill model: the runs name tools "
                            f"{sorted(names) or 'none'}: give --tool NAME")  # fmt: skip
    tool_obj = find_tool(tool or names.pop(), opts.tools_path)
    if not ENDMILL.describes(tool_obj):
        raise AnalysisError("--axes auto chooses the mapping from the end-mill fit; for "
                            f"{tool_obj.kind} tools give --axes")  # fmt: skip
    base = sorted({n["axes"] for n in notes.values()})
    if len(base) != 1:
        raise AnalysisError(f"--axes auto: the exports are read with different mappings "
                            f"({'; '.join(base)}): give --axes")  # fmt: skip
    limits = {n for n, _ in outside_limits(avgs, tool_obj)}
    read = parse_axes(base[0])
    chosen, info = choose_axes([a for a in avgs if a.name not in limits], tool_obj, read)
    return chosen.text, info["line"]
