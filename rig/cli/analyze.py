"""`cutlab analyze` commands: force coefficients from runs, dynamometer modes from a hammer test.

cutlab analyze forces RUN... [--model facemill|endmill] [--tool NAME] [--validate RUN...]
                             [--conditions KEY=VALUE...] [--steady-tolerance FRACTION]
                             [--plot DIR] [--json]
cutlab analyze modal FILE [--hammer NAME] [--rpm RPM...] [--teeth N] [--json]

RUN is an HDF5 run file (conditions from the file) or a DynoWare/plain CSV export (conditions
from its header lines); --conditions overrides them key by key for every run. A run that records
another tool than --tool is refused. A fit that the runs cannot support prints its reason and
exits with status 1; bad input exits with status 2.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def _ci_note() -> str:
    from analysis.identify import CI_NOTE  # inside: `cutlab --help` need not load scipy

    return CI_NOTE


def _condition_overrides(args) -> dict[str, Any]:
    """--conditions KEY=VALUE... as a mapping (applied over each file's own conditions)."""
    from rig.cli._common import parse_conditions

    return parse_conditions(args.conditions)


def _check_tool(path, recorded: str, expected: str | None, by: str) -> None:
    """Refuse a run cut with another tool than the fit's (a silent switch of model and teeth)."""
    from analysis.errors import AnalysisError

    if expected and recorded and recorded != expected:
        hint = "leave out --tool, or" if by == "--tool" else "validate runs of that tool, or"
        raise AnalysisError(
            f"{path}: the run records tool {recorded!r} but {by} is {expected!r}; {hint} "
            "override the run's tool with --conditions tool=NAME"
        )


def _load_runs(paths, args, rig, expected_tool: str | None = None, by: str = "--tool"):
    """Reduce each RUN to its revolution average; returns (averages, rejected, tool names).

    Each run's conditions are its own (HDF5 conditions or the export's header) overridden key by
    key by --conditions; ``expected_tool`` (given by ``by``) must match the tool a run records.
    """
    from tqdm import tqdm

    from analysis.identify import (
        RunConditions,
        import_run,
        merge_conditions,
        reduce_run,
        reduce_run_file,
    )
    from analysis.runs import NoSteadyCutError

    given = _condition_overrides(args)
    avgs, rejected, tool_names = [], [], set()
    # disable=None: tqdm stays quiet when stderr is not a terminal (CI logs).
    quiet = True if (args.json or len(paths) < 2) else None
    for p in tqdm(paths, desc="reducing runs", unit="run", disable=quiet):
        try:
            if str(p).lower().endswith((".h5", ".hdf5")):
                from analysis.runs import load_run

                meta = load_run(p, samples=False)
                where = f"{p} (conditions" + (" and --conditions)" if given else ")")
                cond = RunConditions.from_mapping(merge_conditions(meta.conditions, given), where)
                _check_tool(p, cond.tool, expected_tool, by)
                teeth = _teeth(expected_tool or cond.tool)
                avgs.append(reduce_run_file(p, teeth, cond, tolerance=args.steady_tolerance))
            else:
                run = import_run(p, given, rig.dynamometer, args.rate)
                _check_tool(p, run.conditions.tool, expected_tool, by)
                teeth = _teeth(expected_tool or run.conditions.tool)
                avgs.append(reduce_run(run, teeth, tolerance=args.steady_tolerance))
            tool_names.add(expected_tool or avgs[-1].conditions.tool)
        except NoSteadyCutError as exc:  # a run to leave out; other bad input stops
            rejected.append((Path(p).stem, str(exc)))
    return avgs, rejected, tool_names


def _teeth(name: str) -> int:
    from analysis.config import EndMill, get_tool

    if not name:
        return 1
    tool = get_tool(name)
    return tool.flutes if isinstance(tool, EndMill) else tool.inserts


def _forces(args: argparse.Namespace) -> int:
    from analysis.config import EndMill, FaceMill, get_tool, load_rig
    from analysis.errors import AnalysisError, ConfigError
    from analysis.identify import fit_endmill, fit_facemill
    from rig.cli._common import print_json, print_table, status

    if not 0.0 < args.steady_tolerance < 1.0:
        raise ConfigError(
            f"--steady-tolerance {args.steady_tolerance}: expected a fraction of the steady "
            "force level, 0 < value < 1 (e.g. 0.02)"
        )
    rig = load_rig(args.rig) if args.rig else load_rig()
    avgs, rejected, tool_names = _load_runs(args.runs, args, rig, args.tool)
    names = {t for t in tool_names if t}
    if args.tool:
        tool_name = args.tool
    elif len(names) == 1:
        tool_name = names.pop()
    else:
        raise AnalysisError(
            f"runs name tools {sorted(names) or 'none'}: give --tool NAME (one tool per fit)"
        )
    tool = get_tool(tool_name)
    model = args.model or ("facemill" if isinstance(tool, FaceMill) else "endmill")
    if model == "facemill":
        fit = fit_facemill(avgs, tool, rig.dynamometer)
        stats = fit.summary or {}
    else:
        if not isinstance(tool, EndMill):
            raise AnalysisError(
                f"--model endmill with tool {tool_name!r} of kind {tool.kind!r}: the end-mill "
                "model describes flat, ball and bull end mills"
            )
        fit = fit_endmill(avgs, tool)
        stats = fit.fit.as_dict() if fit.fit else {}
    message = fit.message
    if rejected:
        message += " (rejected: " + "; ".join(f"{n}: {m}" for n, m in rejected) + ")"
    out: dict[str, Any] = {
        "model": model,
        "tool": tool_name,
        "success": fit.success,
        "message": message,
        "coefficients": fit.coefficients.model_dump() if fit.coefficients else None,
        "statistics": stats,
        "statistics_note": _ci_note(),
        "r_squared": fit.fit.r_squared if fit.fit else None,
        "residual_rms_n": fit.fit.residual_rms if fit.fit else None,
        "dof": fit.fit.dof if fit.fit else None,
        "runs": [a.name for a in avgs],
        "rejected": [{"run": n, "reason": m} for n, m in rejected],
        "per_run": [
            {
                "run": a.name,
                "fz_mm": a.conditions.fz_mm,
                "depth_mm": a.conditions.depth_mm,
                "revolutions": a.revolutions,
                "mean_force_n": a.mean_n,
                "tooth_peak_n": a.tooth_peak_n,
                "runout_ratio": a.runout_ratio,
            }
            for a in avgs
        ],
    }
    if fit.success and (args.validate or args.plot):
        from analysis.identify import compare_runs, plot_comparison

        targets = avgs
        if args.validate:
            targets, rej2, _ = _load_runs(args.validate, args, rig, tool_name,
                                          "the fitted runs' tool")  # fmt: skip
            out["rejected"] += [{"run": n, "reason": m} for n, m in rej2]
        cmp = compare_runs(targets, tool, fit.coefficients, rig.dynamometer)
        out["validation"] = {
            "max_error_pct": cmp.max_error_pct,
            "rows": list(cmp.rows),
        }
        if args.plot:
            pngs = plot_comparison(cmp, args.plot)
            if model == "facemill":
                from analysis.identify import plot_waveforms

                pngs += plot_waveforms(targets, tool, fit.coefficients, args.plot, rig.dynamometer)
            out["plots"] = [str(p) for p in pngs]
            status(f"analyze forces: wrote {', '.join(map(str, pngs))}")
    if args.json:
        print_json(out)
    else:
        print(f"{model} fit of {len(avgs)} run(s), tool {tool_name}: {message}")
        if stats:
            print_table([{"coefficient": k, **v} for k, v in stats.items()])
            print(_ci_note())
        if "validation" in out:
            print()
            print_table(
                [
                    {
                        "run": r["run"],
                        "fz_mm": r["fz_mm"],
                        "depth_mm": r["depth_mm"],
                        "measured_resultant_n": r["measured_resultant_n"],
                        "predicted_resultant_n": r["predicted_resultant_n"],
                        "error_pct": r["resultant_error_pct"],
                    }
                    for r in out["validation"]["rows"]
                ]
            )
    return 0 if fit.success else 1


def _modal(args: argparse.Namespace) -> int:
    import numpy as np

    from analysis.config import load_rig
    from analysis.errors import AnalysisError
    from analysis.identify import read_force_table
    from analysis.modal import ImpactRecord, modal_analysis, tooth_passing_warnings
    from rig.cli._common import print_json, print_table, status

    path = Path(args.file)
    if path.suffix.lower() in (".h5", ".hdf5"):
        from analysis.runs import load_run

        run = load_run(path)
        data = run.force_n if run.force_n is not None else run.volts
        columns, rate = list(run.channel_names), run.rate_hz
    else:
        t = read_force_table(path)
        data, columns, rate = t.data, list(t.columns), t.rate_hz
        if args.rate:
            rate = args.rate
    lower = [c.lower() for c in columns]
    hammer = args.hammer.lower()
    if hammer not in lower:
        raise AnalysisError(
            f"{path}: no hammer channel {args.hammer!r} among {columns}; name it with --hammer"
        )
    if not np.isfinite(rate):
        raise AnalysisError(f"{path}: no sampling rate in the file; give --rate HZ")
    h = lower.index(hammer)
    resp_idx = [k for k, c in enumerate(lower) if k != h and c not in ("time", "time_s", "zeit")]
    names = []
    for k in resp_idx:
        c = lower[k]
        names.append(c[-1] if c and c[-1] in "xyz" else columns[k])
    rec = ImpactRecord(data[:, h], data[:, resp_idx], float(rate), tuple(names), path.stem)
    res = modal_analysis(rec, record_s=args.record_s, window_end=args.window_end)
    rig = load_rig(args.rig) if args.rig else load_rig()
    warn = list(res.warnings)
    if args.rpm:
        warn += tooth_passing_warnings(res.modes, args.rpm, args.teeth)
    out = {
        "file": str(path),
        "hits_used": list(res.hits_used),
        "double_hits": list(res.double_hits),
        "modes": [
            {
                "axis": m.channel,
                "frequency_hz": m.frequency_hz,
                "damping_ratio": m.damping_ratio,
                "damping_windowed": m.damping_windowed,
                "half_power_frequency_hz": m.half_power_frequency_hz,
                "half_power_damping": m.half_power_damping,
                "coherence": m.coherence,
            }
            for m in res.modes
        ],
        "skipped": [{"channel": c, "reason": r} for c, r in res.skipped],
        "config_modes": [m.model_dump() for m in rig.dynamometer.modes],
        "warnings": warn,
    }
    if args.plot:
        from analysis.modal import plot_frf

        out["plot"] = str(plot_frf(res, args.plot))
        status(f"analyze modal: wrote {out['plot']}")
    for w in warn:
        status(f"analyze modal: warning: {w}")
    if args.json:
        print_json(out)
    else:
        print_table(out["modes"])
        for s in out["skipped"]:
            print(f"skipped {s['channel']}: {s['reason']}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add this group's subcommands to ``sub``."""
    from analysis.runs import IDENTIFY_TOLERANCE

    p = sub.add_parser("analyze", help="force coefficients from runs, dynamometer modes")
    psub = p.add_subparsers(dest="analyze_command", metavar="ANALYZE_COMMAND")
    psub.required = True
    f = psub.add_parser("forces", help="fit cutting-force coefficients to recorded runs")
    f.add_argument("runs", nargs="+", help="run files (.h5) or DynoWare/CSV exports")
    f.add_argument("--model", choices=("facemill", "endmill"), default=None,
                   help="force model (default: from the tool's kind)")  # fmt: skip
    f.add_argument("--tool", default=None, help="tool name in configs/tools.toml")
    f.add_argument("--rig", default=None, help="rig config (default configs/rig.toml)")
    f.add_argument(
        "--conditions", nargs="*", metavar="KEY=VALUE",
        help="conditions applied over each run's own (file header or run file), key by key "
        "(spindle_rpm=600 depth_mm=2 mode=slot ...)",
    )  # fmt: skip
    f.add_argument("--rate", type=float, default=None, help="Hz, for exports without a rate")
    f.add_argument(
        "--steady-tolerance", type=float, default=IDENTIFY_TOLERANCE, metavar="FRACTION",
        help="revolutions whose mean force is within this fraction of the steady level (median) "
        f"count as steady cutting; fraction, default {IDENTIFY_TOLERANCE} (0.02 = 2 %%)",
    )  # fmt: skip
    f.add_argument("--validate", nargs="*", default=None, metavar="RUN",
                   help="runs to predict with the fitted coefficients")  # fmt: skip
    f.add_argument("--plot", default=None, metavar="DIR", help="write validation PNGs here")
    f.add_argument("--json", action="store_true", help="JSON on stdout")
    f.set_defaults(func=_forces)
    m = psub.add_parser("modal", help="dynamometer modes from an impulse-hammer record")
    m.add_argument("file", help="CSV/DynoWare export or run file with a hammer channel")
    m.add_argument("--hammer", default="hammer", help="name of the hammer force channel")
    m.add_argument("--rate", type=float, default=None, help="Hz, for files without a rate")
    m.add_argument("--record-s", type=float, default=0.08, help="s of record per hit")
    m.add_argument("--window-end", type=float, default=0.05,
                   help="exponential window value at the record's end")  # fmt: skip
    m.add_argument("--rpm", type=float, nargs="*", default=None,
                   help="planned spindle speeds to check against the modes")  # fmt: skip
    m.add_argument("--teeth", type=int, default=1, help="teeth of the planned cutter")
    m.add_argument("--rig", default=None, help="rig config (default configs/rig.toml)")
    m.add_argument("--plot", default=None, metavar="PNG", help="write the FRF and coherence")
    m.add_argument("--json", action="store_true", help="JSON on stdout")
    m.set_defaults(func=_modal)
