"""Force coefficients from files, as `cutlab analyze forces` computes them: reduce each run file
(HDF5 run or DynoWare / CSV export) to its revolution average, choose the tool and the model,
fit, and optionally predict other runs and plot.

Each run's conditions are its own (the run file's conditions or the export's header) overridden
key by key by the given ones; a run that records another tool than the fit's is refused.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from analysis.config import Dynamometer, EndMill, FaceMill, get_tool, load_rig
from analysis.errors import AnalysisError, ConfigError
from analysis.identify._common import (
    CI_NOTE,
    RunAverage,
    RunConditions,
    reduce_run,
    reduce_run_file,
)
from analysis.identify.endmill import fit_endmill
from analysis.identify.facemill import fit_facemill
from analysis.identify.importers import import_run, merge_conditions
from analysis.identify.validate import compare_runs, plot_comparison, plot_waveforms
from analysis.runs import IDENTIFY_TOLERANCE, NoSteadyCutError, load_run

__all__ = ["fit_files", "reduce_files", "tool_teeth"]

Progress = Callable[[int, int], None]


def tool_teeth(name: str) -> int:
    """Flutes of a named end mill, inserts of a face mill; 1 for no name."""
    if not name:
        return 1
    tool = get_tool(name)
    return tool.flutes if isinstance(tool, EndMill) else tool.inserts


def _check_tool(path: Any, recorded: str, expected: str | None, by: str) -> None:
    """Refuse a run cut with another tool than the fit's (a silent switch of model and teeth)."""
    if expected and recorded and recorded != expected:
        hint = "leave out --tool, or" if by == "--tool" else "validate runs of that tool, or"
        raise AnalysisError(
            f"{path}: the run records tool {recorded!r} but {by} is {expected!r}; {hint} "
            "override the run's tool with --conditions tool=NAME"
        )


def _reduce_file(path: Any, given: Mapping[str, Any], dynamometer: Dynamometer | None,
                 rate_hz: float | None, expected_tool: str | None, by: str,
                 tolerance: float) -> RunAverage:  # fmt: skip
    if str(path).lower().endswith((".h5", ".hdf5")):
        meta = load_run(path, samples=False)
        where = f"{path} (conditions" + (" and --conditions)" if given else ")")
        cond = RunConditions.from_mapping(merge_conditions(meta.conditions, given), where)
        _check_tool(path, cond.tool, expected_tool, by)
        teeth = tool_teeth(expected_tool or cond.tool)
        return reduce_run_file(path, teeth, cond, tolerance=tolerance)
    run = import_run(path, given, dynamometer, rate_hz)
    _check_tool(path, run.conditions.tool, expected_tool, by)
    return reduce_run(run, tool_teeth(expected_tool or run.conditions.tool), tolerance=tolerance)


def reduce_files(
    paths: Sequence[str | Path],
    overrides: Mapping[str, Any] | None = None,
    dynamometer: Dynamometer | None = None,
    rate_hz: float | None = None,
    expected_tool: str | None = None,
    by: str = "--tool",
    tolerance: float = IDENTIFY_TOLERANCE,
    progress: Progress | None = None,
) -> tuple[list[RunAverage], list[tuple[str, str]], set[str]]:
    """Each run file reduced to its revolution average: (averages, rejected (name, reason),
    tool names). ``overrides`` replace each file's own conditions key by key; ``expected_tool``
    (given by ``by``, for messages) must match the tool a run records; ``rate_hz`` for exports
    without a rate. A run without steady cutting is rejected; other bad input raises.
    ``progress(done, total)`` after each file."""
    given = dict(overrides or {})
    avgs: list[RunAverage] = []
    rejected: list[tuple[str, str]] = []
    tool_names: set[str] = set()
    for k, p in enumerate(paths):
        try:
            avgs.append(_reduce_file(p, given, dynamometer, rate_hz, expected_tool, by, tolerance))
            tool_names.add(expected_tool or avgs[-1].conditions.tool)
        except NoSteadyCutError as exc:  # a run to leave out; other bad input stops
            rejected.append((Path(p).stem, str(exc)))
        if progress:
            progress(k + 1, len(paths))
    return avgs, rejected, tool_names


