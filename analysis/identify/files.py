"""Force coefficients from files, as `cutlab analyze forces` computes them: reduce each run file
(HDF5 run or DynoWare / CSV export) to its revolution average, choose the tool and the model,
fit, and optionally predict other runs and plot.

How each run is read (its conditions, layers and tool) is :mod:`analysis.identify.reading`.
``axes`` maps columns (exports) or channels (run files) to cutlab's x, y, z; the end-mill fit is
checked against the other plausible mappings (:func:`analysis.identify.axes.check_axes`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from analysis.config import Dynamometer, EndMill, FaceMill, load_rig
from analysis.errors import AnalysisError, ConfigError
from analysis.forces.models import (
    ENDMILL,
    FACEMILL,
    ForceModel,
    ModelTool,
    model_for,
    model_named,
)
from analysis.identify._common import CI_NOTE, RunAverage
from analysis.identify._types import StatsRow
from analysis.identify.axes import AxesChoice, check_axes, choose_axes, parse_axes, remap
from analysis.identify.endmill import EndMillFit, fit_endmill
from analysis.identify.facemill import FaceMillFit, fit_facemill
from analysis.identify.importers import NO_AIR_ZEROED
from analysis.identify.options import ImportOptions
from analysis.identify.reading import (
    Mapper,
    Progress,
    find_tool,
    reduce_all,
)
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
from analysis.runs import IDENTIFY_TOLERANCE

__all__ = ["auto_axes", "fit_files"]

#: a run's reading notes (axes, zero, ...), as reduce_all gives them
Note = dict[str, str]


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
    _check_tolerance(tolerance)
    opts = (options or ImportOptions()).loaded()
    dyno = load_rig(rig_path or None).dynamometer
    avgs, rejected, tool_names, notes = reduce_all(
        paths, overrides, dyno, rate_hz, tool, "--tool", tolerance, progress, opts, mapper
    )
    tool_name, tool_obj = _the_tool(tool, tool_names, opts)
    force_model = model_named(model) if model else model_for(tool_obj)
    em_tool = tool_obj if force_model is ENDMILL and ENDMILL.describes(tool_obj) else None
    limits = outside_limits(avgs, em_tool) if em_tool is not None else []
    if limits and not keep:
        out_names = {n for n, _ in limits}
        avgs = [a for a in avgs if a.name not in out_names]
    choice = None
    if opts.auto:
        if em_tool is None:
            raise AnalysisError("--axes auto chooses the mapping from the end-mill fit; for "
                                f"{model or tool_obj.kind} runs give --axes")  # fmt: skip
        avgs, notes, choice = _auto_axes(avgs, notes, em_tool)
    model, tool_cfg, fit, stats = _fit(avgs, tool_name, model, dyno, opts.tools_path)
    out = _result(model, tool_name, fit, stats, avgs, rejected, notes)
    _add_axes_check(out, choice, avgs, tool_cfg)
    if em_tool is not None:
        _add_endmill_trust(out, fit, avgs, em_tool, limits, keep)
    elif model == "facemill" and isinstance(fit, FaceMillFit):
        _add_facemill_trust(out, fit, avgs)
    if fit.success and fit.coefficients is not None and (validate or plot_dir):
        targets = avgs
        if validate:
            by = "the fitted runs' tool"
            targets, rej2, _, _ = reduce_all(validate, overrides, dyno, rate_hz, tool_name, by,
                                             tolerance, progress, opts, mapper)  # fmt: skip
            out["rejected"] += [{"run": n, "reason": m} for n, m in rej2]
        add_validation(out, targets, tool_cfg, fit.coefficients, dyno, plot_dir)
    return out


def _check_tolerance(tolerance: float) -> None:
    if not 0.0 < tolerance < 1.0:
        raise ConfigError(
            f"--steady-tolerance {tolerance}: expected a fraction of the steady "
            "force level, 0 < value < 1 (e.g. 0.02)"
        )


def _the_tool(
    tool: str | None, tool_names: Iterable[str], opts: ImportOptions
) -> tuple[str, EndMill | FaceMill]:
    """The fit's tool: the given one, else the one every run records (one tool per fit)."""
    names = {t for t in tool_names if t}
    if not tool and len(names) != 1:
        raise AnalysisError(
            f"runs name tools {sorted(names) or 'none'}: give --tool NAME (one tool per fit)"
        )
    tool_name = tool or names.pop()
    return tool_name, find_tool(tool_name, opts.tools_path)


def _auto_axes(
    avgs: list[RunAverage], notes: dict[str, Note], em_tool: EndMill
) -> tuple[list[RunAverage], dict[str, Note], AxesChoice]:
    """``--axes auto``: the runs remapped to the mapping the end-mill fit chooses."""
    base = sorted({n["axes"] for n in notes.values()})
    if len(base) != 1:
        raise AnalysisError(f"--axes auto: the runs are read with different mappings "
                            f"({'; '.join(base)}): give --axes")  # fmt: skip
    read = parse_axes(base[0])
    chosen, choice = choose_axes(avgs, em_tool, read)
    # chosen = M_c @ columns, read = M_r @ columns (M_r diagonal +-1): chosen = M_c M_r^T read
    cols = list(read.sources)
    m = chosen.matrix(cols, "--axes auto") @ read.matrix(cols, "--axes auto").T
    notes = {k: {**n, "axes": chosen.text} for k, n in notes.items()}
    return [remap(a, m) for a in avgs], notes, choice


def _result(
    model: str, tool_name: str, fit: FaceMillFit | EndMillFit, stats: dict[str, StatsRow],
    avgs: list[RunAverage], rejected: list[tuple[str, str]], notes: dict[str, Note],
) -> ForcesResult:  # fmt: skip
    """What every fit reports: the coefficients, their statistics and the runs."""
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
    return out


def _add_axes_check(
    out: ForcesResult, choice: AxesChoice | None, avgs: list[RunAverage], tool: ModelTool
) -> None:
    """The mapping --axes auto chose, or the given one checked against the other 47 (end mill);
    refused when another fits clearly better or it gives a negative cutting coefficient."""
    mappings = out["axes"]
    if choice is not None:
        out["axes_choice"] = {"axes": choice["axes"], "line": choice["line"],
                              "runner_up": choice["runner_up"]}  # fmt: skip
        out["axes_check"] = choice["candidates"]
    elif out["model"] == "endmill" and isinstance(mappings, str) and ENDMILL.describes(tool):
        check = check_axes(avgs, tool, parse_axes(mappings))
        if check["refusal"]:
            raise AnalysisError(check["refusal"])
        if not check["checked"]:
            out["warnings"].append(f"axes {mappings} unchecked: the runs cannot be fitted "
                                   "under any mapping (too few runs or feeds)")  # fmt: skip
        out["axes_check"] = check["candidates"]
        out["warnings"] += check["warnings"]


def _add_endmill_trust(
    out: ForcesResult, fit: FaceMillFit | EndMillFit, avgs: list[RunAverage], em_tool: EndMill,
    limits: list[tuple[str, str]], keep: bool,
) -> None:  # fmt: skip
    """The tool's limits (runs beyond them, left out unless ``keep``) and the trust figures."""
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


def _add_facemill_trust(out: ForcesResult, fit: FaceMillFit, avgs: list[RunAverage]) -> None:
    """Per direction and per run residuals of a face-mill fit with a split design."""
    if not (fit.success and fit.split is not None and len(fit.residuals_n) == len(avgs)):
        return
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
    avgs, rejected, tool_names, notes = reduce_all(
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