def _fit(avgs: list[RunAverage], tool_name: str, model: str | None, dynamometer: Dynamometer):
    """(model, tool, fit, statistics) with the model from the tool's kind unless given."""
    tool = get_tool(tool_name)
    model = model or ("facemill" if isinstance(tool, FaceMill) else "endmill")
    if model == "facemill":
        fit = fit_facemill(avgs, tool, dynamometer)
        return model, tool, fit, fit.summary or {}
    if not isinstance(tool, EndMill):
        raise AnalysisError(
            f"--model endmill with tool {tool_name!r} of kind {tool.kind!r}: the end-mill "
            "model describes flat, ball and bull end mills"
        )
    fit = fit_endmill(avgs, tool)
    return model, tool, fit, fit.fit.as_dict() if fit.fit else {}


def _per_run(a: RunAverage) -> dict[str, Any]:
    return {
        "run": a.name,
        "fz_mm": a.conditions.fz_mm,
        "depth_mm": a.conditions.depth_mm,
        "revolutions": a.revolutions,
        "mean_force_n": a.mean_n,
        "tooth_peak_n": a.tooth_peak_n,
        "runout_ratio": a.runout_ratio,
    }


def fit_files(
    paths: Sequence[str | Path],
    model: str | None = None,
    tool: str | None = None,
    overrides: Mapping[str, Any] | None = None,
    rig_path: str | Path | None = None,
    rate_hz: float | None = None,
    tolerance: float = IDENTIFY_TOLERANCE,
    validate: Sequence[str | Path] | None = None,
    plot_dir: str | Path | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Fit the force model (``model`` 'facemill' / 'endmill', default from the tool's kind) to
    run files; the tool is ``tool`` or the one the runs record. With a successful fit,
    ``validate`` runs (or the fitted ones when only ``plot_dir`` is given) are predicted and
    ``plot_dir`` gets the PNGs. Returns the JSON-able result: model, tool, success, message,
    coefficients, statistics (+ note), r_squared, residual_rms_n, dof, runs, rejected, per_run,
    and validation (max_error_pct, rows) / plots when made."""
    if not 0.0 < tolerance < 1.0:
        raise ConfigError(
            f"--steady-tolerance {tolerance}: expected a fraction of the steady "
            "force level, 0 < value < 1 (e.g. 0.02)"
        )
    rig = load_rig(rig_path or None)
    dyno = rig.dynamometer
    avgs, rejected, tool_names = reduce_files(paths, overrides, dyno, rate_hz, tool,
                                              tolerance=tolerance, progress=progress)  # fmt: skip
    names = {t for t in tool_names if t}
    if not tool and len(names) != 1:
        raise AnalysisError(
            f"runs name tools {sorted(names) or 'none'}: give --tool NAME (one tool per fit)"
        )
    tool_name = tool or names.pop()
    model, tool_cfg, fit, stats = _fit(avgs, tool_name, model, dyno)
    message = fit.message
    if rejected:
        message += " (rejected: " + "; ".join(f"{n}: {m}" for n, m in rejected) + ")"
    lin = fit.fit
    out: dict[str, Any] = {
        "model": model,
        "tool": tool_name,
        "success": fit.success,
        "message": message,
        "coefficients": fit.coefficients.model_dump() if fit.coefficients else None,
        "statistics": stats,
        "statistics_note": CI_NOTE,
        "r_squared": lin.r_squared if lin else None,
        "residual_rms_n": lin.residual_rms if lin else None,
        "dof": lin.dof if lin else None,
        "runs": [a.name for a in avgs],
        "rejected": [{"run": n, "reason": m} for n, m in rejected],
        "per_run": [_per_run(a) for a in avgs],
    }
    if fit.success and (validate or plot_dir):
        targets = avgs
        if validate:
            by = "the fitted runs' tool"
            targets, rej2, _ = reduce_files(
                validate, overrides, dyno, rate_hz, tool_name, by, tolerance, progress
            )
            out["rejected"] += [{"run": n, "reason": m} for n, m in rej2]
        out.update(_validate(targets, model, tool_cfg, fit.coefficients, dyno, plot_dir))
    return out


def _validate(targets: list[RunAverage], model: str, tool: Any, coefficients: Any,
              dynamometer: Dynamometer, plot_dir: str | Path | None) -> dict[str, Any]:  # fmt: skip
    """``validation`` (predicted against measured mean forces) and, with ``plot_dir``, ``plots``."""
    cmp = compare_runs(targets, tool, coefficients, dynamometer)
    out: dict[str, Any] = {
        "validation": {"max_error_pct": cmp.max_error_pct, "rows": list(cmp.rows)}
    }
    if plot_dir:
        pngs = plot_comparison(cmp, plot_dir)
        if model == "facemill":
            pngs += plot_waveforms(targets, tool, coefficients, plot_dir, dynamometer)
        out["plots"] = [str(p) for p in pngs]
    return out
